//! Time-domain simulation of an LPV model along a scheduling trajectory.
//!
//! Discrete time, with `X(p) = X(0) + sum_i psi_i(p) X(i)`:
//!
//! ```text
//! x(t+1) = A(p(t)) x(t) + B(p(t)) u(t)
//! y(t)   = C(p(t)) x(t) + D(p(t)) u(t)
//! ```
//!
//! Only the state recursion is sequential: the input term `B(p(t)) u(t)`
//! and the outputs do not feed back. Two paths compute the same thing:
//!
//! - models with `n + l <= 32` (the common case): state and output
//!   equations in one, `[x(t+1); y(t)] = S(t) [x(t); u(t)]` with
//!   `S(t) = sum_i psi_i(t) [[A(i), B(i)], [C(i), D(i)]]`, in register-sized
//!   blocks, with AVX2 and FMA where the CPU has them (chosen at run time).
//!   Forming `S(t)` does not depend on the state, so the processor works on
//!   it ahead; only the product with the state is on the sequential path.
//! - larger models: with `k(v) = [v; psi_1 v; ...; psi_Nb v]` every product
//!   is one matrix times a vector, `A(p) x = [A(0) ... A(Nb)] k(x)`; the
//!   input term and the outputs are computed in bulk, in parallel over
//!   blocks of samples, and the recursion runs in order in between.
//!
//! Continuous time (`dx/dt = A(p) x + B(p) u`) is simulated with a
//! zero-order hold of both `u` and `p` over each sample of length `dt`: the
//! exact solution for piecewise-constant input and scheduling,
//! `x(t+1) = Ad x(t) + Bd u(t)` with
//! `[[Ad, Bd], [0, I]] = exp([[A, B], [0, 0]] dt)` and `A`, `B` frozen at
//! `p(t)`; `y(t) = C(p(t)) x(t) + D(p(t)) u(t)`. At a constant `p` this is
//! the usual ZOH discretisation of the frozen model.
//!
//! The code is split by concern: the entry points and the checks here,
//! the fast path in `kernel`, the general path in `wide` and the
//! zero-order hold in `zoh`.
//!
//! An unstable model (or one unstable along the trajectory) is simulated
//! as it is: its values grow past the range of floating point. The
//! [`Trajectory`] then names the first sample where a returned value is
//! not finite, so that the caller can warn or stop.

mod kernel;
mod wide;
mod zoh;

pub use zoh::{expm, simulate_zoh};

use crate::base::layout::Shape;
use crate::error::{invalid, Result};
use crate::eval::model::ModelAt;
use kernel::{lanes_by_nb, Lanes, DYN};
use wide::simulate_wide;

/// Samples per task of the bulk (parallel) parts.
const BLOCK: usize = 4096;

/// A simulated trajectory.
#[derive(Debug, Clone, PartialEq)]
pub struct Trajectory {
    /// Outputs `y(0..T)`, `T x l` row-major.
    pub y: Vec<f64>,
    /// States `x(0..=T)`, `(T + 1) x n` row-major, when asked for; the last
    /// row is the state after the last sample (to continue a simulation).
    pub x: Option<Vec<f64>>,
    /// The first sample `t` whose output `y(t)` or (when the states are
    /// kept) state `x(t + 1)` is not finite: where the simulation left the
    /// range of floating point. `None` when every value is finite.
    pub diverged: Option<usize>,
}

impl Trajectory {
    /// Wrap outputs and states (`l` outputs, `n` states) and find where
    /// they diverge, if they do.
    fn new(l: usize, n: usize, y: Vec<f64>, x: Option<Vec<f64>>) -> Trajectory {
        let first = |v: &[f64], width: usize| {
            if all_finite(v) {
                None
            } else {
                v.iter().position(|a| !a.is_finite()).map(|i| i / width)
            }
        };
        let in_y = first(&y, l);
        // x(t + 1) is row t of x[n..].
        let in_x = x.as_deref().and_then(|x| first(&x[n..], n));
        let diverged = match (in_y, in_x) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        };
        Trajectory { y, x, diverged }
    }
}

/// Outputs and the full state trajectory of the wide and zero-order-hold
/// paths as a [`Trajectory`] (states kept when asked for).
fn finish(shape: &Shape, y: Vec<f64>, x: Vec<f64>, states: bool) -> Trajectory {
    Trajectory::new(shape.l, shape.n, y, states.then_some(x))
}

