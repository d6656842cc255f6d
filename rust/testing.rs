//! Deterministic numbers for tests and benchmarks (not part of the API).

use crate::base::layout::{Matrix, Shape};
use crate::time::Record;

/// A linear congruential generator: uniform numbers in `[-0.5, 0.5)`,
/// the same on every machine, with no extra dependency.
#[derive(Debug, Clone)]
pub struct Lcg(pub u64);

/// `f` run on a pool of its own of `threads` threads (where faer's calls
/// on "every thread" and the core's parallel loops see that number).
pub fn on_threads<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("a thread pool for a test")
        .install(f)
}

/// A symmetric positive definite `n x n` matrix, `B B^T + I/2` for an
/// irregular `n x (n + 3)` matrix `B`: no entry of its Cholesky factor is
/// a round number.
pub fn spd_matrix(n: usize, seed: f64) -> faer::Mat<f64> {
    let b = faer::Mat::from_fn(n, n + 3, |i, j| {
        (((i * 31 + j * 17) % 101) as f64 * 0.713 + seed).sin() * (1.0 + ((i + 2 * j) % 5) as f64)
    });
    let mut a = faer::Mat::from_fn(n, n, |i, j| if i == j { 0.5 } else { 0.0 });
    faer::linalg::matmul::matmul(
        a.as_mut(),
        faer::Accum::Add,
        b.as_ref(),
        b.transpose(),
        1.0,
        faer::Par::Seq,
    );
    a
}

/// An `n x n` block diagonal of damped rotations, column-major (`n` even):
/// block `k` turns by angle `w` at radius `r`, `(r, w) = rotation(k)`. Its
/// poles are `r e^(+-iw)`, a stable discrete-time `A` for `r < 1`.
pub fn damped_rotations(n: usize, rotation: impl Fn(usize) -> (f64, f64)) -> Vec<f64> {
    let mut a = vec![0.0; n * n];
    for k in 0..n / 2 {
        let (r, w) = rotation(k);
        let (i, j) = (2 * k, 2 * k + 1);
        a[i + i * n] = r * w.cos();
        a[j + j * n] = r * w.cos();
        a[i + j * n] = r * w.sin();
        a[j + i * n] = -r * w.sin();
    }
    a
}

/// `||a - b|| / ||b||`: how far a vector is from a reference.
pub fn relative_gap(a: &[f64], b: &[f64]) -> f64 {
    let gap = a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum::<f64>();
    let size = b.iter().map(|y| y * y).sum::<f64>();
    (gap / size).sqrt()
}

impl Lcg {
    /// The next number, uniform in `[-0.5, 0.5)`.
    pub fn next_f64(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64) / ((1u64 << 53) as f64) - 0.5
    }
}

/// A random model with stable frozen dynamics along [`time_records`]
/// (`A(0)` shifted by 0.4 I in discrete time, by -1.2 I in continuous time).
pub fn time_model(shape: &Shape, discrete: bool, seed: u64) -> Vec<f64> {
    let n = shape.n;
    let mut rng = Lcg(seed);
    let mut theta: Vec<f64> = (0..shape.len()).map(|_| 0.25 * rng.next_f64()).collect();
    let a0 = shape.block(Matrix::A, 0);
    for k in 0..n {
        theta[a0.start + k * (n + 1)] += if discrete { 0.4 } else { -1.2 };
    }
    theta
}

/// Random time records of the given lengths whose scheduling moves fast
/// (basis values change every sample).
pub fn time_records(shape: &Shape, lens: &[usize], seed: u64) -> Vec<Record> {
    let mut rng = Lcg(seed);
    lens.iter()
        .map(|&t| {
            let psi: Vec<f64> = (0..t)
                .flat_map(|k| {
                    let p = (0.37 * k as f64).sin();
                    let q = 2.0 * rng.next_f64();
                    (1..=shape.nb).map(move |i| if i % 2 == 1 { p.powi(i as i32) } else { p * q })
                })
                .collect();
            let u: Vec<f64> = (0..t * shape.r).map(|_| 2.0 * rng.next_f64()).collect();
            let y: Vec<f64> = (0..t * shape.l).map(|_| rng.next_f64()).collect();
            let sigma: Vec<f64> = (0..t * shape.l)
                .map(|_| 0.3 + rng.next_f64().abs())
                .collect();
            Record::new(shape, u, psi, y, &sigma).expect("valid test records")
        })
        .collect()
}

#[cfg(test)]
pub use counting::{expected_calls, Counted};

/// Counting a fit's evaluations (the optimisers' tests).
#[cfg(test)]
mod counting {
    use crate::base::layout::{FreeSet, Shape};
    use crate::error::Result;
    use crate::eval::objective::{GaussNewton, Objective};
    use crate::fit::Iteration;
    use std::sync::atomic::{AtomicUsize, Ordering::Relaxed};

    /// An objective that counts its evaluations: of the cost alone and of
    /// the Gauss-Newton pieces.
    pub struct Counted<'a> {
        inner: &'a dyn Objective,
        costs: AtomicUsize,
        pieces: AtomicUsize,
    }

    impl<'a> Counted<'a> {
        /// `inner`, counted from zero.
        pub fn new(inner: &'a dyn Objective) -> Self {
            Counted {
                inner,
                costs: AtomicUsize::new(0),
                pieces: AtomicUsize::new(0),
            }
        }

        /// The calls so far: `(cost, gauss_newton)`.
        pub fn calls(&self) -> (usize, usize) {
            (self.costs.load(Relaxed), self.pieces.load(Relaxed))
        }
    }

    impl Objective for Counted<'_> {
        fn shape(&self) -> &Shape {
            self.inner.shape()
        }
        fn n_residuals(&self) -> usize {
            self.inner.n_residuals()
        }
        fn cost(&self, theta: &[f64]) -> Result<f64> {
            self.costs.fetch_add(1, Relaxed);
            self.inner.cost(theta)
        }
        fn gauss_newton(&self, theta: &[f64], free: &FreeSet) -> Result<GaussNewton> {
            self.pieces.fetch_add(1, Relaxed);
            self.inner.gauss_newton(theta, free)
        }
        fn response(&self, theta: &[f64]) -> Result<Vec<f64>> {
            self.inner.response(theta)
        }
    }

    /// The evaluations a fit with this history should have made, `(cost,
    /// gauss_newton)`: the pieces at the start; for every solved step that
    /// is `doubtful(k)`, its cost, and its pieces when it was taken; for
    /// every other solved step, its pieces.
    pub fn expected_calls(
        history: &[Iteration],
        doubtful: impl Fn(usize) -> bool,
    ) -> (usize, usize) {
        let (mut costs, mut pieces) = (0, 1);
        for (k, it) in history.iter().enumerate() {
            if !it.step_norm.is_finite() {
                continue; // no step to evaluate
            }
            if doubtful(k) {
                costs += 1;
                pieces += usize::from(it.accepted);
            } else {
                pieces += 1;
            }
        }
        (costs, pieces)
    }
}
