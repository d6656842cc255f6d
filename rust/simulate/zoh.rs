//! Continuous time: the zero-order hold of `u` and `p` over each sample,
//! `[[Ad, Bd], [0, I]] = exp([[A, B], [0, 0]] dt)` with `A`, `B` frozen at
//! `p(t)`, and the matrix exponential behind it (nalgebra's).

use super::wide::{dot, outputs, Wide};
use super::{check_sizes, check_values, finish, Trajectory, BLOCK};
use crate::base::layout::{Matrix, Shape};
use crate::error::{invalid, Error, Result};
use crate::eval::model::ModelAt;
use nalgebra::DMatrix;
use rayon::prelude::*;
use std::panic::{catch_unwind, AssertUnwindSafe};

/// Samples per task when the continuous-time discretisation is computed.
const ZOH_BLOCK: usize = 256;

/// Simulate a continuous-time LPV model with a zero-order hold of `u` and
/// `p` over samples of `dt` seconds (see the module documentation of
/// [`super`]). Other arguments as for [`super::simulate`].
pub fn simulate_zoh(
    model: &ModelAt<'_>,
    u: &[f64],
    x0: &[f64],
    dt: f64,
    states: bool,
) -> Result<Trajectory> {
    let t_len = check_sizes(model, u, x0)?;
    let (shape, theta, basis) = (&model.shape, model.theta, model.basis);
    check_values(basis, u)?;
    // The states are always kept here.
    super::trajectory_fits(shape, t_len, true)?;
    if !(dt.is_finite() && dt > 0.0) {
        return Err(invalid(
            "dt",
            format!("expected a finite sample time > 0, got {dt}"),
        ));
    }
    let (n, r, nb) = (shape.n, shape.r, shape.nb);
    let nn = n * n;
    let mut x = vec![0.0; (t_len + 1) * n];
    x[..n].copy_from_slice(x0);
    let mut ad = vec![0.0; BLOCK * nn];
    for start in (0..t_len).step_by(BLOCK) {
        let end = (start + BLOCK).min(t_len);
        // Ad(t) into `ad`, x(t+1) <- Bd(t) u(t), in parallel.
        ad[..(end - start) * nn]
            .par_chunks_mut(ZOH_BLOCK * nn)
            .zip(x[(start + 1) * n..(end + 1) * n].par_chunks_mut(ZOH_BLOCK * n))
            .enumerate()
            .try_for_each(|(k, (ads, nexts))| {
                let mut hold = Hold::new(shape, theta, dt);
                for (s, (adt, next)) in ads
                    .chunks_exact_mut(nn)
                    .zip(nexts.chunks_exact_mut(n))
                    .enumerate()
                {
                    let t = start + k * ZOH_BLOCK + s;
                    hold.at(&basis[t * nb..(t + 1) * nb]).map_err(|why| {
                        Error::Numerical(format!("{why} (zero-order hold at sample {t})"))
                    })?;
                    adt.copy_from_slice(&hold.ad);
                    let ut = &u[t * r..(t + 1) * r];
                    for (a, v) in next.iter_mut().enumerate() {
                        *v = dot(&hold.bd[a * r..(a + 1) * r], ut);
                    }
                }
                Ok(())
            })?;
        // x(t+1) += Ad(t) x(t), in order.
        for t in start..end {
            let (past, next) = x.split_at_mut((t + 1) * n);
            let xt = &past[t * n..];
            let adt = &ad[(t - start) * nn..(t - start + 1) * nn];
            for (v, row) in next[..n].iter_mut().zip(adt.chunks_exact(n)) {
                *v += dot(row, xt);
            }
        }
    }
    let y = outputs(model, u, &x);
    Ok(finish(shape, y, x, states))
}

/// The zero-order-hold discretisation of the frozen model, with a cache
/// for runs of equal scheduling values.
struct Hold {
    n: usize,
    r: usize,
    dt: f64,
    a: Wide,
    b: Wide,
    last: Option<Vec<f64>>,
    kron: Vec<f64>,
    /// `[[A, B], [0, 0]] dt`.
    m: DMatrix<f64>,
    /// `Ad`, `n x n` row-major.
    ad: Vec<f64>,
    /// `Bd`, `n x r` row-major.
    bd: Vec<f64>,
}

