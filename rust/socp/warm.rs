//! The cone steps of a fit at one point and one set of weights, each
//! solved by Newton's method from the last step solved there.
//!
//! A step is rejected when the trial point does not lower the objective;
//! the fit then solves the same program again with the damping a
//! rejection gives, from the same point and weights. That program's
//! minimiser moves little from the rejected one's, so Newton's method
//! starts there, where from zero it would go the whole way again: the first
//! step of a reweighting (it starts from the initial damping) and its
//! successors are the hard programs of a path, long steps across the
//! groups' kinks (n = 16: 25 and 32 Newton iterations for the first two
//! programs of the first reweighting from zero, 25 and 5 with the second
//! started from the first). The minimiser is unique, so the steps taken
//! are those of cold starts up to the tolerance of the solve (the 16 cases
//! of the scale ladder and the built-in sets chose the same models, the
//! same cone steps, other last bits).
//!
//! Measured against solving each rejected step's successor beside it on
//! the other core from zero (this module's design before; `identify` in
//! one process each, a pair of runs, 2026-11-27): the Newton
//! iterations of the path n = 16 551 -> 444, n = 24 311 -> 276, n = 32 294
//! -> 233; the path's time the same on the gantry, n = 10 and n = 16 (where
//! a factorisation uses the second core poorly and the pair came nearly
//! free), n = 24 30.8 -> 27.7 s, n = 32 142 -> 116 s. One program at a
//! time also holds one solver, not two.

use super::{ConeProblem, ConeSolver, ConeStep};
use crate::error::Result;

/// The Clarabel solver kept between the steps of one fit, and the last
/// step solved at the current point and weights.
#[derive(Debug)]
pub struct WarmSteps {
    solver: ConeSolver,
    last: Option<Vec<f64>>,
}

impl WarmSteps {
    /// A solver whose cone programs are solved to `tol` (see [`ConeSolver::new`]).
    pub fn new(tol: f64) -> Self {
        WarmSteps {
            solver: ConeSolver::new(tol),
            last: None,
        }
    }

    /// The step of `cone` with damping `mu`, Newton's method started from
    /// the last step solved since [`WarmSteps::forget`] (from zero when
    /// there is none).
    ///
    /// The last step belongs to this point and these weights: call
    /// [`WarmSteps::forget`] whenever either changes.
    pub fn solve(&mut self, cone: &ConeProblem<'_>, mu: f64) -> Result<ConeStep> {
        let step = cone.solve_from(mu, &mut self.solver, self.last.as_deref())?;
        if step.step.is_some() {
            self.last.clone_from(&step.step);
        }
        Ok(step)
    }

    /// Start the next step from zero (the point or the weights changed).
    pub fn forget(&mut self) {
        self.last = None;
    }
}
