//! Reweighted l2,1 regularisation (Algorithm 1 of the paper, method.md
//! section 4) and the warm-started gamma path.
//!
//! The regularised objective uses `V_NLS / M`, `M` the number of complex
//! residuals, so that `gamma` means the same on every data set: with the
//! relative weights (23), every group in use costs about `gamma`, and a group
//! is kept when it lowers `V_NLS` by more than about `gamma M`.

use crate::base::layout::{FreeSet, Shape};
use crate::error::{invalid, Result};
use crate::eval::objective::Objective;
use crate::fit::lm::{
    evaluate_trial, levenberg_marquardt, marquardt_diagonal, predicted_decrease, LmSettings,
};
use crate::fit::{
    check_start, norm, seconds_since, Damping, Fit, Iteration, Monitor, StepKind, Stop,
};
use crate::socp::{jacobi_scale, ConeGroup, ConeProblem, ConeSolver, Pinned, WarmSteps};
use std::time::Instant;

mod settings;
#[cfg(test)]
mod tests;

pub use settings::{L21Settings, Weighting};

/// A penalised group with what its weights need.
#[derive(Debug, Clone)]
struct GroupSpec {
    entries: Vec<(usize, Option<usize>)>,
    constant: std::ops::Range<usize>,
    constant_fixed: bool,
    sup: f64,
}

fn group_specs(shape: &Shape, free: &FreeSet, sup_norms: &[f64]) -> Result<Vec<GroupSpec>> {
    if sup_norms.len() != shape.nb {
        return Err(invalid(
            "sup_norms",
            format!(
                "expected {} values (one per basis function), got {}",
                shape.nb,
                sup_norms.len()
            ),
        ));
    }
    if sup_norms.iter().any(|s| !(s.is_finite() && *s >= 0.0)) {
        return Err(invalid("sup_norms", "must be finite and >= 0"));
    }
    Ok(shape
        .groups()
        .into_iter()
        .map(|g| {
            let constant = shape.block(g.matrix, 0);
            GroupSpec {
                entries: g.range.clone().map(|i| (i, free.position(i))).collect(),
                constant_fixed: constant.clone().all(|i| free.position(i).is_none()),
                constant,
                sup: sup_norms[g.basis - 1],
            }
        })
        .collect())
}

/// The penalised groups of a problem with their weights `phi` and scales
/// `varphi` at `theta` (what one cone step needs).
pub fn cone_groups(
    shape: &Shape,
    free: &FreeSet,
    sup_norms: &[f64],
    theta: &[f64],
    settings: &L21Settings,
) -> Result<Vec<ConeGroup>> {
    Ok(weigh(
        &group_specs(shape, free, sup_norms)?,
        theta,
        settings,
    ))
}

/// Weights `phi` and scales `varphi` of every group at `theta`.
fn weigh(specs: &[GroupSpec], theta: &[f64], s: &L21Settings) -> Vec<ConeGroup> {
    specs
        .iter()
        .map(|g| {
            let norm_i = g
                .entries
                .iter()
                .map(|&(i, _)| theta[i] * theta[i])
                .sum::<f64>()
                .sqrt();
            let norm_0 = norm(&theta[g.constant.clone()]);
            let relative = s.weighting == Weighting::Relative && norm_0 > 0.0 && !g.constant_fixed;
            let (phi, varphi) = if relative {
                (1.0 / (norm_i * g.sup / norm_0 + s.eps), g.sup / norm_0)
            } else if s.weighting == Weighting::Plain {
                (1.0 / (norm_i + s.eps), 1.0)
            } else {
                (1.0 / (norm_i * g.sup + s.eps), g.sup)
            };
            ConeGroup {
                entries: g.entries.clone(),
                phi,
                varphi,
            }
        })
        .collect()
}

