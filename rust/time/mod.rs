//! The output error of time records along a varying scheduling trajectory
//! (global data), as an [`crate::Objective`].
//!
//! A record holds inputs `u(t)`, the basis values `psi(p(t))` and measured
//! outputs `y(t)` with standard deviations `sigma(t)`. The cost is
//!
//! ```text
//! V(theta) = sum_records sum_{t >= skip} sum_j ((y_model_j(t) - y_j(t)) / sigma_j(t))^2
//! ```
//!
//! with `y_model` the simulation of [`crate::simulate`] (discrete time, or
//! continuous time with a zero-order hold of `u` and `p` over each sample).
//! Its noise floor is the number of real residuals.
//!
//! The Jacobian comes from the forward sensitivity equations of the LPV
//! recursion: for a parameter of `A(i)` or `B(i)` the state sensitivity
//! `s(t) = dx(t)/dtheta` follows `s(t+1) = Ad(t) s(t) + (dAd(t) x(t) +
//! dBd(t) u(t))`, its output sensitivity is `C(t) s(t)`, and parameters of
//! `C(i)` and `D(i)` enter the output directly. In discrete time
//! `dAd = psi_i(t) e_a e_b^T`; in continuous time the forcing is the
//! Fréchet derivative of the matrix exponential (`hold`). Only `J^T J`
//! and `J^T r` are kept, summed block of samples by block of samples
//! (`sensitivity`).
//!
//! Initial states: zero, given, or estimated per record. Estimated ones
//! are eliminated exactly: the cost at `theta` is the least cost over the
//! initial states, and the Gauss-Newton matrix is the Schur complement of
//! the initial-state block (`schur`). A model whose simulation leaves
//! the finite numbers is an error naming the record and the sample (a
//! rejected step inside a fit).

mod columns;
mod frames;
mod gram;
mod hold;
#[cfg(test)]
mod hold_reference;
mod problem;
mod record;
mod schur;
mod sensitivity;
#[cfg(test)]
mod tests;

pub use problem::TimeProblem;
pub use record::{InitialState, Record};
pub(crate) use sensitivity::BLOCK_ROWS;

/// Seconds spent in each stage of a Gauss-Newton evaluation (summed over
/// records and blocks of samples).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StageTimes {
    /// Simulations of the nominal trajectories (including the one from
    /// rest when the initial state is estimated).
    pub simulation: f64,
    /// Matrices at every sample: `A(p(t))`, `C(p(t))`, and in continuous
    /// time the hold and its derivative.
    pub discretisation: f64,
    /// The sensitivity recursion and the Jacobian rows.
    pub sensitivities: f64,
    /// The products `J^T J` and `J^T r`.
    pub gram: f64,
    /// The elimination of the initial states.
    pub schur: f64,
    /// The whole evaluation.
    pub total: f64,
}
