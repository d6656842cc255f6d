//! The sequential convex step of the l2,1-regularised problem
//! (method.md (27)), built in Clarabel's standard form and solved in Rust.
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

use crate::dense::{cholesky, lower_solve, lower_transpose_solve};
use crate::objective::GaussNewton;
use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettingsBuilder, DefaultSolver, IPSolver, SolverStatus, SupportedConeT,
};
use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, Par};
use std::panic::{catch_unwind, AssertUnwindSafe};

/// One penalised group as the cone step sees it.
#[derive(Debug, Clone)]
pub struct ConeGroup {
    /// Every entry of `theta_g`: its index in theta and, when free, its
    /// position among the free parameters.
    pub entries: Vec<(usize, Option<usize>)>,
    /// Reweighting weight `phi_g`.
    pub phi: f64,
    /// Scale `varphi_g` of (25).
    pub varphi: f64,
}

impl ConeGroup {
    /// `|| theta_g ||` at a parameter vector.
    pub fn norm_at(&self, theta: &[f64]) -> f64 {
        self.entries
            .iter()
            .map(|&(i, _)| theta[i] * theta[i])
            .sum::<f64>()
            .sqrt()
    }

    /// `|| theta_g + d_g ||` for a step over the free parameters.
    pub fn norm_after(&self, theta: &[f64], d: &[f64]) -> f64 {
        self.entries
            .iter()
            .map(|&(i, pos)| {
                let v = theta[i] + pos.map_or(0.0, |p| d[p]);
                v * v
            })
            .sum::<f64>()
            .sqrt()
    }

    /// Whether any entry is free.
    pub fn is_active(&self) -> bool {
        self.entries.iter().any(|e| e.1.is_some())
    }
}

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
}

/// Result of one cone solve.
#[derive(Debug, Clone)]
pub struct ConeStep {
    /// The step over the free parameters, when the solve succeeded.
    pub step: Option<Vec<f64>>,
    /// Clarabel's status (or why no solve took place).
    pub status: String,
    /// Interior-point iterations.
    pub iterations: u32,
    /// Clarabel's objective `1/2 x'Px + q'x` at its solution.
    pub objective: f64,
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

