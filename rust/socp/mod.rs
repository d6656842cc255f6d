//! The sequential convex step of the l2,1-regularised problem
//! (method.md (27)): solved by Newton's method where every group in it
//! stays away from zero, else built in Clarabel's standard form and solved
//! by its interior-point method, in Rust.
//!
//! Variables `x = [d; t]`: the step over the free parameters and one
//! auxiliary `t_g` per penalised group. With `M` the number of complex
//! residuals (lpvid's normalisation of gamma):
//!
//! ```text
//! minimise  (g/M)^T d + 1/2 d^T (2/M)(J^T J + mu diag J^T J) d + gamma sum_g phi_g t_g
//! s.t.      varphi_g || theta_g + d_g ||_2 <= t_g        (one second-order cone per group)
//! ```
//!
//! The step is solved in Jacobi-scaled variables `d = S e`, `S = diag(P)^-1/2`,
//! so that the quadratic has a unit diagonal whatever the parameter scales.
//!
//! **Active set.** A group at zero is optimal when the gradient of the
//! quadratic model on its free entries is no longer than
//! `gamma phi_g varphi_g` (the subgradient condition). Groups predicted to
//! end at zero are fixed there (`d_g = -theta_g`) and leave the cone
//! program: the groups at zero already, and those whose gradient stays
//! well inside the bound. After the solve the condition is checked for each
//! of them, and any that fails it is put back and the program solved again.
//! The answer is the exact solution of (27), from a smaller program: on a
//! regularisation path most groups are at zero, and when all are, no cone
//! solve is needed at all. Groups that the solver leaves at a negligible
//! size are set exactly to zero, so that the next step can fix them.
//!
//! **Newton first.** With the groups at zero left out, the program is
//! usually smooth: Newton's method (`newton.rs`) minimises it in about three
//! Cholesky factorisations where Clarabel takes about ten, and to machine
//! precision. A group it finds heading for zero it holds there, and lets go
//! when zero is not that group's minimum (`newton.rs`). When the check
//! puts back groups fixed at zero, Newton's method goes on from the
//! refuted round's step; Clarabel solves the program when it gives up.
//!
//! A group at zero stays out even when its gradient is at or over its
//! bound at the current point: the other groups' moves usually bring it
//! back inside (measured on the n = 16 2x2 path: with such groups in the
//! program, 1088 variables per solve where the answer moved 576, and a
//! cone step took 3.5 times as long).

mod factored;
mod group;
mod newton;
mod packed;
mod pinned;
mod program;
mod round;
mod warm;

pub use group::ConeGroup;
pub use pinned::{Pinned, PinnedBasis};
pub use program::{ConeSolver, DEFAULT_CONE_TOL};
pub use warm::WarmSteps;

use crate::error::Result;
use crate::eval::objective::GaussNewton;
use round::Method;

/// A group whose relative magnitude `varphi ||theta_g + d_g||` ends below
/// this after a cone solve is set exactly to zero (the interior-point
/// solution only approaches the cone's tip).
pub const SNAP: f64 = 1e-9;

/// Most rounds of the active-set check per step.
const MAX_ROUNDS: usize = 8;

/// The data of one cone step.
#[derive(Debug, Clone, Copy)]
pub struct ConeProblem<'a> {
    /// Gradient and Gauss-Newton matrix at `theta` (free parameters).
    pub gn: &'a GaussNewton,
    /// Marquardt diagonal (floored diag J^T J).
    pub diag: &'a [f64],
    /// Current parameters (all of theta).
    pub theta: &'a [f64],
    /// Penalised groups.
    pub groups: &'a [ConeGroup],
    /// Regularisation weight (lpvid's normalised gamma).
    pub gamma: f64,
    /// Number of complex residuals `M`.
    pub n_residuals: f64,
    /// Directions the step is kept off, if any.
    pub pinned: Option<&'a PinnedBasis>,
    /// Newton's method first (see the module notes); false: Clarabel alone.
    pub newton: bool,
}

