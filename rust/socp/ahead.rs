//! The cone steps of a fit, with the step a rejection would ask for next
//! solved beside each one on the other core.
//!
//! Clarabel solves a cone program on one thread (two threads in its
//! factorisation were measured no faster), so during a solve the second
//! core waits. A step is rejected when the trial point does not lower the
//! objective; the fit then solves the same program again with the damping
//! a rejection gives, from the same point and weights. [`Lookahead`] solves
//! that second program at the same time as the first: when the step is
//! rejected, the next one is already there; when it is accepted, the spare
//! solve is dropped. The steps taken are exactly those of solving one after
//! the other.
//!
//! The fit asks for this only on doubtful steps: the first of a
//! reweighting (it starts from the initial damping) and one after a
//! rejection, which are rejected far more often than a step after an
//! accepted one (gantry path: 5 of 14 and 2 of 11 against 4 of 82; n10: 12
//! of 14 and 12 of 30 against 6 of 52). Solving ahead on every step was
//! measured no faster on the gantry: the two solves share the machine.
//! The price is memory: two solvers and two solves at once (a six-step fit
//! at n = 24 3x3 peaked at 1.38 GB against 1.18 GB on one thread).

use super::{ConeProblem, ConeSolver, ConeStep};
use crate::error::Result;

/// Two Clarabel solvers kept between the steps of one fit, and the spare
/// step solved ahead.
#[derive(Debug)]
pub struct Lookahead {
    main: ConeSolver,
    spare: ConeSolver,
    /// The damping `mu` of the step solved ahead, and that step.
    ahead: Option<(f64, ConeStep)>,
}

impl Lookahead {
    /// Solvers whose cone programs are solved to `tol` (see [`ConeSolver::new`]).
    pub fn new(tol: f64) -> Self {
        Lookahead {
            main: ConeSolver::new(tol),
            spare: ConeSolver::new(tol),
            ahead: None,
        }
    }

    /// The step of `cone` with damping `mu`. With `next_mu` (the damping
    /// after a rejection) and more than one thread in the pool, the step
    /// with `next_mu` is solved beside it and kept for the next call.
    ///
    /// The step solved ahead belongs to this point and these weights: call
    /// [`Lookahead::forget`] whenever either changes.
    pub fn solve(
        &mut self,
        cone: &ConeProblem<'_>,
        mu: f64,
        next_mu: Option<f64>,
    ) -> Result<ConeStep> {
        if let Some((ahead_mu, step)) = self.ahead.take() {
            if ahead_mu == mu {
                return Ok(step);
            }
        }
        match next_mu {
            Some(next) if rayon::current_num_threads() > 1 => {
                let (main, spare) = (&mut self.main, &mut self.spare);
                let (step, ahead) =
                    rayon::join(|| cone.solve(mu, main), || cone.solve(next, spare));
                self.ahead = Some((next, ahead?));
                step
            }
            _ => cone.solve(mu, &mut self.main),
        }
    }

    /// Drop the step solved ahead (the point or the weights changed).
    pub fn forget(&mut self) {
        self.ahead = None;
    }
}
