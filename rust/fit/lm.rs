//! Levenberg-Marquardt on V_NLS (method.md (11)).
//!
//! The step solves `(J^T J + mu D) d = -J^T r` with Marquardt's scaling
//! `D = diag(J^T J)` (method.md (18) with `mu = lambda^2`), by Cholesky.
//! The damping follows the gain ratio (actual over predicted decrease).

use crate::base::dense::{cholesky_solve, factor_lower};
use crate::base::layout::FreeSet;
use crate::base::spread::{self, worth_spreading};
use crate::error::{invalid, Result};
use crate::eval::objective::{GaussNewton, Objective};
use crate::eval::point_factors::FactoredSystem;
use crate::fit::{
    check_start, norm, seconds_since, Damping, Fit, Iteration, Monitor, StepKind, Stop,
};
use crate::memory::try_par_columns;
use faer::{Mat, MatMut};
use std::time::Instant;

/// Settings of [`levenberg_marquardt`].
#[derive(Debug, Clone, Copy)]
pub struct LmSettings {
    /// Most steps computed (accepted or not).
    pub max_iter: usize,
    /// Stop when `||d|| <= xtol (||theta_free|| + xtol)`.
    pub xtol: f64,
    /// Stop when an accepted step lowers V_NLS by less than `ftol V_NLS`.
    pub ftol: f64,
    /// Stop when `||gradient||_inf <= gtol`.
    pub gtol: f64,
    /// Initial damping `lambda`.
    pub lambda0: f64,
}

impl Default for LmSettings {
    fn default() -> Self {
        LmSettings {
            max_iter: 100,
            xtol: 1e-10,
            ftol: 1e-10,
            gtol: 0.0,
            lambda0: 1e-2,
        }
    }
}

impl LmSettings {
    /// Check every field.
    pub fn validate(&self) -> Result<()> {
        for (name, v) in [
            ("xtol", self.xtol),
            ("ftol", self.ftol),
            ("gtol", self.gtol),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(invalid(
                    name,
                    format!("expected a finite number >= 0, got {v}"),
                ));
            }
        }
        if !(self.lambda0.is_finite() && self.lambda0 > 0.0) {
            return Err(invalid(
                "lambda0",
                format!("expected a finite number > 0, got {}", self.lambda0),
            ));
        }
        Ok(())
    }
}

/// Diagonal of the Marquardt scaling, floored so that parameters without
/// influence still get some damping.
pub fn marquardt_diagonal(gn: &GaussNewton) -> Vec<f64> {
    let m = gn.dim();
    let diag: Vec<f64> = (0..m).map(|i| gn.gram[i + i * m]).collect();
    let floor = 1e-12 * diag.iter().fold(0.0f64, |a, &b| a.max(b)).max(1e-300);
    diag.iter().map(|&d| d.max(floor)).collect()
}

/// Solve `(J^T J + mu D) d = -J^T r`; `None` when the matrix is not
/// numerically positive definite, [`crate::Error::OutOfMemory`] when its
/// factor cannot be had.
pub fn lm_step(gn: &GaussNewton, diag: &[f64], mu: f64) -> Result<Option<Vec<f64>>> {
    let m = gn.dim();
    // A copy (the factorisation overwrites it) with the damped diagonal.
    let mut factor = try_par_columns(
        m,
        m,
        |i, j| {
            let g = gn.gram[i + j * m];
            if i == j {
                g + mu * diag[i]
            } else {
                g
            }
        },
        worth_spreading(m, (m * m) as f64),
        "the factor of the Levenberg-Marquardt step",
    )?;
    let mut l = MatMut::from_column_major_slice_mut(&mut factor, m, m);
    if !factor_lower(l.as_mut())? {
        return Ok(None);
    }
    let mut d = Mat::from_fn(m, 1, |i, _| -0.5 * gn.gradient[i]);
    cholesky_solve(l.as_ref(), d.as_mut());
    let d: Vec<f64> = (0..m).map(|i| d[(i, 0)]).collect();
    Ok(d.iter().all(|v| v.is_finite()).then_some(d))
}