/// Result of one cone solve.
#[derive(Debug, Clone)]
pub struct ConeStep {
    /// The step over the free parameters, when the solve succeeded.
    pub step: Option<Vec<f64>>,
    /// Clarabel's status (or why no solve took place).
    pub status: String,
    /// Interior-point iterations, summed over the rounds.
    pub iterations: u32,
    /// Groups fixed at zero in the final program.
    pub zeroed: usize,
    /// Cone programs solved (0 when every group was at zero).
    pub solves: usize,
}

impl ConeProblem<'_> {
    /// The regularisation term `gamma sum_g phi_g varphi_g ||theta_g + d_g||`
    /// (with `d = None` at the current point).
    pub fn penalty(&self, d: Option<&[f64]>) -> f64 {
        self.gamma
            * self
                .groups
                .iter()
                .map(|g| {
                    let n = match d {
                        Some(d) => g.norm_after(self.theta, d),
                        None => g.norm_at(self.theta),
                    };
                    g.phi * g.varphi * n
                })
                .sum::<f64>()
    }

    /// `P = (2/M)(J^T J + mu D)` times `d`, plus `g/M` (and the pinned
    /// curvature times `d`, when set): the gradient of the quadratic model at
    /// the step `d` (free parameters, unscaled).
    pub fn model_gradient(&self, mu: f64, d: &[f64]) -> Vec<f64> {
        let nf = self.gn.dim();
        let m = self.n_residuals;
        let mut out: Vec<f64> = self.gn.gradient.iter().map(|g| g / m).collect();
        for (j, &dj) in d.iter().enumerate() {
            if dj == 0.0 {
                continue;
            }
            let col = &self.gn.gram[j * nf..(j + 1) * nf];
            let c = 2.0 / m * dj;
            out.iter_mut().zip(col).for_each(|(o, h)| *o += c * h);
            out[j] += c * mu * self.diag[j];
        }
        if let Some(p) = self.pinned {
            p.add_gradient(d, &mut out);
        }
        out
    }

    /// Jacobi scaling of the step (see [`jacobi_scale`]).
    fn jacobi_scale(&self, mu: f64) -> Vec<f64> {
        jacobi_scale(self.gn, self.diag, mu, self.n_residuals)
    }

    /// The largest gradient a group at zero may have: `gamma phi varphi`.
    fn bound(&self, g: &ConeGroup) -> f64 {
        self.gamma * g.phi * g.varphi
    }

    /// Solve the cone program (27) with damping `mu` (see the module notes
    /// on the active set). A failed solve is a step without a solution;
    /// the error is [`crate::Error::OutOfMemory`] only.
    pub fn solve(&self, mu: f64, cache: &mut ConeSolver) -> Result<ConeStep> {
        self.solve_from(mu, cache, None)
    }

    /// As [`ConeProblem::solve`], Newton's method started from the step
    /// `warm` (over the free parameters, unscaled; see [`WarmSteps`])
    /// instead of zero. The minimiser is the same up to the tolerance of
    /// the solve; Clarabel, when it takes over, starts from its own point.
    pub fn solve_from(
        &self,
        mu: f64,
        cache: &mut ConeSolver,
        warm: Option<&[f64]>,
    ) -> Result<ConeStep> {
        let nf = self.gn.dim();
        let active: Vec<usize> = (0..self.groups.len())
            .filter(|&k| self.groups[k].is_active())
            .collect();
        // Prediction: the groups at zero already, and the groups whose
        // gradient at the current point stays well inside their bound,
        // confirmed at the point where all of them are at zero. A group at
        // zero stays out of the program even when its gradient is near or
        // over its bound: the check after the solve puts it back when the
        // solution needs it.
        let scale = self.jacobi_scale(mu);
        if scale.iter().any(|s| !s.is_finite()) {
            return Ok(ConeStep::failed(
                "the quadratic has a zero or non-finite diagonal",
            ));
        }
        let curvature = self
            .pinned
            .map(|p| p.scaled_curvature(&scale))
            .transpose()?;
        let grad0 = self.model_gradient(mu, &vec![0.0; nf]);
        let resting: Vec<bool> = self
            .groups
            .iter()
            .map(|g| g.norm_at(self.theta) == 0.0)
            .collect();
        let mut zero: Vec<bool> = vec![false; self.groups.len()];
        for &k in &active {
            let g = &self.groups[k];
            zero[k] = resting[k]
                || (g.can_vanish(self.theta) && g.free_norm(&grad0) <= 0.9 * self.bound(g));
        }
        let at_zero = self.zero_step(&zero);
        let grad = self.model_gradient(mu, &at_zero);
        for &k in &active {
            let g = &self.groups[k];
            zero[k] = zero[k] && (resting[k] || g.free_norm(&grad) <= self.bound(g));
        }
        let mut iterations = 0;
        let mut solves = 0;
        let mut by_newton = self.newton;
        // Where Newton's method starts (scaled): `warm`, then the last
        // round's step when the check refuted it.
        let mut start: Option<Vec<f64>> =
            warm.map(|d| d.iter().zip(&scale).map(|(d, s)| d / s).collect());
        for round in 0..MAX_ROUNDS {
            let curv = curvature.as_ref();
            let method = if by_newton && round < MAX_ROUNDS - 2 {
                Method::Newton(start.take())
            } else {
                Method::Clarabel
            };
            let round = self.solve_with(mu, &zero, &scale, curv, cache, method)?;
            iterations += round.iterations;
            solves += usize::from(round.solved);
            if round.kink {
                // A group on its way to zero that Newton's method cannot
                // hold there (a fixed entry off zero): Clarabel's program.
                by_newton = false;
                continue;
            }
            let Some(mut d) = round.step else {
                return Ok(ConeStep {
                    step: None,
                    status: round.status,
                    iterations,
                    zeroed: 0,
                    solves,
                });
            };
            let grad = self.model_gradient(mu, &d);
            let mut violated = false;
            for &k in &active {
                let g = &self.groups[k];
                if zero[k] && g.free_norm(&grad) > self.bound(g) * (1.0 + 1e-9) {
                    zero[k] = false;
                    violated = true;
                }
            }
            if violated {
                start = Some(d.iter().zip(&scale).map(|(d, s)| d / s).collect());
                continue;
            }
            // Groups the solver left at a negligible size are at zero.
            for &k in &active {
                let g = &self.groups[k];
                if !zero[k] && g.can_vanish(self.theta) {
                    let size = g.varphi * g.norm_after(self.theta, &d);
                    if size <= SNAP {
                        for (i, p) in g.entries.iter().filter_map(|&(i, p)| p.map(|p| (i, p))) {
                            d[p] = -self.theta[i];
                        }
                        zero[k] = true;
                    }
                }
            }
            return Ok(ConeStep {
                step: Some(d),
                status: round.status,
                iterations,
                zeroed: zero.iter().filter(|&&z| z).count(),
                solves,
            });
        }
        Ok(ConeStep::failed("the active set did not settle"))
    }

    /// The step that brings the groups marked in `zero` to zero and leaves
    /// everything else where it is.
    fn zero_step(&self, zero: &[bool]) -> Vec<f64> {
        let mut d = vec![0.0; self.gn.dim()];
        for (g, _) in self.groups.iter().zip(zero).filter(|(_, &z)| z) {
            for &(i, pos) in &g.entries {
                if let Some(p) = pos {
                    d[p] = -self.theta[i];
                }
            }
        }
        d
    }
}

/// Jacobi scaling of a step with damping `mu`: `P = S (2/M)(J^T J + mu D) S`
/// has a unit diagonal (`M` = `n_residuals`).
pub fn jacobi_scale(gn: &GaussNewton, diag: &[f64], mu: f64, n_residuals: f64) -> Vec<f64> {
    let nf = gn.dim();
    (0..nf)
        .map(|i| 1.0 / (2.0 / n_residuals * (gn.gram[i + i * nf] + mu * diag[i])).sqrt())
        .collect()
}

impl ConeStep {
    fn failed(why: &str) -> Self {
        ConeStep {
            step: None,
            status: why.to_string(),
            iterations: 0,
            zeroed: 0,
            solves: 0,
        }
    }
}

#[cfg(test)]
mod tests;
