//! The sum of several costs of the same model: FRF data and time records
//! together. Costs, gradients and Gauss-Newton matrices add, and so do
//! the noise floors (each cost is already weighted by its own noise).

use crate::base::layout::{FreeSet, Shape};
use crate::error::{invalid, Result};
use crate::eval::objective::{GaussNewton, Objective};

/// `V = V_1 + V_2 + ...` over objectives of one model shape.
pub struct Sum<'a> {
    parts: Vec<&'a dyn Objective>,
}

impl<'a> Sum<'a> {
    /// Checked constructor: at least one part, all with the same shape.
    pub fn new(parts: Vec<&'a dyn Objective>) -> Result<Self> {
        let Some(first) = parts.first() else {
            return Err(invalid("parts", "a sum needs at least one cost"));
        };
        let shape = *first.shape();
        if let Some(k) = parts.iter().position(|p| *p.shape() != shape) {
            return Err(invalid(
                "parts",
                format!(
                    "cost {k} is of a model with shape {:?}, cost 0 of {:?}",
                    parts[k].shape(),
                    shape
                ),
            ));
        }
        Ok(Sum { parts })
    }
}

impl Objective for Sum<'_> {
    fn shape(&self) -> &Shape {
        self.parts[0].shape()
    }

    fn n_residuals(&self) -> usize {
        self.parts.iter().map(|p| p.n_residuals()).sum()
    }

    fn cost(&self, theta: &[f64]) -> Result<f64> {
        self.parts.iter().map(|p| p.cost(theta)).sum()
    }

    fn response(&self, theta: &[f64]) -> Result<Vec<f64>> {
        let mut out = Vec::new();
        for part in &self.parts {
            out.extend(part.response(theta)?);
        }
        Ok(out)
    }

    fn gauss_newton(&self, theta: &[f64], free: &FreeSet) -> Result<GaussNewton> {
        let mut total = self.parts[0].gauss_newton(theta, free)?;
        for part in &self.parts[1..] {
            let gn = part.gauss_newton(theta, free)?;
            total.vnls += gn.vnls;
            total
                .gradient
                .iter_mut()
                .zip(&gn.gradient)
                .for_each(|(a, b)| *a += b);
            total
                .gram
                .iter_mut()
                .zip(&gn.gram)
                .for_each(|(a, b)| *a += b);
            // The points of every part, when each part has them.
            total.factors = match (total.factors.take(), gn.factors) {
                (Some(a), Some(b)) => a.join(b),
                _ => None,
            };
        }
        Ok(total)
    }
}
