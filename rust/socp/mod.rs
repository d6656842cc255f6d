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
//! precision. A group it finds heading for zero is fixed there for the next
//! round; Clarabel solves the program when that is refuted.
//!
//! A group at zero stays out even when its gradient is at or over its
//! bound at the current point: the other groups' moves usually bring it
//! back inside (measured on the n = 16 2x2 path: with such groups in the
//! program, 1088 variables per solve where the answer moved 576, and a
//! cone step took 3.5 times as long).

mod ahead;
mod group;
mod newton;
mod pinned;
mod program;

pub use ahead::Lookahead;
pub use group::ConeGroup;
pub use pinned::{Pinned, PinnedBasis};
pub use program::{ConeSolver, DEFAULT_CONE_TOL};

use crate::dense::{cholesky, lower_solve, lower_transpose_solve, par_for};
use crate::error::Result;
use crate::memory::try_mat;
use crate::objective::GaussNewton;
use clarabel::solver::SolverStatus;
use faer::linalg::matmul::matmul;
use faer::{Accum, Mat};
use newton::{newton, Newton};

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
        // Groups Newton's method stopped at (fixed at zero for the next round).
        let mut kinked = vec![false; self.groups.len()];
        let mut put_back = vec![false; self.groups.len()];
        let mut by_newton = self.newton;
        for round in 0..MAX_ROUNDS {
            let curv = curvature.as_ref();
            let round = self.solve_with(
                mu,
                &zero,
                &scale,
                curv,
                cache,
                by_newton && round < MAX_ROUNDS - 2,
            )?;
            iterations += round.iterations;
            solves += usize::from(round.solved);
            if let Some(k) = round.kink {
                // The check below puts it back if zero is not optimal;
                // then Clarabel solves the program.
                if self.groups[k].can_vanish(self.theta) && !kinked[k] && !put_back[k] {
                    zero[k] = true;
                    kinked[k] = true;
                } else {
                    by_newton = false;
                }
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
                    put_back[k] = true;
                    by_newton &= !kinked[k];
                }
            }
            if violated {
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

    /// The cone program with the groups marked in `zero` fixed at zero.
    ///
    /// Free parameters outside every remaining group (the constant parts
    /// `X(0)`) enter only the quadratic; they are eliminated first by a
    /// Schur complement, which shrinks the dense block Clarabel works with,
    /// and recovered after. With no group left, that elimination is the
    /// whole solution. With `by_newton`, Newton's method first: when it
    /// finds a group on its way to zero the round ends there (its `kink`).
    fn solve_with(
        &self,
        mu: f64,
        zero: &[bool],
        scale: &[f64],
        extra: Option<&Mat<f64>>,
        cache: &mut ConeSolver,
        by_newton: bool,
    ) -> Result<Round> {
        let nf = self.gn.dim();
        let m_res = self.n_residuals;
        let p_full = |i: usize, j: usize| {
            let h = self.gn.gram[i + j * nf] + if i == j { mu * self.diag[i] } else { 0.0 };
            2.0 / m_res * h * scale[i] * scale[j] + extra.map_or(0.0, |e| e[(i, j)])
        };
        // The fixed groups' steps in scaled variables, folded into q.
        let d_zero = self.zero_step(zero);
        let e_zero: Vec<(usize, f64)> = d_zero
            .iter()
            .enumerate()
            .filter(|(_, &d)| d != 0.0)
            .map(|(p, &d)| (p, d / scale[p]))
            .collect();
        let mut in_zero = vec![false; nf];
        let open_index: Vec<usize> = (0..self.groups.len())
            .filter(|&k| {
                let g = &self.groups[k];
                if zero[k] {
                    g.free_positions().for_each(|p| in_zero[p] = true);
                }
                g.is_active() && !zero[k]
            })
            .collect();
        let open: Vec<&ConeGroup> = open_index.iter().map(|&k| &self.groups[k]).collect();
        let q_full = |i: usize| {
            self.gn.gradient[i] / m_res * scale[i]
                + e_zero.iter().map(|&(j, e)| p_full(i, j) * e).sum::<f64>()
        };
        let ng = open.len();
        // Grouped free parameters (in group order) and the others.
        let grouped: Vec<usize> = open.iter().flat_map(|g| g.free_positions()).collect();
        let mut is_grouped = in_zero.clone();
        grouped.iter().for_each(|&p| is_grouped[p] = true);
        let others: Vec<usize> = (0..nf).filter(|&p| !is_grouped[p]).collect();
        let nk = grouped.len();
        let dense = "the dense block of the cone step";
        let mut p_red = try_mat(nk, nk, |a, b| p_full(grouped[a], grouped[b]), dense)?;
        let mut q_red: Vec<f64> = grouped.iter().map(|&p| q_full(p)).collect();
        // Elimination: e_U = -L^-T (v + W e_G) with P_UU = L L^T, W = L^-1 P_UG, v = L^-1 q_U.
        let mut elimination = None;
        if !others.is_empty() {
            let nu = others.len();
            let p_uu = try_mat(nu, nu, |a, b| p_full(others[a], others[b]), dense)?;
            let Some(l) = cholesky(p_uu)? else {
                return Ok(Round::failed("the quadratic is not positive definite"));
            };
            let mut w = try_mat(nu, nk, |a, b| p_full(others[a], grouped[b]), dense)?;
            let mut v = Mat::from_fn(nu, 1, |a, _| q_full(others[a]));
            lower_solve(&l, w.as_mut());
            lower_solve(&l, v.as_mut());
            if nk > 0 {
                matmul(
                    p_red.as_mut(),
                    Accum::Add,
                    w.transpose(),
                    &w,
                    -1.0,
                    par_for(2.0 * (nk * nk * nu) as f64),
                );
                let wtv = w.transpose() * &v;
                q_red
                    .iter_mut()
                    .enumerate()
                    .for_each(|(a, q)| *q -= wtv[(a, 0)]);
            }
            elimination = Some((l, w, v));
        }
        let tried = if ng > 0 && by_newton {
            let groups = self.newton_groups(&open, scale);
            newton(&mut p_red, &q_red, &groups, cache.tol())?
        } else {
            Newton::GaveUp { iterations: 0 }
        };
        let (x_g, status, iterations, solved) = if ng == 0 {
            (
                Vec::new(),
                "Solved (every group at zero)".to_string(),
                0,
                false,
            )
        } else if let Newton::Solved { x, iterations } = tried {
            (x, "Solved (Newton)".to_string(), iterations, true)
        } else if let Newton::Kink { group, iterations } = tried {
            return Ok(Round {
                kink: Some(open_index[group]),
                iterations,
                ..Round::failed("a group on its way to zero")
            });
        } else {
            let spent = match tried {
                Newton::GaveUp { iterations } => iterations,
                _ => 0,
            };
            let program = self.program(&open, scale, &p_red, q_red)?;
            drop(p_red);
            let sol = match cache.run(&program)? {
                Ok(sol) => sol,
                Err(why) => return Ok(Round::failed(&why)),
            };
            let good = matches!(
                sol.status,
                SolverStatus::Solved | SolverStatus::AlmostSolved
            );
            if !good {
                return Ok(Round {
                    step: None,
                    status: format!("{:?}", sol.status),
                    iterations: spent + sol.iterations,
                    solved: true,
                    kink: None,
                });
            }
            (
                sol.x[..nk].to_vec(),
                format!("{:?}", sol.status),
                spent + sol.iterations,
                true,
            )
        };
        let mut e = vec![0.0; nf];
        for (a, &p) in grouped.iter().enumerate() {
            e[p] = x_g[a];
        }
        for &(p, v) in &e_zero {
            e[p] = v;
        }
        if let Some((l, w, v)) = elimination {
            let e_g = Mat::from_fn(nk, 1, |a, _| x_g[a]);
            let mut rhs = if nk > 0 { &v + &w * &e_g } else { v };
            lower_transpose_solve(&l, rhs.as_mut());
            for (a, &p) in others.iter().enumerate() {
                e[p] = -rhs[(a, 0)];
            }
        }
        let step: Vec<f64> = e.iter().zip(scale).map(|(x, s)| x * s).collect();
        let finite = step.iter().all(|v| v.is_finite());
        Ok(Round {
            step: finite.then_some(step),
            status: if finite {
                status
            } else {
                "the step is not finite".to_string()
            },
            iterations,
            solved,
            kink: None,
        })
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

/// One solve of the program with a given set of groups at zero.
struct Round {
    step: Option<Vec<f64>>,
    status: String,
    iterations: u32,
    solved: bool,
    /// The group Newton's method found on its way to zero (no step then).
    kink: Option<usize>,
}

impl Round {
    fn failed(why: &str) -> Self {
        Round {
            step: None,
            status: why.to_string(),
            iterations: 0,
            solved: false,
            kink: None,
        }
    }
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