    /// Build the cone program in Clarabel's form and solve it with damping `mu`.
    ///
    /// Free parameters outside every group (the constant parts `X(0)`) enter
    /// only the quadratic; they are eliminated first by a Schur complement,
    /// which shrinks the dense block Clarabel works with, and recovered after.
    pub fn solve(&self, mu: f64, cache: &mut ConeSolver) -> ConeStep {
        let nf = self.gn.dim();
        let active: Vec<&ConeGroup> = self.groups.iter().filter(|g| g.is_active()).collect();
        let ng = active.len();
        let m_res = self.n_residuals;
        // Jacobi scaling: P = S (2/M)(H + mu D) S has a unit diagonal.
        let scale: Vec<f64> = (0..nf)
            .map(|i| 1.0 / (2.0 / m_res * (self.gn.gram[i + i * nf] + mu * self.diag[i])).sqrt())
            .collect();
        if scale.iter().any(|s| !s.is_finite()) {
            return ConeStep::failed("the quadratic has a zero or non-finite diagonal");
        }
        let p_full = |i: usize, j: usize| {
            let h = self.gn.gram[i + j * nf] + if i == j { mu * self.diag[i] } else { 0.0 };
            2.0 / m_res * h * scale[i] * scale[j]
        };
        let q_full = |i: usize| self.gn.gradient[i] / m_res * scale[i];
        // Grouped free parameters (in group order) and the others.
        let grouped: Vec<usize> = active
            .iter()
            .flat_map(|g| g.entries.iter().filter_map(|e| e.1))
            .collect();
        let mut is_grouped = vec![false; nf];
        grouped.iter().for_each(|&p| is_grouped[p] = true);
        let others: Vec<usize> = (0..nf).filter(|&p| !is_grouped[p]).collect();
        let nk = grouped.len();
        let mut p_red = Mat::from_fn(nk, nk, |a, b| p_full(grouped[a], grouped[b]));
        let mut q_red: Vec<f64> = grouped.iter().map(|&p| q_full(p)).collect();
        // Elimination: e_U = -L^-T (v + W e_G) with P_UU = L L^T, W = L^-1 P_UG, v = L^-1 q_U.
        let mut elimination = None;
        if !others.is_empty() {
            let nu = others.len();
            let p_uu = Mat::from_fn(nu, nu, |a, b| p_full(others[a], others[b]));
            let Some(l) = cholesky(p_uu) else {
                return ConeStep::failed("the quadratic is not positive definite");
            };
            let mut w = Mat::from_fn(nu, nk, |a, b| p_full(others[a], grouped[b]));
            let mut v = Mat::from_fn(nu, 1, |a, _| q_full(others[a]));
            lower_solve(&l, w.as_mut());
            lower_solve(&l, v.as_mut());
            matmul(
                p_red.as_mut(),
                Accum::Add,
                w.transpose(),
                &w,
                -1.0,
                Par::Seq,
            );
            let wtv = w.transpose() * &v;
            q_red
                .iter_mut()
                .enumerate()
                .for_each(|(a, q)| *q -= wtv[(a, 0)]);
            elimination = Some((l, w, v));
        }
        // Clarabel's form over x = [e_G; t]: P_red as the upper triangle,
        // then one cone per group, (t_k, varphi (theta_g + d_g)): s = b - A x
        // with A = -1 at t_k (b = 0) and A = -varphi S at each free entry
        // (b = varphi theta).
        let mut p_values = Vec::with_capacity(nk * (nk + 1) / 2);
        for b in 0..nk {
            for a in 0..=b {
                p_values.push(p_red[(a, b)]);
            }
        }
        let mut q = q_red;
        q.extend(active.iter().map(|g| self.gamma * g.phi));
        let mut a_values = Vec::with_capacity(nk + ng);
        let mut a_rows = Vec::with_capacity(nk + ng);
        let mut b = Vec::new();
        let mut cone_dims = Vec::with_capacity(ng);
        let mut t_rows = Vec::with_capacity(ng);
        for g in &active {
            t_rows.push(b.len());
            b.push(0.0);
            for &(i, pos) in &g.entries {
                if let Some(p) = pos {
                    // grouped columns come in this same order
                    a_rows.push(b.len());
                    a_values.push(-g.varphi * scale[p]);
                }
                b.push(g.varphi * self.theta[i]);
            }
            cone_dims.push(1 + g.entries.len());
        }
        a_rows.extend(&t_rows);
        a_values.extend(std::iter::repeat_n(-1.0, ng));
        let program = Program {
            nk,
            ng,
            m: b.len(),
            p_values,
            q,
            a_rows,
            a_values,
            b,
            cone_dims,
        };
        let sol = match cache.run(&program) {
            Ok(sol) => sol,
            Err(why) => return ConeStep::failed(&why),
        };
        let status = format!("{:?}", sol.status);
        let good = matches!(
            sol.status,
            SolverStatus::Solved | SolverStatus::AlmostSolved
        );
        let mut e = vec![0.0; nf];
        for (a, &p) in grouped.iter().enumerate() {
            e[p] = sol.x[a];
        }
        if let Some((l, w, v)) = elimination {
            let e_g = Mat::from_fn(nk, 1, |a, _| sol.x[a]);
            let mut rhs = &v + &w * &e_g;
            lower_transpose_solve(&l, rhs.as_mut());
            for (a, &p) in others.iter().enumerate() {
                e[p] = -rhs[(a, 0)];
            }
        }
        let step: Vec<f64> = e.iter().zip(&scale).map(|(x, s)| x * s).collect();
        ConeStep {
            step: (good && step.iter().all(|v| v.is_finite())).then_some(step),
            status,
            iterations: sol.iterations,
            objective: sol.obj_val,
        }
    }
}

/// The numbers of one cone program in Clarabel's form over `x = [e; t]`.
struct Program {
    nk: usize,
    ng: usize,
    m: usize,
    /// Upper triangle of the dense `nk x nk` block of P, column by column.
    p_values: Vec<f64>,
    q: Vec<f64>,
    /// One entry per column of A: its row and value (first the `nk`
    /// step columns, then the `ng` columns of `t`).
    a_rows: Vec<usize>,
    a_values: Vec<f64>,
    b: Vec<f64>,
    cone_dims: Vec<usize>,
}

impl Program {
    /// What fixes the sparsity pattern: a solver built for one program can
    /// take the numbers of another with the same key.
    fn key(&self) -> (usize, usize, usize, Vec<usize>, Vec<usize>) {
        (
            self.nk,
            self.ng,
            self.m,
            self.a_rows.clone(),
            self.cone_dims.clone(),
        )
    }

