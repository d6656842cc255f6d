//! What the fitting routines share: the record of one iteration, the
//! outcome of a fit, the damping rule, and the monitor through which a
//! caller follows progress and stops a run; and the fits on them:
//! Levenberg-Marquardt ([`lm`]), the stability guard ([`stable`]) and the
//! estimate of a fit's memory ([`estimate`]). The l2,1 fit is [`crate::l21`],
//! its cone step [`crate::socp`].

pub mod estimate;
pub mod lm;
#[cfg(test)]
mod spread_tests;
pub mod stable;

use crate::error::{invalid, Result};
use std::time::Instant;

/// Which kind of step an iteration computed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StepKind {
    /// A Levenberg-Marquardt step on V_NLS.
    Lm,
    /// A second-order cone step of the regularised problem (method.md (27)).
    Socp,
}

/// One row of a fit's history: one step computed, accepted or not.
#[derive(Debug, Clone)]
pub struct Iteration {
    /// Step kind.
    pub kind: StepKind,
    /// Outer (reweighting) iteration, 0 for Levenberg-Marquardt.
    pub outer: usize,
    /// V_NLS after the iteration (at the new point if accepted, else at the old).
    pub vnls: f64,
    /// Objective after the iteration: V_NLS for LM, V_NLS / M + gamma * penalty for l2,1.
    pub objective: f64,
    /// Norm of the computed step.
    pub step_norm: f64,
    /// Damping `lambda` of method.md (18) used for the step (`lambda^2` multiplies diag J^T J).
    pub lambda: f64,
    /// Whether the step was taken.
    pub accepted: bool,
    /// Actual over predicted decrease of the objective.
    pub gain_ratio: f64,
    /// Status of the step's linear or cone solve.
    pub status: String,
    /// Iterations of the cone solver (0 for LM).
    pub solver_iterations: u32,
    /// Wall time of the iteration in seconds.
    pub seconds: f64,
}

/// Why a fit stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stop {
    /// The step became smaller than the tolerance.
    StepSize,
    /// The objective stopped decreasing (relative change below tolerance).
    CostChange,
    /// The gradient vanished.
    Gradient,
    /// The weights of the reweighting loop stopped changing.
    Weights,
    /// The groups in use and V_NLS stopped changing between reweightings.
    Settled,
    /// The iteration limit was reached.
    MaxIterations,
    /// No damping made the objective decrease.
    Damping,
    /// The caller asked to stop (callback or Ctrl-C).
    Interrupted,
    /// Nothing to optimise: no free parameter.
    NothingFree,
}

impl Stop {
    /// Whether the fit counts as converged.
    pub fn converged(self) -> bool {
        matches!(
            self,
            Stop::StepSize
                | Stop::CostChange
                | Stop::Gradient
                | Stop::Weights
                | Stop::Settled
                | Stop::NothingFree
        )
    }

    /// A sentence for users.
    pub fn message(self) -> &'static str {
        match self {
            Stop::StepSize => "converged: the step is below the tolerance",
            Stop::CostChange => {
                "converged: the relative change of the objective is below the tolerance"
            }
            Stop::Gradient => "converged: the gradient vanished",
            Stop::Weights => "converged: the reweighting weights stopped changing",
            Stop::Settled => "converged: the groups in use and the fit settled",
            Stop::MaxIterations => "stopped: iteration limit reached",
            Stop::Damping => {
                "stopped: no damping gives a decrease (a local minimum or a numerical limit)"
            }
            Stop::Interrupted => "interrupted by the caller; the best model so far is returned",
            Stop::NothingFree => "nothing to fit: every parameter is fixed",
        }
    }
}

/// The outcome of a fit.
#[derive(Debug, Clone)]
pub struct Fit {
    /// Final parameters (the best accepted point).
    pub theta: Vec<f64>,
    /// V_NLS at `theta`.
    pub vnls: f64,
    /// Objective at `theta`.
    pub objective: f64,
    /// One row per computed step.
    pub history: Vec<Iteration>,
    /// Why the fit stopped.
    pub stop: Stop,
    /// Final reweighting weights `phi` per group (l2,1 only; empty for LM).
    pub weights: Vec<f64>,
    /// Number of outer (reweighting) iterations (l2,1 only).
    pub outer_iterations: usize,
    /// Total wall time in seconds.
    pub total_seconds: f64,
}