/// Whether the groups in use are the same as at the last reweighting and
/// none of them is on its way out. A group between the threshold and a tenth
/// of `eps` that shrank by half or more over the last reweighting is still
/// dying (its weight is near `1/eps` and no longer moves); one that holds
/// its size there is in use.
fn settled(magnitudes: &[f64], previous: &[f64], s: &L21Settings) -> bool {
    magnitudes.iter().zip(previous).all(|(&m, &p)| {
        let in_use = m > s.threshold;
        let dying = in_use && m < 0.1 * s.eps && m < 0.5 * p;
        in_use == (p > s.threshold) && !dying
    })
}

/// The fit has also settled when the groups in use are the same as at the
/// last reweighting and the model's weighted response at the data moved by
/// at most this much over it, in `sum |dG / sigma|^2`: less than the noise
/// of a single residual, whatever V_NLS did (the other test, V_NLS changing
/// by at most `dvnls_min`). What still moves then is a slide along state
/// transformations that inflate `||theta_X(0)||` and so lower the relative
/// magnitudes (25) of the kept groups, which the data do not see: on a
/// one-group system at 6 points, `||A(0)||` 599 -> 1051 over five
/// reweightings, V_NLS / M at 0.958 throughout and the response moving by
/// 0.2-0.4 per reweighting, each V_NLS change near `dvnls_min` (a knife
/// edge between stopping and sliding on to the iteration limit).
const SETTLED_RESPONSE: f64 = 1.0;