impl Hold {
    fn new(shape: &Shape, theta: &[f64], dt: f64) -> Hold {
        let (n, r) = (shape.n, shape.r);
        Hold {
            n,
            r,
            dt,
            a: Wide::new(shape, theta, Matrix::A),
            b: Wide::new(shape, theta, Matrix::B),
            last: None,
            kron: vec![0.0; shape.n_coef()],
            m: DMatrix::zeros(n + r, n + r),
            ad: vec![0.0; n * n],
            bd: vec![0.0; n * r],
        }
    }

    /// Discretise at the basis values `psi` (unless they equal the last ones).
    fn at(&mut self, psi: &[f64]) -> std::result::Result<(), String> {
        if self.last.as_deref() == Some(psi) {
            return Ok(());
        }
        let (n, r) = (self.n, self.r);
        // [1, psi]: the weights of X(0..=Nb).
        self.kron[0] = 1.0;
        self.kron[1..].copy_from_slice(psi);
        self.m.fill(0.0);
        for (wide, cols, offset) in [(&self.a, n, 0), (&self.b, r, n)] {
            for row in 0..n {
                let coefs = &wide.data[row * wide.width..(row + 1) * wide.width];
                for (i, &w) in self.kron.iter().enumerate() {
                    for col in 0..cols {
                        self.m[(row, offset + col)] += w * coefs[i * cols + col] * self.dt;
                    }
                }
            }
        }
        let e = expm(&self.m)?;
        for row in 0..n {
            for col in 0..n {
                self.ad[row * n + col] = e[(row, col)];
            }
            for col in 0..r {
                self.bd[row * r + col] = e[(row, n + col)];
            }
        }
        self.last = Some(psi.to_vec());
        Ok(())
    }
}

/// Largest 1-norm handed to nalgebra's exponential unscaled: it forms
/// powers up to `m^10` before it scales, which must stay finite.
const MAX_UNSCALED_NORM: f64 = 4294967296.0; // 2^32

/// `exp(m)` by nalgebra (scaling and squaring with the Padé degree chosen
/// as in Al-Mohy and Higham 2009, the algorithm of `scipy.linalg.expm`).
/// Matrices of a 1-norm above 2^32 are scaled down by a power of two first
/// and the result squared back. Fails only when `m` is not finite or the
/// Padé denominator is singular (which the scaling rules out for finite
/// `m`).
pub fn expm(m: &DMatrix<f64>) -> std::result::Result<DMatrix<f64>, String> {
    // (f64::max ignores NaN: the check of the norm is not enough.)
    let norm = m
        .column_iter()
        .map(|c| c.iter().map(|v| v.abs()).sum::<f64>())
        .fold(0.0, f64::max);
    if !norm.is_finite() || m.iter().any(|v| !v.is_finite()) {
        return Err("matrix exponential of a non-finite matrix".into());
    }
    let squarings = if norm > MAX_UNSCALED_NORM {
        (norm / MAX_UNSCALED_NORM).log2().ceil() as i32
    } else {
        0
    };
    let scaled = m * 0.5f64.powi(squarings);
    // nalgebra unwraps its LU solve of the Padé denominator: a panic here
    // becomes an error, never a crash of the caller.
    let mut e = catch_unwind(AssertUnwindSafe(|| fixed_exp(&scaled)))
        .map_err(|_| "singular Pade denominator in the matrix exponential".to_string())?;
    for _ in 0..squarings {
        e = &e * &e;
    }
    Ok(e)
}

/// `m.exp()` with the size known at compile time for `2 <= s <= 12` (no
/// allocation per product: three times faster than the dynamic size on a
/// 7 x 7 matrix, and faster than the hand-written exponential it replaced);
/// larger matrices take the dynamic path.
macro_rules! fixed_sizes {
    ($m:expr, $($s:literal)*) => {
        match $m.nrows() {
            $($s => DMatrix::from_column_slice(
                $s,
                $s,
                nalgebra::SMatrix::<f64, $s, $s>::from_column_slice($m.as_slice())
                    .exp()
                    .as_slice(),
            ),)*
            _ => $m.exp(),
        }
    };
}

