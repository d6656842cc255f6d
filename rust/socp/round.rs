//! One round of the cone step's active set: the program (27) with a given
//! set of groups fixed at zero, solved by Newton's method first and by
//! Clarabel when Newton's method gives up (see the module notes of
//! [`super`]).

use super::factored::FactoredHessian;
use super::newton::{newton, Newton};
use super::packed::subtract_gram;
use super::{ConeGroup, ConeProblem, ConeSolver};
use crate::base::dense::{cholesky, lower_solve, lower_transpose_solve, product};
use crate::error::Result;
use crate::memory::try_mat;
use clarabel::solver::SolverStatus;
use faer::linalg::matmul::triangular::BlockStructure;
use faer::Mat;

/// How a round solves its program.
pub(super) enum Method {
    /// Newton's method first, from the scaled step given (the last round's,
    /// which the check refuted) or from zero; Clarabel when it gives up.
    Newton(Option<Vec<f64>>),
    /// Clarabel alone.
    Clarabel,
}

/// One solve of the program with a given set of groups at zero.
pub(super) struct Round {
    /// The step over the free parameters (unscaled), when solved.
    pub(super) step: Option<Vec<f64>>,
    pub(super) status: String,
    /// Newton's and Clarabel's iterations.
    pub(super) iterations: u32,
    /// Whether a program was solved (false with every group at zero).
    pub(super) solved: bool,
    /// Newton's method stopped at a group on its way to zero that it
    /// cannot hold there (no step then).
    pub(super) kink: bool,
}

impl Round {
    pub(super) fn failed(why: &str) -> Self {
        Round {
            step: None,
            status: why.to_string(),
            iterations: 0,
            solved: false,
            kink: false,
        }
    }
}

impl ConeProblem<'_> {
    /// The cone program with the groups marked in `zero` fixed at zero.
    ///
    /// Free parameters outside every remaining group (the constant parts
    /// `X(0)`) enter only the quadratic; they are eliminated first by a
    /// Schur complement, which shrinks the dense block Clarabel works with,
    /// and recovered after. With no group left, that elimination is the
    /// whole solution. By [`Method::Newton`], Newton's method first: when
    /// it finds a group on its way to zero the round ends there (its `kink`).
    pub(super) fn solve_with(
        &self,
        mu: f64,
        zero: &[bool],
        scale: &[f64],
        extra: Option<&Mat<f64>>,
        cache: &mut ConeSolver,
        method: Method,
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
        // Through every point's factor where that is cheaper (no pinned
        // curvature: it is not of the factors' form). That route solves
        // without `P`: the Schur complement of the others is left to the
        // products of the quadratic, and formed only should the step fall
        // back to the cone solver.
        let factors = match (&method, &self.gn.factors) {
            (Method::Newton(_), Some(f)) if ng > 0 && extra.is_none() && f.newton_worth_it(nk) => {
                Some(f)
            }
            _ => None,
        };
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
                // The upper triangle only, half the flops: what Newton's
                // method (its packed P) and Clarabel's program read; the
                // lower triangle keeps P_GG's values.
                if factors.is_none() {
                    subtract_gram(p_red.as_mut(), w.as_ref(), BlockStructure::TriangularUpper);
                }
                let wtv = product(w.transpose(), v.as_ref());
                q_red
                    .iter_mut()
                    .enumerate()
                    .for_each(|(a, q)| *q -= wtv[(a, 0)]);
            }
            elimination = Some((l, w, v));
        }
        let tried = match method {
            Method::Newton(start) if ng > 0 => {
                let groups = self.newton_groups(&open, scale);
                let x0 = start.map(|e| grouped.iter().map(|&p| e[p]).collect());
                let factored = factors.map(|f| {
                    FactoredHessian::new(f, &grouped, &others, scale, self.diag, mu, m_res)
                });
                let schur = factors
                    .and(elimination.as_ref())
                    .map(|(_, w, _)| w.as_ref());
                newton(
                    &mut p_red,
                    &q_red,
                    &groups,
                    cache.tol(),
                    x0,
                    factored.as_ref(),
                    schur.filter(|_| nk > 0),
                )?
            }
            _ => Newton::GaveUp { iterations: 0 },
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
            let why = format!("group {} on its way to zero", open_index[group]);
            return Ok(Round {
                kink: true,
                iterations,
                ..Round::failed(&why)
            });
        } else {
            let spent = match tried {
                Newton::GaveUp { iterations } => iterations,
                _ => 0,
            };
            if let (Some(_), Some((_, w, _))) = (factors, &elimination) {
                subtract_gram(p_red.as_mut(), w.as_ref(), BlockStructure::TriangularUpper);
            }
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
                    kink: false,
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
            let mut rhs = if nk > 0 {
                &v + product(w.as_ref(), e_g.as_ref())
            } else {
                v
            };
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
            kink: false,
        })
    }
}
