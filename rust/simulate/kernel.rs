//! The fast path for models with `n + l <= 32`: state and output equations
//! in one small matrix per sample, in register-sized blocks, with AVX2 and
//! FMA where the CPU has them (chosen at run time). See the module
//! documentation of [`super`].

// Small matrix kernels index several arrays at once; an index reads best.
#![allow(clippy::needless_range_loop)]

use crate::base::layout::{Matrix, Shape};
use crate::eval::model::ModelAt;

/// Outputs `y` and, when asked for, states `x` (as in [`super::Trajectory`]).
pub(super) type Outputs = (Vec<f64>, Option<Vec<f64>>);

/// Four doubles side by side: one AVX register's worth.
type V4 = [f64; 4];

/// `acc += s v`, lane by lane, with fused multiply-adds when `FUSED` (only
/// where the CPU has them: elsewhere `mul_add` is a slow library call).
#[inline(always)]
fn axpy4<const FUSED: bool>(acc: &mut V4, s: f64, v: &V4) {
    for k in 0..4 {
        acc[k] = if FUSED {
            s.mul_add(v[k], acc[k])
        } else {
            acc[k] + s * v[k]
        };
    }
}

/// A number of basis functions known only at run time.
pub(super) const DYN: usize = usize::MAX;

/// The fast path with the number of basis functions fixed at compile time
/// when it is at most 4.
pub(super) fn lanes_by_nb<const K: usize>(
    model: &ModelAt<'_>,
    u: &[f64],
    x0: &[f64],
    states: bool,
) -> Outputs {
    let lanes = Lanes::<K>::new(&model.shape, model.theta);
    let basis = model.basis;
    match model.shape.nb {
        0 => lanes.simulate::<0>(basis, u, x0, states),
        1 => lanes.simulate::<1>(basis, u, x0, states),
        2 => lanes.simulate::<2>(basis, u, x0, states),
        3 => lanes.simulate::<3>(basis, u, x0, states),
        4 => lanes.simulate::<4>(basis, u, x0, states),
        _ => lanes.simulate::<DYN>(basis, u, x0, states),
    }
}

/// The fast path for `n + l <= 32`. State and output equations together:
/// with `w(t) = [x(t); u(t)]` and the `(n + l) x (n + r)` blocks
/// `S(i) = [[A(i), B(i)], [C(i), D(i)]]`,
///
/// ```text
/// [x(t+1); y(t)] = S(t) w(t),   S(t) = sum_i psi_i(t) S(i),
/// ```
///
/// column by column: column `b` of `S(t)` does not depend on the state, so
/// the processor forms it ahead while the previous step finishes, and
/// only `z += w_b S(t)[:, b]` lies on the sequential path. Columns are
/// padded to `4 K` rows so that every operation works on whole registers
/// and the accumulators stay in registers.
pub(super) struct Lanes<const K: usize> {
    n: usize,
    r: usize,
    l: usize,
    nb: usize,
    /// Column `b` of `S(i)` at index `b (Nb + 1) + i`.
    cols: Vec<[V4; K]>,
}

impl<const K: usize> Lanes<K> {
    pub(super) fn new(shape: &Shape, theta: &[f64]) -> Self {
        let (n, r) = (shape.n, shape.r);
        let m = shape.n_coef();
        let mut cols = vec![[[0.0; 4]; K]; (n + r) * m];
        for i in 0..m {
            for (x, row0, col0) in [
                (Matrix::A, 0, 0),
                (Matrix::B, 0, n),
                (Matrix::C, n, 0),
                (Matrix::D, n, n),
            ] {
                let (rows, ncols) = shape.dims(x);
                let block = &theta[shape.block(x, i)];
                for col in 0..ncols {
                    for row in 0..rows {
                        let at = row0 + row;
                        cols[(col0 + col) * m + i][at / 4][at % 4] = block[row + col * rows];
                    }
                }
            }
        }
        Lanes {
            n,
            r,
            l: shape.l,
            nb: shape.nb,
            cols,
        }
    }

