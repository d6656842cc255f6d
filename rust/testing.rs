//! Deterministic numbers for tests and benchmarks (not part of the API).

use crate::layout::{Matrix, Shape};
use crate::time::Record;

/// A linear congruential generator: uniform numbers in `[-0.5, 0.5)`,
/// the same on every machine, with no extra dependency.
#[derive(Debug, Clone)]
pub struct Lcg(pub u64);

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