impl Fit {
    /// Mean seconds per step of the given kind (NaN when there is none).
    pub fn mean_seconds(&self, kind: StepKind) -> f64 {
        let times: Vec<f64> = self
            .history
            .iter()
            .filter(|it| it.kind == kind)
            .map(|it| it.seconds)
            .collect();
        if times.is_empty() {
            f64::NAN
        } else {
            times.iter().sum::<f64>() / times.len() as f64
        }
    }

    /// Number of rejected steps.
    pub fn rejected(&self) -> usize {
        self.history.iter().filter(|it| !it.accepted).count()
    }
}

/// Follows a fit: sees every iteration and may stop the run.
pub trait Monitor {
    /// Called after every iteration; return `false` to stop the fit.
    fn iteration(&mut self, it: &Iteration) -> bool;
}

/// A monitor that never stops anything.
#[derive(Debug, Default, Clone, Copy)]
pub struct Silent;

impl Monitor for Silent {
    fn iteration(&mut self, _it: &Iteration) -> bool {
        true
    }
}

/// Nielsen's damping update from the gain ratio (Nielsen 1999; Madsen,
/// Nielsen and Tingleff 2004): on a good step the damping shrinks smoothly
/// with the gain ratio, on a bad one it grows by a doubling factor.
#[derive(Debug, Clone, Copy)]
pub struct Damping {
    /// Current `mu = lambda^2`, multiplying diag(J^T J).
    pub mu: f64,
    nu: f64,
}

/// Largest damping tried before giving up.
pub const MAX_DAMPING: f64 = 1e16;

impl Damping {
    /// Start from `lambda`.
    pub fn new(lambda: f64) -> Self {
        Damping {
            mu: lambda * lambda,
            nu: 2.0,
        }
    }

    /// `lambda = sqrt(mu)`.
    pub fn lambda(&self) -> f64 {
        self.mu.sqrt()
    }

    /// Update after a step with gain ratio `rho` (accepted when `rho > 0`).
    pub fn update(&mut self, rho: f64) {
        if rho > 0.0 && rho.is_finite() {
            let f = 1.0 - (2.0 * rho - 1.0).powi(3);
            self.mu *= f.max(1.0 / 3.0);
            self.mu = self.mu.max(1e-12);
            self.nu = 2.0;
        } else {
            self.mu *= self.nu;
            self.nu *= 2.0;
        }
    }

    /// Whether the damping has grown past any use.
    pub fn exhausted(&self) -> bool {
        self.mu.is_nan() || self.mu >= MAX_DAMPING
    }
}

/// Check that V_NLS at the start of a fit is finite: a fit from a point
/// where it is not cannot decrease it, and would return it.
pub(crate) fn check_start(vnls: f64) -> Result<()> {
    if vnls.is_finite() {
        Ok(())
    } else {
        Err(invalid(
            "model",
            format!(
                "V_NLS at the start is not finite ({vnls}): the start model's response \
                 overflows at the data's points; start from another model"
            ),
        ))
    }
}

/// Stopwatch for an iteration.
pub(crate) fn seconds_since(t0: Instant) -> f64 {
    t0.elapsed().as_secs_f64()
}

/// Euclidean norm.
pub(crate) fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

#[cfg(test)]
mod tests {
    use super::{seconds_since, Damping, Fit, Iteration, StepKind, Stop};
    use std::time::{Duration, Instant};

    const ALL: [Stop; 9] = [
        Stop::StepSize,
        Stop::CostChange,
        Stop::Gradient,
        Stop::Weights,
        Stop::Settled,
        Stop::MaxIterations,
        Stop::Damping,
        Stop::Interrupted,
        Stop::NothingFree,
    ];

    /// A fit stopped by its iteration limit, by damping or by the caller is
    /// not converged (result.converged is what users test); the others are.
    #[test]
    fn converged_only_where_a_criterion_was_met() {
        for stop in ALL {
            let expected = !matches!(
                stop,
                Stop::MaxIterations | Stop::Damping | Stop::Interrupted
            );
            assert_eq!(stop.converged(), expected, "{stop:?}");
        }
    }