    /// Run with AVX2 and FMA when the CPU has them (checked at run time);
    /// `NB` is the number of basis functions or [`DYN`].
    pub(super) fn simulate<const NB: usize>(
        &self,
        basis: &[f64],
        u: &[f64],
        x0: &[f64],
        states: bool,
    ) -> Outputs {
        let t_len = u.len() / self.r;
        let mut y = vec![0.0; t_len * self.l];
        let mut x = states.then(|| vec![0.0; (t_len + 1) * self.n]);
        let mut run = Run::<K, NB> {
            lanes: self,
            basis,
            u,
            x0,
            y: &mut y,
            xs: x.as_deref_mut(),
        };
        #[cfg(target_arch = "x86_64")]
        if let Some(simd) = pulp::x86::V3::try_new().filter(|_| crate::base::route::Route::avx2()) {
            pulp::Simd::vectorize(simd, run);
            return (y, x);
        }
        run.recursion::<false>();
        (y, x)
    }

    /// The portable kernel even where AVX2 is available (for tests).
    #[cfg(test)]
    pub(super) fn simulate_portable<const NB: usize>(
        &self,
        basis: &[f64],
        u: &[f64],
        x0: &[f64],
    ) -> Vec<f64> {
        let mut y = vec![0.0; u.len() / self.r * self.l];
        Run::<K, NB> {
            lanes: self,
            basis,
            u,
            x0,
            y: &mut y,
            xs: None,
        }
        .recursion::<false>();
        y
    }
}

/// One simulation on the fast path, as an operation that `pulp` compiles
/// for the instruction set found at run time.
struct Run<'a, const K: usize, const NB: usize> {
    lanes: &'a Lanes<K>,
    basis: &'a [f64],
    u: &'a [f64],
    x0: &'a [f64],
    y: &'a mut [f64],
    xs: Option<&'a mut [f64]>,
}

impl<const K: usize, const NB: usize> pulp::WithSimd for Run<'_, K, NB> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(mut self, _simd: S) {
        // Only reached through an instruction set with FMA.
        self.recursion::<true>();
    }
}

impl<const K: usize, const NB: usize> Run<'_, K, NB> {
    #[inline(always)]
    fn recursion<const FUSED: bool>(&mut self) {
        let lanes = self.lanes;
        let (n, r, l) = (lanes.n, lanes.r, lanes.l);
        let nb = if NB == DYN { lanes.nb } else { NB };
        let m = nb + 1;
        let width = n + r;
        let mut w = vec![0.0; width];
        w[..n].copy_from_slice(self.x0);
        if let Some(xs) = self.xs.as_deref_mut() {
            xs[..n].copy_from_slice(self.x0);
        }
        for (t, (yt, ut)) in self
            .y
            .chunks_exact_mut(l)
            .zip(self.u.chunks_exact(r))
            .enumerate()
        {
            let psi = &self.basis[t * nb..(t + 1) * nb];
            for (v, &x) in w[n..].iter_mut().zip(ut) {
                *v = x;
            }
            // Column b of S(t), formed from the coefficients.
            let column = |col: &[[V4; K]]| {
                let mut s = col[0];
                for (c, &weight) in col[1..].iter().zip(psi) {
                    for k in 0..K {
                        axpy4::<FUSED>(&mut s[k], weight, &c[k]);
                    }
                }
                s
            };
            // z = S(t) w, columns in pairs into two accumulators (half the
            // sequential chain, both kept in registers).
            let mut even = [[0.0; 4]; K];
            let mut odd = [[0.0; 4]; K];
            let pairs = lanes.cols.chunks_exact(2 * m);
            let last = pairs.remainder();
            for (cols, wb) in pairs.zip(w.chunks_exact(2)) {
                let (s0, s1) = (column(&cols[..m]), column(&cols[m..]));
                for k in 0..K {
                    axpy4::<FUSED>(&mut even[k], wb[0], &s0[k]);
                    axpy4::<FUSED>(&mut odd[k], wb[1], &s1[k]);
                }
            }
            if !last.is_empty() {
                let s0 = column(last);
                for k in 0..K {
                    axpy4::<FUSED>(&mut even[k], w[width - 1], &s0[k]);
                }
            }
            for k in 0..K {
                for j in 0..4 {
                    even[k][j] += odd[k][j];
                }
            }
            for (a, v) in w[..n].iter_mut().enumerate() {
                *v = even[a / 4][a % 4];
            }
            for (j, v) in yt.iter_mut().enumerate() {
                *v = even[(n + j) / 4][(n + j) % 4];
            }
            if let Some(xs) = self.xs.as_deref_mut() {
                xs[(t + 1) * n..(t + 2) * n].copy_from_slice(&w[..n]);
            }
        }
    }
}