/// nalgebra's exponential, at a fixed size where one is compiled.
fn fixed_exp(m: &DMatrix<f64>) -> DMatrix<f64> {
    fixed_sizes!(m, 2 3 4 5 6 7 8 9 10 11 12)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: &DMatrix<f64>, want: &[f64], tol: f64) {
        for (got, w) in a.transpose().iter().zip(want) {
            assert!((got - w).abs() <= tol, "{got} vs {w}");
        }
    }

    #[test]
    fn expm_of_known_matrices() {
        // A rotation generator, large enough that nalgebra scales and squares.
        let w = 7.3;
        let e = expm(&DMatrix::from_row_slice(2, 2, &[0.0, w, -w, 0.0])).unwrap();
        close(&e, &[w.cos(), w.sin(), -w.sin(), w.cos()], 1e-13);
        // A Jordan block: exp(J) = e^lambda [[1, 1, 1/2], [0, 1, 1], [0, 0, 1]].
        let lam = -0.8;
        let j = [lam, 1.0, 0.0, 0.0, lam, 1.0, 0.0, 0.0, lam];
        let e = expm(&DMatrix::from_row_slice(3, 3, &j)).unwrap();
        let el = lam.exp();
        close(&e, &[el, el, el / 2.0, 0.0, el, el, 0.0, 0.0, el], 1e-15);
        // Beyond the unscaled limit, where nalgebra alone would overflow in
        // m^2: a strongly stable block decays to 0, and a nilpotent one
        // gives I + m.
        let stable = DMatrix::from_row_slice(2, 2, &[-1e200, 1.0, 0.0, -1e200]);
        close(&expm(&stable).unwrap(), &[0.0; 4], 0.0);
        let e = expm(&DMatrix::from_row_slice(2, 2, &[0.0, 1e300, 0.0, 0.0])).unwrap();
        close(&e, &[1.0, 1e300, 0.0, 1.0], 1e285);
        assert_eq!((e[(0, 0)], e[(1, 0)], e[(1, 1)]), (1.0, 0.0, 1.0));
        let bad = DMatrix::from_row_slice(2, 2, &[f64::NAN, 0.0, 0.0, 1.0]);
        assert!(expm(&bad).is_err());
    }

    #[test]
    fn fixed_and_dynamic_sizes_agree() {
        // A size compiled in (7) against nalgebra's dynamic path, and one
        // beyond them (13): both satisfy exp(m) exp(-m) = I.
        let mut rng = crate::testing::Lcg(17);
        for s in [7, 13] {
            let m = DMatrix::from_fn(s, s, |_, _| 2.0 * rng.next_f64());
            let e = expm(&m).unwrap();
            assert!((&e - m.exp()).amax() <= 1e-14 * e.amax());
            let back = &e * expm(&(-&m)).unwrap();
            assert!((back - DMatrix::<f64>::identity(s, s)).amax() < 1e-13);
        }
    }

    #[test]
    fn zoh_of_a_first_order_system() {
        // dx/dt = a(p) x + b u with a(p) = -2 + p, b = 3; y = x.
        let shape = Shape::new(1, 1, 1, 1).unwrap();
        let theta = vec![-2.0, 1.0, 3.0, 0.0, 1.0, 0.0, 0.0, 0.0];
        let dt = 0.05;
        let basis = vec![0.0, 0.5, 0.5, -1.0];
        let u = vec![1.0, -2.0, 0.5, 4.0];
        let at = ModelAt::new(shape, &theta, &basis, u.len());
        let traj = simulate_zoh(&at, &u, &[0.2], dt, true).unwrap();
        let xs = traj.x.unwrap();
        let mut x = 0.2;
        for t in 0..4 {
            let a = -2.0 + basis[t];
            assert!((traj.y[t] - x).abs() < 1e-14);
            x = (a * dt).exp() * x + ((a * dt).exp() - 1.0) / a * 3.0 * u[t];
            assert!((xs[t + 1] - x).abs() < 1e-14, "{} vs {x}", xs[t + 1]);
        }
        assert_eq!(traj.diverged, None);
    }

    #[test]
    fn bad_dt_is_named() {
        let shape = Shape::new(2, 2, 1, 1).unwrap();
        let theta = vec![0.1; shape.len()];
        assert!(matches!(
            simulate_zoh(
                &ModelAt::new(shape, &theta, &[0.0; 3], 3),
                &[0.0; 6],
                &[0.0; 2],
                0.0,
                false
            ),
            Err(Error::InvalidArgument { name: "dt", .. })
        ));
    }
}