    /// Every stop has its own sentence, and a converged one says so first.
    #[test]
    fn messages_are_distinct_and_agree_with_converged() {
        let messages: Vec<&str> = ALL.iter().map(|s| s.message()).collect();
        for (i, (stop, m)) in ALL.iter().zip(&messages).enumerate() {
            assert!(m.len() > 20, "{stop:?}: {m:?}");
            assert!(!messages[..i].contains(m), "{stop:?} repeats {m:?}");
            let says = m.starts_with("converged") || m.starts_with("nothing to fit");
            assert_eq!(says, stop.converged(), "{stop:?}: {m:?}");
        }
    }

    fn step(kind: StepKind, seconds: f64, accepted: bool) -> Iteration {
        Iteration {
            kind,
            outer: 0,
            vnls: 1.0,
            objective: 1.0,
            step_norm: 0.1,
            lambda: 1e-2,
            accepted,
            gain_ratio: 0.5,
            status: "solved".to_string(),
            solver_iterations: 0,
            seconds,
        }
    }

    /// The mean is over the steps of the kind asked for only; none: NaN.
    #[test]
    fn mean_seconds_per_kind_and_rejected_steps() {
        let fit = Fit {
            theta: vec![],
            vnls: 1.0,
            objective: 1.0,
            history: vec![
                step(StepKind::Lm, 1.0, true),
                step(StepKind::Socp, 10.0, false),
                step(StepKind::Lm, 4.0, false),
                step(StepKind::Socp, 20.0, false),
                step(StepKind::Socp, 60.0, true),
            ],
            stop: Stop::StepSize,
            weights: vec![],
            outer_iterations: 1,
            total_seconds: 95.0,
        };
        assert_eq!(fit.mean_seconds(StepKind::Lm), 2.5);
        assert_eq!(fit.mean_seconds(StepKind::Socp), 30.0);
        assert_eq!(fit.rejected(), 3);
        let lm_only = Fit {
            history: fit.history[..1].to_vec(),
            ..fit
        };
        assert!(lm_only.mean_seconds(StepKind::Socp).is_nan());
        assert_eq!(lm_only.rejected(), 0);
    }

    /// Nielsen's rule: after a step with gain ratio rho > 0 the damping is
    /// multiplied by max(1/3, 1 - (2 rho - 1)^3) (floored at 1e-12) and the
    /// growth factor resets to 2; after a rejected step (rho <= 0, or not
    /// finite) it is multiplied by the growth factor, which doubles.
    #[test]
    fn damping_follows_nielsens_rule() {
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-14 * b.abs();
        let mut d = Damping::new(0.1);
        assert!(close(d.mu, 0.01) && close(d.lambda(), 0.1));
        d.update(0.75); // 1 - 0.5^3 = 0.875
        assert!(close(d.mu, 0.00875), "{}", d.mu);
        d.update(1.0); // 1 - 1 = 0: the floor 1/3
        assert!(close(d.mu, 0.00875 / 3.0), "{}", d.mu);
        let before = d.mu;
        for (rho, factor) in [
            (0.0, 2.0),
            (-1.0, 4.0),
            (f64::INFINITY, 8.0),
            (f64::NAN, 16.0),
        ] {
            let mu = d.mu;
            d.update(rho);
            assert_eq!(d.mu, mu * factor, "rho = {rho}");
        }
        assert_eq!(d.mu, before * 1024.0);
        d.update(0.5); // f = 1: the damping stays, the growth factor resets to 2
        assert_eq!(d.mu, before * 1024.0);
        let mu = d.mu;
        d.update(-1.0);
        assert_eq!(d.mu, 2.0 * mu);
        let mut tiny = Damping::new(1e-7);
        tiny.update(1.0);
        assert_eq!(tiny.mu, 1e-12);
        assert!(!tiny.exhausted());
        let mut big = Damping::new(1e8);
        assert!(big.exhausted());
        big.mu = f64::NAN;
        assert!(big.exhausted());
    }

    #[test]
    fn seconds_since_measures_the_time_since() {
        let t0 = Instant::now();
        std::thread::sleep(Duration::from_millis(20));
        let s = seconds_since(t0);
        assert!((0.019..0.9).contains(&s), "{s}");
    }
}