/// Algorithm 1: reweighted l2,1-regularised fit from `theta0`.
///
/// `sup_norms[i-1]` is `||psi_i||_inf` over the scheduling range. With
/// `gamma = 0` the problem is plain nonlinear least squares and the fit is
/// [`levenberg_marquardt`] with its default settings (the cone steps would
/// reproduce its steps at a higher price). Fails when V_NLS at `theta0` is
/// not finite, as [`levenberg_marquardt`] does.
pub fn fit_l21(
    problem: &dyn Objective,
    theta0: &[f64],
    free: &FreeSet,
    sup_norms: &[f64],
    settings: &L21Settings,
    pinned: Option<&Pinned>,
    monitor: &mut dyn Monitor,
) -> Result<Fit> {
    settings.validate()?;
    problem.shape().check_theta(theta0)?;
    let specs = group_specs(problem.shape(), free, sup_norms)?;
    if settings.gamma == 0.0 {
        let lm = LmSettings {
            lambda0: settings.lambda0,
            ..LmSettings::default()
        };
        let mut fit = levenberg_marquardt(problem, theta0, free, &lm, monitor)?;
        fit.objective = fit.vnls / problem.n_residuals() as f64;
        fit.weights = weigh(&specs, &fit.theta, settings)
            .iter()
            .map(|g| g.phi)
            .collect();
        return Ok(fit);
    }
    let start = Instant::now();
    let m_res = problem.n_residuals() as f64;
    let mut theta = theta0.to_vec();
    let mut gn = problem.gauss_newton(&theta, free)?;
    check_start(gn.vnls)?;
    let mut diag = marquardt_diagonal(&gn);
    let mut history = Vec::new();
    let mut prev_phi: Option<Vec<f64>> = None;
    let mut prev_state: Option<(Vec<f64>, f64, Vec<f64>)> = None;
    let mut stop = Stop::MaxIterations;
    let mut groups;
    let mut outer = 0;
    let mut solver = WarmSteps::new(settings.cone_tol);
    // The kept-off directions, made orthonormal once in the metric of the
    // first step.
    let mu0 = Damping::new(settings.lambda0).mu;
    let pinned = match pinned {
        Some(p) => p.basis(&jacobi_scale(&gn, &diag, mu0, m_res))?,
        None => None,
    };
    // The stopping tests run at the top of every reweighting and once more
    // after the last one the limit allows: a fit whose last reweighting
    // settled it has converged, not run out of iterations.
    'outer: loop {
        groups = weigh(&specs, &theta, settings);
        solver.forget();
        let phi: Vec<f64> = groups.iter().map(|g| g.phi).collect();
        if let Some(prev) = &prev_phi {
            let change = phi
                .iter()
                .zip(prev)
                .map(|(a, b)| (a - b).abs() / b.abs())
                .fold(0.0f64, f64::max);
            if change <= settings.dphi_min {
                stop = Stop::Weights;
                break;
            }
        }
        // Once the groups in use and the fit have settled, further outer
        // iterations only slide along similarity transforms that trade the
        // size of the penalised groups for that of the constant parts.
        let magnitudes: Vec<f64> = groups.iter().map(|g| g.magnitude(&theta)).collect();
        let response = problem.response(&theta)?;
        if let Some((prev_mag, prev_v, prev_response)) = &prev_state {
            let moved: f64 = response
                .iter()
                .zip(prev_response)
                .map(|(a, b)| (a - b) * (a - b))
                .sum();
            let quiet = (prev_v - gn.vnls).abs() <= settings.dvnls_min * prev_v
                || moved <= SETTLED_RESPONSE;
            if settled(&magnitudes, prev_mag, settings) && quiet {
                stop = Stop::Settled;
                break;
            }
        }
        if outer == settings.max_outer {
            break;
        }
        prev_state = Some((magnitudes, gn.vnls, response));
        outer += 1;
        // Every reweighting starts from the initial damping (carrying it
        // over was measured: fewer rejected steps, but other models on the
        // gantry path, one more group at gamma = 0.03).
        let mut damping = Damping::new(settings.lambda0);
        // Doubtful: a reweighting's first step, or one after a rejection
        // (judged by V_NLS alone, see `evaluate_trial`).
        let mut doubtful = true;
        if free.is_empty() {
            stop = Stop::NothingFree;
            break;
        }
        for _ in 0..settings.max_inner {
            let t0 = Instant::now();
            let cone = ConeProblem {
                gn: &gn,
                diag: &diag,
                theta: &theta,
                groups: &groups,
                gamma: settings.gamma,
                n_residuals: m_res,
                pinned: pinned.as_ref(),
                newton: settings.newton,
            };
            let objective = gn.vnls / m_res + cone.penalty(None);
            let lambda = damping.lambda();
            let solved = solver.solve(&cone, damping.mu)?;
            let (mut accepted, mut rho, mut step_norm) = (false, f64::NAN, f64::NAN);
            let mut new_theta = None;
            let mut new_objective = objective;
            if let Some(d) = &solved.step {
                step_norm = norm(d);
                let trial = free.add_step(&theta, d);
                let predicted = objective
                    - (gn.vnls - predicted_decrease(&gn, d)) / m_res
                    - cone.penalty(Some(d));
                // As Levenberg-Marquardt evaluates its trial points.
                let penalty = cone.penalty(Some(d));
                let at = evaluate_trial(problem, &trial, free, doubtful, |v| {
                    let f_trial = v / m_res + penalty;
                    f_trial.is_finite() && f_trial < objective && predicted > 0.0
                })?;
                if let Some(v) = at.vnls {
                    rho = (objective - (v / m_res + penalty)) / predicted;
                }
                if let Some(cand) = at.taken {
                    accepted = true;
                    new_objective = cand.vnls / m_res + penalty;
                    new_theta = Some((trial, cand));
                }
            }
            damping.update(if accepted { rho } else { -1.0 });
            doubtful = !accepted;
            let theta_norm = norm(&free.gather(&theta));
            if let Some((trial, cand)) = new_theta {
                solver.forget();
                gn = cand;
                diag = marquardt_diagonal(&gn);
                theta = trial;
            }
            history.push(Iteration {
                kind: StepKind::Socp,
                outer,
                vnls: gn.vnls,
                objective: new_objective,
                step_norm,
                lambda,
                accepted,
                gain_ratio: rho,
                status: solved.status.clone(),
                solver_iterations: solved.iterations,
                seconds: seconds_since(t0),
            });
            if !monitor.iteration(history.last().expect("just pushed")) {
                stop = Stop::Interrupted;
                break 'outer;
            }
            let small = step_norm <= settings.dtheta_min * (theta_norm + settings.dtheta_min);
            if small || (accepted && objective - new_objective <= settings.ftol * objective.abs()) {
                break;
            }

            if !accepted && damping.exhausted() {
                // No decrease at any damping: this point is as good as it gets
                // for these weights.
                break;
            }
        }
        prev_phi = Some(phi);
    }
    let objective = gn.vnls / m_res
        + settings.gamma
            * groups
                .iter()
                .map(|g| g.phi * g.varphi * g.norm_at(&theta))
                .sum::<f64>();
    Ok(Fit {
        weights: groups.iter().map(|g| g.phi).collect(),
        vnls: gn.vnls,
        objective,
        theta,
        history,
        stop,
        outer_iterations: outer,
        total_seconds: seconds_since(start),
    })
}

