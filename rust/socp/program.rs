//! The cone program of one step in Clarabel's standard form, and the
//! Clarabel solver kept between the steps of a fit.

use super::{ConeGroup, ConeProblem};
use crate::error::Result as CoreResult;
use crate::fit::estimate;
use crate::memory::{guarded, probe, try_grow};
use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettingsBuilder, DefaultSolver, IPSolver, SolverStatus, SupportedConeT,
};
use faer::Mat;
use std::panic::{catch_unwind, AssertUnwindSafe};

/// A sparse matrix by columns (Clarabel's CSC layout).
#[derive(Debug, Clone, Default, PartialEq)]
pub(super) struct Csc {
    pub(super) colptr: Vec<usize>,
    pub(super) rowval: Vec<usize>,
    pub(super) values: Vec<f64>,
}

impl Csc {
    /// Start a matrix; add columns with [`Csc::push`] in order.
    pub(super) fn new() -> Self {
        Csc {
            colptr: vec![0],
            ..Csc::default()
        }
    }

    /// Start a matrix with room for `nnz` entries, or
    /// [`crate::Error::OutOfMemory`] naming `what`.
    pub(super) fn with_capacity(nnz: usize, what: &'static str) -> CoreResult<Self> {
        let mut m = Csc::new();
        try_grow(&mut m.rowval, nnz, what)?;
        try_grow(&mut m.values, nnz, what)?;
        Ok(m)
    }

    /// Append one column from `(row, value)` pairs (rows ascending).
    pub(super) fn push(&mut self, entries: impl IntoIterator<Item = (usize, f64)>) {
        for (r, v) in entries {
            self.rowval.push(r);
            self.values.push(v);
        }
        self.colptr.push(self.rowval.len());
    }

    fn to_clarabel(&self, m: usize) -> CscMatrix<f64> {
        CscMatrix::new(
            m,
            self.colptr.len() - 1,
            self.colptr.clone(),
            self.rowval.clone(),
            self.values.clone(),
        )
    }
}

/// A cone of the program.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Cone {
    /// A second-order cone of the given dimension.
    Soc(usize),
}

/// The numbers of one cone program in Clarabel's form:
/// minimise `1/2 x'Px + q'x` subject to `Ax + s = b`, `s` in the cones.
pub(super) struct Program {
    /// Upper triangle of P.
    pub(super) p: Csc,
    pub(super) q: Vec<f64>,
    pub(super) a: Csc,
    pub(super) b: Vec<f64>,
    pub(super) cones: Vec<Cone>,
}

/// What fixes the sparsity pattern of a program.
type Key = (
    Vec<usize>,
    Vec<usize>,
    Vec<usize>,
    Vec<usize>,
    Vec<Cone>,
    usize,
);

impl Program {
    /// Whether `key` is this program's (compared in place: no copy).
    fn has_key(&self, key: &Key) -> bool {
        self.p.colptr == key.0
            && self.p.rowval == key.1
            && self.a.colptr == key.2
            && self.a.rowval == key.3
            && self.cones == key.4
            && self.b.len() == key.5
    }

    /// What fixes the sparsity pattern: a solver built for one program can
    /// take the numbers of another with the same key.
    fn key(&self) -> Key {
        (
            self.p.colptr.clone(),
            self.p.rowval.clone(),
            self.a.colptr.clone(),
            self.a.rowval.clone(),
            self.cones.clone(),
            self.b.len(),
        )
    }
}

/// What a cone step keeps of Clarabel's solution.
pub(super) struct Solved {
    pub(super) x: Vec<f64>,
    pub(super) status: SolverStatus,
    pub(super) iterations: u32,
}

impl From<&clarabel::solver::DefaultSolution<f64>> for Solved {
    fn from(s: &clarabel::solver::DefaultSolution<f64>) -> Self {
        Solved {
            x: s.x.clone(),
            status: s.status,
            iterations: s.iterations,
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
    builds: usize,
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
            .field("builds", &self.builds)
            .finish()
    }
}

impl ConeSolver {
    /// A solver whose cone programs are solved to `tol` (gap and
    /// feasibility); below the default, Clarabel's iterative refinement is
    /// switched on as well.
    pub fn new(tol: f64) -> Self {
        ConeSolver {
            tol,
            cached: None,
            builds: 0,
        }
    }

    /// The accuracy its programs are solved to.
    pub(super) fn tol(&self) -> f64 {
        self.tol
    }

    /// How many Clarabel solvers this one has built: one per change of the
    /// programs' sparsity pattern (the steps in between reuse it). Cheap to
    /// read; a benchmark can print it beside its timings.
    pub fn builds(&self) -> usize {
        self.builds
    }