/// The damped system of one point of a fit, whatever the damping: solved
/// through every point's factor when the Gauss-Newton pieces carry them
/// ([`crate::eval::point_factors`]; `K` formed once, a rejected step refactors
/// `K + mu I` alone), else by the dense [`lm_step`].
pub enum LmSystem {
    /// `J^T J + mu D` factored anew for every `mu`.
    Dense,
    /// `K + mu I` of every point's factor.
    Factored(FactoredSystem),
}

impl LmSystem {
    /// The system of `gn` with the Marquardt diagonal `diag`.
    pub fn new(gn: &GaussNewton, diag: &[f64]) -> Result<Self> {
        Ok(match &gn.factors {
            Some(f) => LmSystem::Factored(FactoredSystem::new(f, diag)?),
            None => LmSystem::Dense,
        })
    }

    /// The step of `(J^T J + mu D) d = -J^T r`, as [`lm_step`].
    pub fn step(&self, gn: &GaussNewton, diag: &[f64], mu: f64) -> Result<Option<Vec<f64>>> {
        match (self, &gn.factors) {
            (LmSystem::Factored(system), Some(f)) => system.step(f, diag, mu),
            _ => lm_step(gn, diag, mu),
        }
    }
}

/// Predicted decrease of V_NLS for step `d`: `-(g^T d + d^T J^T J d)`.
///
/// Written out rather than with faer's product: faer sums in another order,
/// and the last bits of the gain ratio steer the damping, so the fits'
/// results would move (1e-7 relative in the gantry demo's V_NLS).
pub(crate) fn predicted_decrease(gn: &GaussNewton, d: &[f64]) -> f64 {
    let m = gn.dim();
    let gd: f64 = gn.gradient.iter().zip(d).map(|(g, x)| g * x).sum();
    // Each column's sum in order (the columns in parallel), then their
    // weighted sum in column order.
    let spread = worth_spreading(m, (2 * m * m) as f64);
    let columns: Vec<&[f64]> = gn.gram.chunks(m.max(1)).collect();
    let columns = spread::map(columns, spread, |col| {
        col.iter().zip(d).map(|(h, x)| h * x).sum::<f64>()
    });
    let quad = columns.iter().zip(d).fold(0.0, |q, (c, x)| q + x * c);
    -(gd + quad)
}

/// An evaluation at a trial point: `None` when the model cannot be
/// evaluated there (a rejected step), the error when the machine failed
/// ([`crate::Error::is_fatal`]: out of memory, a bug).
pub(crate) fn trial_point<T>(eval: Result<T>) -> Result<Option<T>> {
    match eval {
        Ok(value) => Ok(Some(value)),
        Err(e) if e.is_fatal() => Err(e),
        Err(_) => Ok(None),
    }
}

/// What a trial point gave: its cost (`None` when the model cannot be
/// evaluated there) and, when the step is taken, the Gauss-Newton pieces.
pub(crate) struct Trial {
    pub vnls: Option<f64>,
    pub taken: Option<GaussNewton>,
}

/// Evaluate a trial point; `take(V)` says whether a step to a point of
/// cost `V` is taken.
///
/// Most steps are taken (the damping follows the gain ratio), so the
/// Gauss-Newton pieces are computed with the cost rather than after it.
/// A `doubtful` step (a fit's first, or one after a rejection: the
/// damping is still being found, and most such steps are rejected) has
/// its cost computed alone first, a tenth to a fortieth of the pieces'
/// price, and the pieces only when it is taken. Both ways give the same
/// values ([`Objective::cost`] is the `vnls` of
/// [`Objective::gauss_newton`] to the last bit), so the fit takes the same
/// steps either way.
pub(crate) fn evaluate_trial(
    problem: &dyn Objective,
    trial: &[f64],
    free: &FreeSet,
    doubtful: bool,
    take: impl Fn(f64) -> bool,
) -> Result<Trial> {
    if doubtful {
        let Some(vnls) = trial_point(problem.cost(trial))? else {
            return Ok(Trial {
                vnls: None,
                taken: None,
            });
        };
        if !take(vnls) {
            return Ok(Trial {
                vnls: Some(vnls),
                taken: None,
            });
        }
        let gn = trial_point(problem.gauss_newton(trial, free))?;
        return Ok(Trial {
            vnls: gn.as_ref().map(|g| g.vnls),
            taken: gn,
        });
    }
    let gn = trial_point(problem.gauss_newton(trial, free))?;
    Ok(Trial {
        vnls: gn.as_ref().map(|g| g.vnls),
        taken: gn.filter(|g| take(g.vnls)),
    })
}

