//! Frequency-response data at frozen scheduling values (method.md (6)).

use crate::error::{invalid, Result};
use num_complex::Complex64 as C64;

/// Measured FRFs `Gm[q](w_k)` with their standard deviations, on frequency
/// lines shared by all points, and the evaluation points `z_k` of the model
/// (`exp(j w_k Ts)` in discrete time, `j w_k` in continuous time).
///
/// Arrays are row-major `(N, F, l, r)`, as numpy stores them.
#[derive(Debug, Clone)]
pub struct FrfData {
    n_points: usize,
    l: usize,
    r: usize,
    z: Vec<C64>,
    g: Vec<C64>,
    weight: Vec<f64>,
}

impl FrfData {
    /// Checked constructor. `sigma` must be finite and positive; it is
    /// stored as the weight `1 / sigma`.
    pub fn new(
        n_points: usize,
        l: usize,
        r: usize,
        z: Vec<C64>,
        g: Vec<C64>,
        sigma: &[f64],
    ) -> Result<Self> {
        if n_points == 0 {
            return Err(invalid("G", "no scheduling points"));
        }
        if z.is_empty() {
            return Err(invalid("freqs", "no frequency lines"));
        }
        if l == 0 || r == 0 {
            return Err(invalid("G", "needs at least one output and one input"));
        }
        let len = n_points * z.len() * l * r;
        if g.len() != len {
            return Err(invalid(
                "G",
                format!("expected {len} values (N*F*l*r), got {}", g.len()),
            ));
        }
        if sigma.len() != len {
            return Err(invalid(
                "sigma",
                format!("expected {len} values (N*F*l*r), got {}", sigma.len()),
            ));
        }
        if z.iter().any(|v| !v.re.is_finite() || !v.im.is_finite()) {
            return Err(invalid("freqs", "contains NaN or Inf"));
        }
        if g.iter().any(|v| !v.re.is_finite() || !v.im.is_finite()) {
            return Err(invalid("G", "contains NaN or Inf"));
        }
        if sigma.iter().any(|&s| !(s.is_finite() && s > 0.0)) {
            return Err(invalid("sigma", "must be finite and > 0 everywhere"));
        }
        let weight = sigma.iter().map(|&s| 1.0 / s).collect();
        Ok(FrfData {
            n_points,
            l,
            r,
            z,
            g,
            weight,
        })
    }

    /// Number of scheduling points `N`.
    pub fn n_points(&self) -> usize {
        self.n_points
    }

    /// Number of frequency lines `F`.
    pub fn n_lines(&self) -> usize {
        self.z.len()
    }

    /// Number of outputs.
    pub fn l(&self) -> usize {
        self.l
    }

    /// Number of inputs.
    pub fn r(&self) -> usize {
        self.r
    }

    /// Evaluation points `z_k`.
    pub fn z(&self) -> &[C64] {
        &self.z
    }

    /// Measured FRF values, `(N, F, l, r)` row-major.
    pub fn g(&self) -> &[C64] {
        &self.g
    }

    /// Weights `1 / sigma`, `(N, F, l, r)` row-major.
    pub fn weight(&self) -> &[f64] {
        &self.weight
    }

    /// Number of complex residuals `N F l r` (the noise floor of V_NLS).
    pub fn n_residuals(&self) -> usize {
        self.g.len()
    }

    /// Offset of entry `(q, k, 0, 0)`.
    pub(crate) fn offset(&self, q: usize, k: usize) -> usize {
        (q * self.z.len() + k) * self.l * self.r
    }
}