    /// Solve `prog`: Clarabel's solution, or why it failed. The error is
    /// [`crate::Error::OutOfMemory`] when a new solver would not fit in the
    /// memory left (checked before Clarabel, which cannot fail gracefully,
    /// allocates).
    pub(super) fn run(&mut self, prog: &Program) -> CoreResult<Result<Solved, String>> {
        let reuse = matches!(&self.cached, Some((k, _)) if prog.has_key(k));
        if !reuse {
            // The old solver goes before the new one is built.
            self.cached = None;
            let (n, m) = (prog.q.len(), prog.b.len());
            let bytes = estimate::clarabel(n, m, prog.p.values.len() + prog.a.values.len());
            probe(bytes, "the cone solver (Clarabel)")?;
        }
        // A new solver's allocations were probed: marked as guarded (see
        // `memory::guarded_allocation`).
        let outcome = catch_unwind(AssertUnwindSafe(|| -> Result<_, String> {
            if reuse {
                if let Some((_, solver)) = self.cached.as_mut() {
                    solver
                        .update_data(&prog.p.values, &prog.q, &prog.a.values, &prog.b)
                        .map_err(|e| format!("data update failed: {e}"))?;
                    solver.solve();
                    return Ok(Solved::from(&solver.solution));
                }
            }
            guarded(|| self.build(prog))
        }));
        Ok(match outcome {
            Ok(r) => r,
            Err(_) => {
                self.cached = None;
                Err("the cone solver panicked".to_string())
            }
        })
    }

    /// Build a solver for `prog`, solve, and keep the solver.
    fn build(&mut self, prog: &Program) -> Result<Solved, String> {
        let n = prog.q.len();
        let p = prog.p.to_clarabel(n);
        let a = prog.a.to_clarabel(prog.b.len());
        let cones: Vec<SupportedConeT<f64>> = prog
            .cones
            .iter()
            .map(|&c| match c {
                Cone::Soc(d) => SupportedConeT::SecondOrderConeT(d),
            })
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
            // The step is Jacobi-scaled already (P has a unit
            // diagonal); Clarabel's own equilibration on top of it
            // costs interior-point iterations: measured 13.5 -> 11.2 per
            // step on the gantry, 17.0 -> 11.7 on points25, 12.6 -> 8.4
            // on n10 (benches/bench_scale.py), same models.
            .equilibrate_enable(false)
            .build()
            .map_err(|e| format!("settings: {e}"))?;
        let mut solver = DefaultSolver::new(&p, &prog.q, &a, &prog.b, &cones, settings)
            .map_err(|e| format!("setup failed: {e}"))?;
        self.builds += 1;
        solver.solve();
        let sol = Solved::from(&solver.solution);
        self.cached = Some((prog.key(), solver));
        Ok(sol)
    }
}

impl ConeProblem<'_> {
    /// The cone program over `x = [e_G; t]`: `P = P_red` (its dense upper
    /// triangle), then one cone per group, `(t_k, varphi (theta_g + d_g))`,
    /// i.e. `s = b - A x` with `A = -1` at `t_k` (`b = 0`) and
    /// `A = -varphi S` at each free entry (`b = varphi theta`).
    ///
    /// Measured against an epigraph form (`P = 0`, `P_red = R^T R`,
    /// `y = R e` as equality rows and `||y||^2 <= 2 s` as one more cone,
    /// which moves the dense block from P to A): on the gantry path the
    /// epigraph form took twice the time per step and more steps.
    pub(super) fn program(
        &self,
        open: &[&ConeGroup],
        scale: &[f64],
        p_red: &Mat<f64>,
        q_red: Vec<f64>,
    ) -> CoreResult<Program> {
        let nk = p_red.nrows();
        let ng = open.len();
        let mut b = Vec::new();
        let mut cones = Vec::with_capacity(ng);
        let mut t_rows = Vec::with_capacity(ng);
        let mut a = Csc::new();
        for g in open {
            t_rows.push(b.len());
            b.push(0.0);
            for &(i, pos) in &g.entries {
                if let Some(p) = pos {
                    // grouped columns come in this same order
                    a.push([(b.len(), -g.varphi * scale[p])]);
                }
                b.push(g.varphi * self.theta[i]);
            }
            cones.push(Cone::Soc(1 + g.entries.len()));
        }
        for &row in &t_rows {
            a.push([(row, -1.0)]);
        }
        let mut p = Csc::with_capacity(nk * (nk + 1) / 2, "the cone program's quadratic")?;
        for c in 0..nk {
            p.push((0..=c).map(|i| (i, p_red[(i, c)])));
        }
        for _ in 0..ng {
            p.push([]);
        }
        let mut q = q_red;
        q.extend(open.iter().map(|g| self.gamma * g.phi));
        Ok(Program { p, q, a, b, cones })
    }
}

#[cfg(test)]
#[path = "program_tests.rs"]
mod tests;