/// What [`single_cone_step`] reports.
#[derive(Debug, Clone)]
pub struct ConeStepReport {
    /// The step over the free parameters, when the solve succeeded.
    pub step: Option<Vec<f64>>,
    /// The subproblem's objective at the step,
    /// `(g/M)^T d + 1/2 d^T (2/M)(J^T J + mu diag J^T J) d + gamma sum phi varphi ||theta_g + d_g||`.
    pub objective: f64,
    /// The cone solver's status.
    pub status: String,
    /// The groups with their weights.
    pub groups: Vec<ConeGroup>,
}

/// One cone step (27) at `theta` with damping `mu`, for inspection and tests.
pub fn single_cone_step(
    problem: &dyn Objective,
    theta: &[f64],
    free: &FreeSet,
    sup_norms: &[f64],
    settings: &L21Settings,
    mu: f64,
) -> Result<ConeStepReport> {
    settings.validate()?;
    problem.shape().check_theta(theta)?;
    if !(mu.is_finite() && mu >= 0.0) {
        return Err(invalid(
            "mu",
            format!("expected a finite number >= 0, got {mu}"),
        ));
    }
    let gn = problem.gauss_newton(theta, free)?;
    let diag = marquardt_diagonal(&gn);
    let groups = cone_groups(problem.shape(), free, sup_norms, theta, settings)?;
    let m_res = problem.n_residuals() as f64;
    let cone = ConeProblem {
        gn: &gn,
        diag: &diag,
        theta,
        groups: &groups,
        gamma: settings.gamma,
        n_residuals: m_res,
        pinned: None,
        newton: settings.newton,
    };
    let solved = cone.solve(mu, &mut ConeSolver::new(settings.cone_tol))?;
    // g^T d + d^T (J^T J + mu D) d = -predicted decrease + mu d^T D d.
    let objective = solved.step.as_ref().map_or(f64::NAN, |d| {
        let damping: f64 = diag.iter().zip(d).map(|(w, x)| mu * w * x * x).sum();
        (damping - predicted_decrease(&gn, d)) / m_res + cone.penalty(Some(d))
    });
    Ok(ConeStepReport {
        step: solved.step,
        objective,
        status: solved.status,
        groups,
    })
}

/// A warm-started sweep over `gammas`, from the largest to the smallest
/// (section 5.3 of the paper): each fit starts from the previous result.
/// Returns the fits in that order.
pub fn l21_path(
    problem: &dyn Objective,
    theta0: &[f64],
    free: &FreeSet,
    sup_norms: &[f64],
    gammas: &[f64],
    settings: &L21Settings,
    monitor: &mut dyn Monitor,
) -> Result<Vec<(f64, Fit)>> {
    if gammas.is_empty() {
        return Err(invalid("gammas", "needs at least one value"));
    }
    if gammas.iter().any(|g| !(g.is_finite() && *g >= 0.0)) {
        return Err(invalid("gammas", "every gamma must be finite and >= 0"));
    }
    let mut order = gammas.to_vec();
    order.sort_by(|a, b| b.total_cmp(a));
    let mut theta = theta0.to_vec();
    let mut out = Vec::with_capacity(order.len());
    for gamma in order {
        let s = L21Settings { gamma, ..*settings };
        let fit = fit_l21(problem, &theta, free, sup_norms, &s, None, monitor)?;
        theta = fit.theta.clone();
        let stop = fit.stop;
        out.push((gamma, fit));
        if stop == Stop::Interrupted {
            break;
        }
    }
    Ok(out)
}