/// Whether every value is finite, without an early exit per value (so that
/// the check vectorises: it runs over every sample of a long trajectory).
fn all_finite(v: &[f64]) -> bool {
    v.chunks(64)
        .all(|c| c.iter().fold(true, |ok, a| ok & a.is_finite()))
}

/// Check the sizes of a simulation's arguments (the basis values against
/// the number of samples `T` that `u` gives) and that `theta` and `x0` are
/// finite; returns `T`.
fn check_sizes(model: &ModelAt<'_>, u: &[f64], x0: &[f64]) -> Result<usize> {
    let (shape, basis) = (&model.shape, model.basis);
    shape.check_theta(model.theta)?;
    let (n, r, nb) = (shape.n, shape.r, shape.nb);
    if !u.len().is_multiple_of(r) {
        return Err(invalid(
            "u",
            format!("expected T x {r} input values, got {}", u.len()),
        ));
    }
    let t = u.len() / r;
    if basis.len() != t * nb {
        return Err(invalid(
            "psi",
            format!(
                "expected {} basis values ({t} samples x {nb} functions), got {}",
                t * nb,
                basis.len()
            ),
        ));
    }
    if x0.len() != n {
        return Err(invalid(
            "x0",
            format!("expected {n} initial states, got {}", x0.len()),
        ));
    }
    if !all_finite(x0) {
        return Err(invalid("x0", "contains NaN or Inf"));
    }
    Ok(t)
}

/// Check that the basis values and inputs are finite.
fn check_values(basis: &[f64], u: &[f64]) -> Result<()> {
    for (name, v) in [("psi", basis), ("u", u)] {
        if !all_finite(v) {
            return Err(invalid(name, "contains NaN or Inf"));
        }
    }
    Ok(())
}

/// Check that the simulated trajectory (outputs, and the states with
/// `states` or on the wide path) can be had: [`crate::Error::OutOfMemory`]
/// before any work rather than an abort while the kernels allocate.
fn trajectory_fits(shape: &Shape, t_len: usize, states: bool) -> Result<()> {
    let wide = (shape.n + shape.l).div_ceil(4) > 8;
    let x = if states || wide {
        (t_len + 1) * shape.n
    } else {
        0
    };
    let bytes = (t_len * shape.l + x).saturating_mul(8);
    crate::memory::probe(bytes, "the simulated trajectory")
}