/// Levenberg-Marquardt from `theta0` over the free parameters.
///
/// Fails ([`crate::Error::InvalidArgument`] named `model`) when V_NLS at
/// `theta0` is not finite.
pub fn levenberg_marquardt(
    problem: &dyn Objective,
    theta0: &[f64],
    free: &FreeSet,
    settings: &LmSettings,
    monitor: &mut dyn Monitor,
) -> Result<Fit> {
    settings.validate()?;
    let start = Instant::now();
    let mut theta = theta0.to_vec();
    let mut gn = problem.gauss_newton(&theta, free)?;
    check_start(gn.vnls)?;
    let mut history = Vec::new();
    let finish = |theta: Vec<f64>, vnls: f64, history: Vec<Iteration>, stop: Stop| Fit {
        theta,
        vnls,
        objective: vnls,
        history,
        stop,
        weights: Vec::new(),
        outer_iterations: 0,
        total_seconds: seconds_since(start),
    };
    if free.is_empty() {
        let v = gn.vnls;
        return Ok(finish(theta, v, history, Stop::NothingFree));
    }
    let mut diag = marquardt_diagonal(&gn);
    let mut system = LmSystem::new(&gn, &diag)?;
    let mut damping = Damping::new(settings.lambda0);
    let mut stop = Stop::MaxIterations;
    let mut doubtful = true;
    for _ in 0..settings.max_iter {
        if gn.gradient.iter().fold(0.0f64, |a, g| a.max(g.abs())) <= settings.gtol {
            stop = Stop::Gradient;
            break;
        }
        let t0 = Instant::now();
        let lambda = damping.lambda();
        let step = system.step(&gn, &diag, damping.mu)?;
        let (mut accepted, mut rho, mut step_norm) = (false, f64::NAN, f64::NAN);
        let mut status = "not positive definite";
        let mut new_theta = None;
        let mut predicted = f64::NAN;
        if let Some(d) = step {
            status = "solved";
            step_norm = norm(&d);
            let trial = free.add_step(&theta, &d);
            predicted = predicted_decrease(&gn, &d);
            // A singular frozen model at the trial point is a rejected
            // step; running out of memory is not.
            let current = gn.vnls;
            let at = evaluate_trial(problem, &trial, free, doubtful, |v| {
                v.is_finite() && v < current && predicted > 0.0
            })?;
            if let Some(v) = at.vnls {
                rho = (current - v) / predicted;
            }
            if let Some(cand) = at.taken {
                accepted = true;
                new_theta = Some((trial, cand));
            }
        }
        damping.update(if accepted { rho } else { -1.0 });
        doubtful = !accepted;
        let old_vnls = gn.vnls;
        let theta_norm = norm(&free.gather(&theta));
        if let Some((trial, cand)) = new_theta {
            gn = cand;
            theta = trial;
            diag = marquardt_diagonal(&gn);
            system = LmSystem::new(&gn, &diag)?;
        }
        let it = Iteration {
            kind: StepKind::Lm,
            outer: 0,
            vnls: gn.vnls,
            objective: gn.vnls,
            step_norm,
            lambda,
            accepted,
            gain_ratio: rho,
            status: status.to_string(),
            solver_iterations: 0,
            seconds: seconds_since(t0),
        };
        history.push(it);
        if !monitor.iteration(history.last().expect("just pushed")) {
            stop = Stop::Interrupted;
            break;
        }
        let small_step = step_norm <= settings.xtol * (theta_norm + settings.xtol);
        if accepted && old_vnls - gn.vnls <= settings.ftol * old_vnls {
            stop = Stop::CostChange;
            break;
        }
        if small_step || (predicted >= 0.0 && predicted <= 0.1 * settings.ftol * old_vnls) {
            // Nothing left to gain from this point: converged, accepted or not.
            stop = if small_step {
                Stop::StepSize
            } else {
                Stop::CostChange
            };
            break;
        }
        if !accepted && damping.exhausted() {
            stop = Stop::Damping;
            break;
        }
    }
    let v = gn.vnls;
    Ok(finish(theta, v, history, stop))
}

#[cfg(test)]
#[path = "lm_tests.rs"]
mod tests;