    fn matrices(&self) -> (CscMatrix<f64>, CscMatrix<f64>) {
        let n = self.nk + self.ng;
        let mut colptr = Vec::with_capacity(n + 1);
        let mut rowval = Vec::with_capacity(self.p_values.len());
        colptr.push(0);
        for b in 0..self.nk {
            rowval.extend(0..=b);
            colptr.push(rowval.len());
        }
        colptr.extend(std::iter::repeat_n(rowval.len(), self.ng));
        let p = CscMatrix::new(n, n, colptr, rowval, self.p_values.clone());
        let a = CscMatrix::new(
            self.m,
            n,
            (0..=n).collect(),
            self.a_rows.clone(),
            self.a_values.clone(),
        );
        (p, a)
    }
}

type Key = (usize, usize, usize, Vec<usize>, Vec<usize>);

/// What a cone step keeps of Clarabel's solution.
struct Solved {
    x: Vec<f64>,
    status: SolverStatus,
    iterations: u32,
    obj_val: f64,
}

impl From<&clarabel::solver::DefaultSolution<f64>> for Solved {
    fn from(s: &clarabel::solver::DefaultSolution<f64>) -> Self {
        Solved {
            x: s.x.clone(),
            status: s.status,
            iterations: s.iterations,
            obj_val: s.obj_val,
        }
    }
}

/// A Clarabel solver kept between cone steps of one fit. The steps of a
/// fit share their sparsity pattern, so the solver is built once (ordering,
/// symbolic factorisation, equilibration) and later steps only overwrite
/// its numbers. Every solve still starts cold.
pub struct ConeSolver {
    tol: f64,
    cached: Option<(Key, DefaultSolver<f64>)>,
}

impl Default for ConeSolver {
    fn default() -> Self {
        ConeSolver::new(DEFAULT_CONE_TOL)
    }
}

/// Clarabel's default accuracy: enough for a step that is accepted or not
/// on the true objective.
pub const DEFAULT_CONE_TOL: f64 = 1e-8;

impl std::fmt::Debug for ConeSolver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ConeSolver")
            .field("cached", &self.cached.is_some())
            .finish()
    }
}

impl ConeSolver {
    /// A solver whose cone programs are solved to `tol` (gap and
    /// feasibility); below the default, Clarabel's iterative refinement is
    /// switched on as well.
    pub fn new(tol: f64) -> Self {
        ConeSolver { tol, cached: None }
    }

    fn run(&mut self, prog: &Program) -> Result<Solved, String> {
        let key = prog.key();
        let reuse = matches!(&self.cached, Some((k, _)) if *k == key);
        let outcome = catch_unwind(AssertUnwindSafe(|| -> Result<_, String> {
            if reuse {
                if let Some((_, solver)) = self.cached.as_mut() {
                    solver
                        .update_data(&prog.p_values, &prog.q, &prog.a_values, &prog.b)
                        .map_err(|e| format!("data update failed: {e}"))?;
                    solver.solve();
                    return Ok(Solved::from(&solver.solution));
                }
            }
            let (p, a) = prog.matrices();
            let cones: Vec<SupportedConeT<f64>> = prog
                .cone_dims
                .iter()
                .map(|&d| SupportedConeT::SecondOrderConeT(d))
                .collect();
            let settings = DefaultSettingsBuilder::default()
                .verbose(false)
                .max_iter(200)
                .max_threads(1)
                .tol_gap_abs(self.tol)
                .tol_gap_rel(self.tol)
                .tol_feas(self.tol)
                .iterative_refinement_enable(self.tol < DEFAULT_CONE_TOL)
                .presolve_enable(false)
                .build()
                .map_err(|e| format!("settings: {e}"))?;
            let mut solver = DefaultSolver::new(&p, &prog.q, &a, &prog.b, &cones, settings)
                .map_err(|e| format!("setup failed: {e}"))?;
            solver.solve();
            let sol = Solved::from(&solver.solution);
            self.cached = Some((key, solver));
            Ok(sol)
        }));
        match outcome {
            Ok(r) => r,
            Err(_) => {
                self.cached = None;
                Err("the cone solver panicked".to_string())
            }
        }
    }
}

impl ConeStep {
    fn failed(why: &str) -> Self {
        ConeStep {
            step: None,
            status: why.to_string(),
            iterations: 0,
            objective: f64::NAN,
        }
    }
}
