//! What the optimisers need of an identification problem: the weighted
//! least-squares cost, its gradient and Gauss-Newton matrix over the free
//! parameters. [`crate::Problem`] (local FRF data) is one; time records and
//! sums of costs are others. Levenberg-Marquardt and the l2,1 fit work on
//! any [`Objective`].

use crate::base::layout::{FreeSet, Shape};
use crate::error::Result;
use crate::eval::point_factors::PointFactors;

/// V_NLS with its gradient and Gauss-Newton matrix at one `theta`,
/// restricted to the free parameters.
#[derive(Debug, Clone)]
pub struct GaussNewton {
    /// `V_NLS = r^T r`, `r` the real weighted residual.
    pub vnls: f64,
    /// `dV/dtheta = 2 J^T r` over the free parameters.
    pub gradient: Vec<f64>,
    /// `J^T J` over the free parameters, symmetric, column-major.
    pub gram: Vec<f64>,
    /// `J^T J` and the gradient as every point's factor, where the shape
    /// makes the Levenberg-Marquardt step cheaper that way
    /// ([`crate::eval::point_factors`]); None elsewhere.
    pub factors: Option<PointFactors>,
}

impl GaussNewton {
    /// Number of free parameters.
    pub fn dim(&self) -> usize {
        self.gradient.len()
    }
}

/// A weighted least-squares cost of the parameters of an LPV model.
pub trait Objective: Sync {
    /// The model shape: the layout of theta.
    fn shape(&self) -> &Shape;
    /// The noise floor `M`: the expected cost at the true system when the
    /// noise levels are right (complex residuals of FRF data, real residuals
    /// of time records). The l2,1 objective uses `V / M`.
    fn n_residuals(&self) -> usize;
    /// The cost `V(theta)`; an error when the model cannot be evaluated.
    /// It must equal the `vnls` of [`Objective::gauss_newton`] to the last
    /// bit (summed in the same order): the fits judge some trial points by
    /// the cost alone and go on with the pieces' `vnls`.
    fn cost(&self, theta: &[f64]) -> Result<f64>;
    /// Cost, gradient and `J^T J` at `theta` over the free parameters.
    fn gauss_newton(&self, theta: &[f64], free: &FreeSet) -> Result<GaussNewton>;
    /// The real weighted residual `r` at `theta` (`cost = r^T r`): how the
    /// model responds at the data, in units of the noise.
    fn response(&self, theta: &[f64]) -> Result<Vec<f64>>;
}
