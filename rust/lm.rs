//! Levenberg-Marquardt on V_NLS (method.md (11)).
//!
//! The step solves `(J^T J + mu D) d = -J^T r` with Marquardt's scaling
//! `D = diag(J^T J)` (method.md (18) with `mu = lambda^2`), by Cholesky.
//! The damping follows the gain ratio (actual over predicted decrease).

use crate::dense::{cholesky, cholesky_solve};
use crate::error::{invalid, Result};
use crate::fit::{
    check_start, norm, seconds_since, Damping, Fit, Iteration, Monitor, StepKind, Stop,
};
use crate::layout::FreeSet;
use crate::memory::try_mat;
use crate::objective::{GaussNewton, Objective};
use faer::Mat;
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
    // A copy (the factorisation overwrites it), then the diagonal.
    let mut mat = try_mat(
        m,
        m,
        |i, j| gn.gram[i + j * m],
        "the factor of the Levenberg-Marquardt step",
    )?;
    for (i, d) in diag.iter().enumerate() {
        mat[(i, i)] = gn.gram[i + i * m] + mu * d;
    }
    let Some(l) = cholesky(mat)? else {
        return Ok(None);
    };
    let mut d = Mat::from_fn(m, 1, |i, _| -0.5 * gn.gradient[i]);
    cholesky_solve(&l, d.as_mut());
    let d: Vec<f64> = (0..m).map(|i| d[(i, 0)]).collect();
    Ok(d.iter().all(|v| v.is_finite()).then_some(d))
}

/// Predicted decrease of V_NLS for step `d`: `-(g^T d + d^T J^T J d)`.
///
/// Written out rather than with faer's product: faer sums in another order,
/// and the last bits of the gain ratio steer the damping, so the fits'
/// results would move (1e-7 relative in the gantry demo's V_NLS).
pub(crate) fn predicted_decrease(gn: &GaussNewton, d: &[f64]) -> f64 {
    let m = gn.dim();
    let gd: f64 = gn.gradient.iter().zip(d).map(|(g, x)| g * x).sum();
    let mut quad = 0.0;
    for j in 0..m {
        let col = &gn.gram[j * m..(j + 1) * m];
        quad += d[j] * col.iter().zip(d).map(|(h, x)| h * x).sum::<f64>();
    }
    -(gd + quad)
}

/// The evaluation at a trial point: `None` when the model cannot be
/// evaluated there (a rejected step), the error when the machine failed
/// ([`crate::Error::is_fatal`]: out of memory, a bug).
pub(crate) fn trial_point(eval: Result<GaussNewton>) -> Result<Option<GaussNewton>> {
    match eval {
        Ok(gn) => Ok(Some(gn)),
        Err(e) if e.is_fatal() => Err(e),
        Err(_) => Ok(None),
    }
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
    let mut damping = Damping::new(settings.lambda0);
    let mut stop = Stop::MaxIterations;
    for _ in 0..settings.max_iter {
        if gn.gradient.iter().fold(0.0f64, |a, g| a.max(g.abs())) <= settings.gtol {
            stop = Stop::Gradient;
            break;
        }
        let t0 = Instant::now();
        let lambda = damping.lambda();
        let step = lm_step(&gn, &diag, damping.mu)?;
        let (mut accepted, mut rho, mut step_norm) = (false, f64::NAN, f64::NAN);
        let mut status = "not positive definite";
        let mut new_theta = None;
        let mut predicted = f64::NAN;
        if let Some(d) = step {
            status = "solved";
            step_norm = norm(&d);
            let trial = free.add_step(&theta, &d);
            predicted = predicted_decrease(&gn, &d);
            // Most steps are taken (the damping follows the gain ratio), so
            // the Jacobian at the trial point is evaluated with its V_NLS
            // rather than after it. A singular frozen model at the trial
            // point is a rejected step; running out of memory is not.
            if let Some(cand) = trial_point(problem.gauss_newton(&trial, free))? {
                let v = cand.vnls;
                rho = (gn.vnls - v) / predicted;
                if v.is_finite() && v < gn.vnls && predicted > 0.0 {
                    accepted = true;
                    new_theta = Some((trial, cand));
                }
            }
        }
        damping.update(if accepted { rho } else { -1.0 });
        let old_vnls = gn.vnls;
        let theta_norm = norm(&free.gather(&theta));
        if let Some((trial, cand)) = new_theta {
            gn = cand;
            theta = trial;
            diag = marquardt_diagonal(&gn);
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
