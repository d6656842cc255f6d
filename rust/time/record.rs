//! One time record and how its initial state is treated.

use crate::base::layout::Shape;
use crate::error::{invalid, Result};

/// One record: inputs, basis values along the scheduling trajectory,
/// measured outputs and their weights `1 / sigma`, all row-major by sample.
#[derive(Debug, Clone)]
pub struct Record {
    len: usize,
    u: Vec<f64>,
    psi: Vec<f64>,
    y: Vec<f64>,
    w: Vec<f64>,
}

/// Whether every value is finite.
fn finite(v: &[f64]) -> bool {
    v.iter().all(|x| x.is_finite())
}

impl Record {
    /// Checked constructor: `u` is `T x r`, `psi` the `T x Nb` values
    /// `psi_1..psi_Nb` at `p(t)`, `y` and `sigma` are `T x l` (sigma > 0).
    pub fn new(
        shape: &Shape,
        u: Vec<f64>,
        psi: Vec<f64>,
        y: Vec<f64>,
        sigma: &[f64],
    ) -> Result<Record> {
        let (r, l, nb) = (shape.r, shape.l, shape.nb);
        if u.is_empty() || !u.len().is_multiple_of(r) {
            return Err(invalid(
                "u",
                format!("expected T x {r} input values with T >= 1, got {}", u.len()),
            ));
        }
        let len = u.len() / r;
        for (name, v, width) in [("psi", &psi, nb), ("y", &y, l)] {
            if v.len() != len * width {
                return Err(invalid(
                    name,
                    format!(
                        "expected {} values ({len} samples x {width}), got {}",
                        len * width,
                        v.len()
                    ),
                ));
            }
        }
        if sigma.len() != len * l {
            return Err(invalid(
                "sigma",
                format!(
                    "expected {} values ({len} samples x {l}), got {}",
                    len * l,
                    sigma.len()
                ),
            ));
        }
        for (name, v) in [("u", &u), ("psi", &psi), ("y", &y)] {
            if !finite(v) {
                return Err(invalid(name, "contains NaN or Inf"));
            }
        }
        if !sigma.iter().all(|s| s.is_finite() && *s > 0.0) {
            return Err(invalid("sigma", "expected finite values > 0"));
        }
        let w = sigma.iter().map(|s| 1.0 / s).collect();
        Ok(Record { len, u, psi, y, w })
    }

    /// Number of samples `T`.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Always false: a record has at least one sample.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Inputs, `T x r` row-major.
    pub fn u(&self) -> &[f64] {
        &self.u
    }

    /// Basis values `psi_1..psi_Nb`, `T x Nb` row-major.
    pub fn psi(&self) -> &[f64] {
        &self.psi
    }

    /// Measured outputs, `T x l` row-major.
    pub fn y(&self) -> &[f64] {
        &self.y
    }

    /// Weights `1 / sigma`, `T x l` row-major.
    pub fn weight(&self) -> &[f64] {
        &self.w
    }
}

/// How the initial state `x(0)` of every record is treated.
#[derive(Debug, Clone, PartialEq)]
pub enum InitialState {
    /// `x(0) = 0`: the system starts at rest.
    Zero,
    /// `x(0)` is estimated for every record: the cost at `theta` is the
    /// least value over the initial states (the outputs are linear in
    /// `x(0)`), and the initial states are eliminated from the
    /// Gauss-Newton matrix by a Schur complement.
    Estimate,
    /// `x(0)` given for every record, `records x n` values row-major.
    Given(Vec<f64>),
}