/// Simulate a discrete-time LPV model.
///
/// `model` is the model at `p(0..T)`: its basis values are the `T x Nb`
/// values `psi_1..psi_Nb` (row-major), `T` being the number of samples
/// that `u` gives (the basis values are checked against it; `n_points` is
/// not read). `u` holds the `T x r` inputs (row-major) and `x0` the
/// initial state; with `states` the trajectory keeps `x(0..=T)`. Unstable
/// models give non-finite values, not an error: [`Trajectory::diverged`]
/// names the first sample where they appear.
pub fn simulate(model: &ModelAt<'_>, u: &[f64], x0: &[f64], states: bool) -> Result<Trajectory> {
    let t_len = check_sizes(model, u, x0)?;
    let (shape, theta, basis) = (&model.shape, model.theta, model.basis);
    trajectory_fits(shape, t_len, states)?;
    // Monomorphised kernels: K = ceil((n + l) / 4) register blocks and,
    // for K <= 4, the number of basis functions (small models are the
    // common case; the rest runs with Nb known at run time).
    let (y, x) = match (shape.n + shape.l).div_ceil(4) {
        1 => lanes_by_nb::<1>(model, u, x0, states),
        2 => lanes_by_nb::<2>(model, u, x0, states),
        3 => lanes_by_nb::<3>(model, u, x0, states),
        4 => lanes_by_nb::<4>(model, u, x0, states),
        5 => Lanes::<5>::new(shape, theta).simulate::<DYN>(basis, u, x0, states),
        6 => Lanes::<6>::new(shape, theta).simulate::<DYN>(basis, u, x0, states),
        7 => Lanes::<7>::new(shape, theta).simulate::<DYN>(basis, u, x0, states),
        8 => Lanes::<8>::new(shape, theta).simulate::<DYN>(basis, u, x0, states),
        _ => {
            let (y, x) = simulate_wide(model, u, x0);
            (y, states.then_some(x))
        }
    };
    let traj = Trajectory::new(shape.l, shape.n, y, x);
    // Every output y(t) is a sum of products that involve every psi_i(t),
    // every u(t) and (through the state) every earlier value, and a NaN or
    // Inf factor makes such a sum NaN (0 * Inf = NaN). So finite outputs
    // prove finite inputs, and the inputs are only scanned (to name the bad
    // one) when an output is not finite, which an unstable model may also
    // cause.
    if traj.diverged.is_some() {
        check_values(basis, u)?;
    }
    Ok(traj)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::base::layout::Matrix;
    use crate::error::Error;
    use crate::eval::lti::Frozen;
    use crate::testing::Lcg;

    /// The model along the `T` samples of `u`.
    fn along<'a>(shape: &Shape, theta: &'a [f64], basis: &'a [f64], u: &[f64]) -> ModelAt<'a> {
        ModelAt::new(*shape, theta, basis, u.len() / shape.r)
    }

    fn model(n: usize, r: usize, l: usize, nb: usize, a0: f64) -> (Shape, Vec<f64>) {
        let shape = Shape::new(n, r, l, nb).unwrap();
        let mut rng = Lcg(3 + n as u64);
        let mut theta: Vec<f64> = (0..shape.len()).map(|_| 0.4 * rng.next_f64()).collect();
        let blk = shape.block(Matrix::A, 0);
        for k in 0..n {
            theta[blk.start + k * (n + 1)] += a0;
        }
        (shape, theta)
    }

    /// The recursion written out with the frozen matrices at every sample:
    /// `(y, x(0..=T))`.
    fn naive(
        shape: &Shape,
        theta: &[f64],
        basis: &[f64],
        u: &[f64],
        x0: &[f64],
    ) -> (Vec<f64>, Vec<f64>) {
        let (n, r, l, nb) = (shape.n, shape.r, shape.l, shape.nb);
        let t_len = u.len() / r;
        let mut x = x0.to_vec();
        let mut xs = x0.to_vec();
        let mut y = Vec::new();
        for t in 0..t_len {
            let mut psi = vec![1.0];
            psi.extend_from_slice(&basis[t * nb..(t + 1) * nb]);
            let m = Frozen::at(shape, theta, &psi);
            let ut = &u[t * r..(t + 1) * r];
            for j in 0..l {
                let cx: f64 = (0..n).map(|a| m.c[j + a * l] * x[a]).sum();
                let du: f64 = (0..r).map(|c| m.d[j + c * l] * ut[c]).sum();
                y.push(cx + du);
            }
            x = (0..n)
                .map(|a| {
                    (0..n).map(|b| m.a[a + b * n] * x[b]).sum::<f64>()
                        + (0..r).map(|c| m.b[a + c * n] * ut[c]).sum::<f64>()
                })
                .collect();
            xs.extend_from_slice(&x);
        }
        (y, xs)
    }

    fn assert_close(a: &[f64], b: &[f64], scale: f64) {
        assert_eq!(a.len(), b.len());
        for (p, q) in a.iter().zip(b) {
            assert!((p - q).abs() <= 1e-12 * scale, "{p} vs {q}");
        }
    }

    #[test]
    fn recursion_matches_the_frozen_matrices_sample_by_sample() {
        // Sizes on the lane path (n, l <= 16), with padding (n = 3, 6, 13)
        // and without (n = 4, 16), and on the general path (n or l > 16),
        // which also runs over several blocks.
        for (n, r, l, nb, t_len) in [
            (1, 1, 1, 0, 7),
            (3, 2, 2, 2, 300),
            (4, 3, 5, 1, 40),
            (6, 1, 2, 4, 50),
            (13, 2, 9, 3, 30),
            (16, 1, 16, 2, 30),
            (17, 2, 3, 2, 9000),
            (2, 1, 18, 1, 20),
            (3, 1, 2, 6, 50),
            (20, 2, 14, 1, 5000),
        ] {
            let (shape, theta) = model(n, r, l, nb, 0.5 / (1.0 + n as f64 / 8.0));
            let mut rng = Lcg(99);
            let basis: Vec<f64> = (0..t_len * nb).map(|_| rng.next_f64()).collect();
            let u: Vec<f64> = (0..t_len * r).map(|_| rng.next_f64()).collect();
            let x0: Vec<f64> = (0..n).map(|_| rng.next_f64()).collect();
            let (y, x) = naive(&shape, &theta, &basis, &u, &x0);
            let scale = y.iter().fold(1.0f64, |m, v| m.max(v.abs()));
            let at = along(&shape, &theta, &basis, &u);
            let with = simulate(&at, &u, &x0, true).unwrap();
            assert_close(&with.y, &y, scale);
            assert_close(with.x.as_deref().unwrap(), &x, scale);
            let without = simulate(&at, &u, &x0, false).unwrap();
            assert_eq!(without.y, with.y);
            assert!(without.x.is_none());
        }
    }

    #[test]
    fn portable_kernel_matches_too() {
        let (shape, theta) = model(6, 1, 2, 4, 0.5);
        let t_len = 200;
        let mut rng = Lcg(5);
        let basis: Vec<f64> = (0..t_len * 4).map(|_| rng.next_f64()).collect();
        let u: Vec<f64> = (0..t_len).map(|_| rng.next_f64()).collect();
        let x0: Vec<f64> = (0..6).map(|_| rng.next_f64()).collect();
        let (y, _) = naive(&shape, &theta, &basis, &u, &x0);
        let scale = y.iter().fold(1.0f64, |m, v| m.max(v.abs()));
        let lanes = Lanes::<2>::new(&shape, &theta);
        assert_close(&lanes.simulate_portable::<4>(&basis, &u, &x0), &y, scale);
        assert_close(&lanes.simulate_portable::<DYN>(&basis, &u, &x0), &y, scale);
    }

    #[test]
    fn unstable_models_give_non_finite_values_but_nan_inputs_are_named() {
        let (shape, theta) = model(2, 1, 1, 1, 3.0);
        let t_len = 2000;
        let basis = vec![0.1; t_len];
        let u = vec![1.0; t_len];
        let at = along(&shape, &theta, &basis, &u);
        let traj = simulate(&at, &u, &[0.0, 0.0], false).unwrap();
        let first = traj.y.iter().position(|v| !v.is_finite()).unwrap();
        assert_eq!(traj.diverged, Some(first));
        let mut bad = basis.clone();
        bad[1234] = f64::INFINITY;
        let (shape, theta) = model(2, 1, 1, 1, 0.5);
        assert!(matches!(
            simulate(&along(&shape, &theta, &bad, &u), &u, &[0.0, 0.0], false),
            Err(Error::InvalidArgument { name: "psi", .. })
        ));
    }

    #[test]
    fn divergence_is_found_at_its_first_sample() {
        // x(t+1) = 10 x(t) + u(t), y = x, from x(0) = 1: x(t) = 10^t, so
        // y(308) = 1e308 is the last finite output and x(309) the first
        // infinite state.
        let shape = Shape::new(1, 1, 1, 0).unwrap();
        let theta = vec![10.0, 0.0, 1.0, 0.0];
        let u = vec![0.0; 400];
        let at = along(&shape, &theta, &[], &u);
        let traj = simulate(&at, &u, &[1.0], false).unwrap();
        assert_eq!(traj.diverged, Some(309));
        assert!(traj.y[308].is_finite() && traj.y[308] > 9e307);
        let traj = simulate(&at, &u, &[1.0], true).unwrap();
        assert_eq!(traj.diverged, Some(308));
        // The same on the wide path (n + l > 32), where the state of a
        // larger diagonal model diverges the same way.
        let shape = Shape::new(17, 1, 17, 0).unwrap();
        let mut theta = vec![0.0; shape.len()];
        for k in 0..17 {
            theta[shape.block(Matrix::A, 0).start + k * 18] = 10.0;
            theta[shape.block(Matrix::C, 0).start + k * 18] = 1.0;
        }
        let traj = simulate(&along(&shape, &theta, &[], &u), &u, &[1.0; 17], false).unwrap();
        assert_eq!(traj.diverged, Some(309));
        let short = &u[..300];
        let stable = simulate(&along(&shape, &theta, &[], short), short, &[1.0; 17], true).unwrap();
        assert_eq!(stable.diverged, None);
    }

    #[test]
    fn bad_sizes_and_values_are_named() {
        let (shape, theta) = model(2, 2, 1, 1, 0.5);
        // The basis values at as many points as they have rows: `simulate`
        // checks them against the samples of `u`.
        let err = |basis: &[f64], u: &[f64], x0: &[f64]| match simulate(
            &ModelAt::new(shape, &theta, basis, basis.len()),
            u,
            x0,
            false,
        ) {
            Err(Error::InvalidArgument { name, .. }) => name,
            other => panic!("expected an error, got {other:?}"),
        };
        assert_eq!(err(&[0.0; 3], &[0.0; 5], &[0.0; 2]), "u");
        assert_eq!(err(&[0.0; 2], &[0.0; 6], &[0.0; 2]), "psi");
        assert_eq!(err(&[0.0; 3], &[0.0; 6], &[0.0; 3]), "x0");
        assert_eq!(err(&[0.0; 3], &[f64::NAN; 6], &[0.0; 2]), "u");
    }
}
