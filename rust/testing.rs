//! Deterministic numbers for tests and benchmarks (not part of the API).

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
