//! What a fit needs in memory, from the sizes of the problem, before it
//! starts: the arrays of one Gauss-Newton evaluation (FRF data: the
//! per-point Gram pieces of every block of lines, the per-point Gram
//! matrices, `J^T J` from them; time records: the
//! Jacobian block, the per-thread sums), what the optimiser holds between
//! evaluations (`J^T J`, the Cholesky factor of a Levenberg-Marquardt
//! step, the cone step's dense block and the Clarabel solvers) and the
//! per-thread workspaces. Each term follows the code that allocates it
//! (the sizes are read from the same constants); `tests/core_memory.rs`
//! checks the totals against the peak measured by a counting allocator.
//!
//! The estimate is of the bytes a fit allocates beyond what the caller
//! already holds (the data, the problem).

use crate::base::lanes::LANES;
use crate::base::layout::{FreeSet, Matrix, Shape};
use crate::eval::kron_gram::{GramParts, KronGram};
use crate::eval::problem::lines_per_task;
use crate::eval::workspace;
use crate::time::BLOCK_ROWS;
use faer::linalg::cholesky::llt::factor::cholesky_in_place_scratch;
use faer::Par;

/// Which optimiser runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// Levenberg-Marquardt (`fit_nls`, `fit_time`).
    Lm,
    /// The reweighted l2,1 fit and the gamma path (cone steps).
    L21 {
        /// With directions kept off (`pinned=True`): one more dense matrix.
        pinned: bool,
    },
}

/// Sizes of the time records of a problem.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TimeSizes {
    /// Samples of every record.
    pub lengths: Vec<usize>,
    /// Continuous time (the zero-order hold's derivative is formed).
    pub hold: bool,
    /// Initial states estimated (and eliminated).
    pub estimate_x0: bool,
}

/// The sizes that fix a fit's memory.
#[derive(Debug, Clone)]
pub struct FitSizes {
    /// The model shape.
    pub shape: Shape,
    /// The free parameters.
    pub free: FreeSet,
    /// FRF data: scheduling points and frequency lines (`None`: none).
    pub frf: Option<(usize, usize)>,
    /// Time records (`None`: none).
    pub time: Option<TimeSizes>,
    /// Threads of the pool the fit runs on.
    pub threads: usize,
}

/// The estimate, in bytes, by part.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Estimate {
    /// One Gauss-Newton evaluation at its peak (its result included).
    pub evaluation: usize,
    /// What the fit holds across evaluations (`J^T J` and gradient of the
    /// current point; for cone steps the Clarabel solvers kept; the
    /// workspaces the problem keeps, [`kept_workspaces`]).
    pub held: usize,
    /// One step at its peak beyond what is held (the Levenberg-Marquardt
    /// factor; the cone programs' dense blocks and solver set-up).
    pub step: usize,
    /// Scratch that no formula above follows: the packing buffers of the
    /// matrix products (a cache-sized slab per thread and a panel per
    /// product) and the vectors over the free parameters.
    pub scratch: usize,
    /// The fit's peak: `held + max(step, evaluation - kept) + scratch`,
    /// `kept` the workspaces counted in both `held` and `evaluation`.
    pub total: usize,
}

/// [`Estimate::scratch`] per thread of the pool.
const SCRATCH_PER_THREAD: usize = 4 << 20;
/// [`Estimate::scratch`] besides the threads'.
const SCRATCH: usize = 8 << 20;

const F64: usize = 8;
const C64: usize = 16;
/// A complex number per lane (`crate::base::lanes::Cx`).
const CX: usize = 2 * LANES * F64;

/// Bytes of `n` f64.
fn floats(n: usize) -> usize {
    n.saturating_mul(F64)
}

/// Bytes of a dense `n x n` matrix of f64.
fn square(n: usize) -> usize {
    floats(n.saturating_mul(n))
}

/// One Gauss-Newton evaluation of FRF data (`Problem::gauss_newton`) at
/// its peak, its result included.
pub fn frf_evaluation(
    shape: &Shape,
    n_points: usize,
    n_lines: usize,
    n_free: usize,
    threads: usize,
) -> usize {
    let Shape { n, r, l, .. } = *shape;
    let lti = shape.lti_len();
    // Hessenberg forms of the frozen models, and the residuals.
    let forms = n_points * floats(2 * n * n + n * r + l * n + l * r);
    let residual = n_points * n_lines * l * r * C64;
    let base = forms + residual;
    // Stage 1: per thread a resolvent and a Gram accumulator, and the
    // sums of its next task; every point's running sum of its
    // tasks' parts, and the parts that wait for an earlier task of their
    // point (`crate::eval::point_sums`: a thread works through a run of tasks in
    // order, so the parts of at most one point per thread wait), never
    // more than every task's part.
    let workspace = workspace_bytes(shape);
    // The workspaces live to the end of the evaluation (the small ones
    // after it too: [`kept_workspaces`]).
    let workspaces = threads * workspace;
    let tasks_per_point = n_lines.div_ceil(lines_per_task(shape));
    let part = GramParts::bytes(shape);
    let parts = part * (n_points * tasks_per_point).min(n_points + threads * tasks_per_point);
    let stage1 = workspaces + threads * part + parts;
    // Stage 2: every point's sum unfolded into its Gram matrix (the points
    // in parallel: the sums not yet unfolded, the Gram matrices of those
    // done).
    let gram_point = square(lti) + floats(lti);
    let busy = threads.min(n_points);
    let stage2 = n_points * part.max(gram_point) + busy * gram_point + workspaces;
    // Stage 3: J^T J, from the Gram matrices of the points.
    let result = square(n_free) + floats(n_free);
    let stage3 = n_points * gram_point + result + workspaces;
    base + stage1.max(stage2).max(stage3)
}

/// One thread's workspace of a Gauss-Newton evaluation of FRF data: a
/// resolvent and a Gram accumulator (`crate::eval::workspace`).
fn workspace_bytes(shape: &Shape) -> usize {
    let Shape { n, r, l, .. } = *shape;
    let resolvent = CX * (n * n + 2 * n + 2 * n * r + 2 * n * l + l * r) + n * LANES;
    resolvent + KronGram::bytes(shape)
}

/// The workspaces a problem of FRF data keeps from one evaluation to the
/// next, one per thread, when its shape's are small enough
/// (`crate::eval::workspace`), else none.
pub fn kept_workspaces(shape: &Shape, threads: usize) -> usize {
    if workspace::kept(shape) {
        threads * workspace_bytes(shape)
    } else {
        0
    }
}

/// One Gauss-Newton evaluation of time records (`TimeProblem::gauss_newton`)
/// at its peak, its result included.
pub fn time_evaluation(shape: &Shape, free: &FreeSet, time: &TimeSizes, threads: usize) -> usize {
    let Shape { n, r, l, nb } = *shape;
    let m = nb + 1;
    let n_free = free.len();
    // Columns of the Jacobian that run through the state, and the others.
    let n_ab = free
        .indices()
        .iter()
        .filter(|&&i| i < shape.block(Matrix::C, 0).start)
        .count();
    let initial = if time.estimate_x0 { n } else { 0 };
    let n_state = n_ab + initial;
    let n_out = n_free - n_ab;
    let kcols = n_state + n_out;
    let longest = time.lengths.iter().copied().max().unwrap_or(0);
    // The result's sums, and one record's trajectories and residuals.
    let result = square(n_free) + floats(n_free);
    let coefficients = floats(m * (n * n + n * r + l * n));
    let record = floats((longest + 1) * n + 3 * longest * l);
    // One pass over the record: the Jacobian block, the state columns of
    // every thread, the output columns' values, the frames of a block and
    // the sums of every thread, then J^T J over all columns.
    let block = (BLOCK_ROWS / l).max(8);
    let pieces = threads.min(n_state).max(1);
    let slices = floats((2 * n + l) * (n_state + 8 * pieces));
    let frames = floats(block * (n * n + l * n + m))
        + if time.hold && n_ab > 0 {
            floats(block * n * (n + r) * n)
        } else {
            0
        };
    let per_output = n_out.div_ceil(l.max(1));
    let sums = threads
        * floats(
            n_state * n_state + n_state + n_out * n_state + l * per_output * per_output + n_out,
        );
    let pass = floats(block * l * (n_state + 1)) + slices + floats(block * n_out) + frames + sums;
    let normal = square(kcols) + floats(kcols);
    // The elimination of the initial states: J^T J over theta again.
    let eliminate = if time.estimate_x0 {
        square(n_free) + floats(n_free * n + n * n)
    } else {
        0
    };
    result + coefficients + record + (pass + normal).max(normal + eliminate)
}

/// Bytes per entry of a sparse matrix (value and row index).
const ENTRY: usize = F64 + std::mem::size_of::<usize>();

/// What a Clarabel solver keeps between the steps of a fit, for a cone
/// program with `n` variables, `m` cone rows and `nnz` entries in the
/// upper triangle of `P` and in `A`: its copy of the program, its KKT
/// matrix and the factor (the dense block of `P` fills in: as many entries
/// again), and their maps. Measured: 106 bytes per entry of `P` from
/// 400 to 1300 variables.
pub fn clarabel_kept(n: usize, m: usize, nnz: usize) -> usize {
    7 * nnz * ENTRY + floats(40 * (n + m))
}

/// What Clarabel allocates to set up a solver ([`clarabel_kept`] and the
/// copy of the program handed to it): what the cone step checks it can
/// have before it calls Clarabel.
pub fn clarabel(n: usize, m: usize, nnz: usize) -> usize {
    clarabel_kept(n, m, nnz) + nnz * ENTRY
}

/// One cone step's own arrays beside its solver: the program as built
/// (`P`'s upper triangle), the key of its pattern, and the elimination of
/// the constant parts (`others` of them: the Cholesky factor and the cross
/// block with the `grouped` parameters).
fn cone_step(nnz: usize, grouped: usize, others: usize) -> usize {
    nnz * (ENTRY + std::mem::size_of::<usize>())
        + square(others)
        + floats(others * grouped)
        + floats(8 * (grouped + others))
}

impl FitSizes {
    /// One Gauss-Newton evaluation of the whole cost at its peak.
    pub fn evaluation(&self) -> usize {
        let nf = self.free.len();
        let frf = self
            .frf
            .map(|(points, lines)| frf_evaluation(&self.shape, points, lines, nf, self.threads));
        let time = self
            .time
            .as_ref()
            .map(|t| time_evaluation(&self.shape, &self.free, t, self.threads));
        match (frf, time) {
            (Some(a), Some(b)) => a.max(square(nf) + floats(nf) + b + self.kept()),
            (a, b) => a.or(b).unwrap_or(0),
        }
    }

    /// The workspaces the FRF part keeps between evaluations
    /// ([`kept_workspaces`]).
    fn kept(&self) -> usize {
        self.frf
            .map_or(0, |_| kept_workspaces(&self.shape, self.threads))
    }

    /// The estimate for a fit by `method`.
    pub fn estimate(&self, method: Method) -> Estimate {
        let nf = self.free.len();
        let evaluation = self.evaluation();
        // The current point's J^T J and gradient, the Marquardt diagonal.
        let point = square(nf) + floats(3 * nf);
        let (held, step) = match method {
            Method::Lm => {
                let scratch =
                    cholesky_in_place_scratch::<f64>(nf, Par::rayon(0), Default::default());
                (point, square(nf) + scratch.size_bytes() + floats(nf))
            }
            Method::L21 { pinned } => {
                // Worst case: every penalised group in the program; the
                // constant parts eliminated first (Cholesky factor and
                // cross block).
                let constant: Vec<_> = Matrix::ALL
                    .iter()
                    .map(|&x| self.shape.block(x, 0))
                    .collect();
                let grouped = self
                    .free
                    .indices()
                    .iter()
                    .filter(|&&i| !constant.iter().any(|c| c.contains(&i)))
                    .count();
                let others = nf - grouped;
                let groups = self.shape.groups().len();
                let (n, m) = (grouped + groups, grouped + 2 * groups);
                let nnz = grouped * (grouped + 1) / 2 + grouped + groups;
                // One program at a time (`socp::WarmSteps`), its solver
                // kept between steps.
                let curvature = if pinned { square(nf) } else { 0 };
                // While a solver is set up: Clarabel's own, the copy handed
                // to it and the step's arrays.
                let set_up = clarabel(n, m, nnz) - clarabel_kept(n, m, nnz);
                (
                    point + clarabel_kept(n, m, nnz),
                    set_up + cone_step(nnz, grouped, others) + curvature,
                )
            }
        };
        let scratch = SCRATCH + self.threads * SCRATCH_PER_THREAD + floats(16 * nf);
        // The problem's kept workspaces are held through the steps, and
        // are part of every evaluation's peak.
        let kept = self.kept();
        let held = held + kept;
        Estimate {
            evaluation,
            held,
            step,
            scratch,
            total: held + step.max(evaluation.saturating_sub(kept)) + scratch,
        }
    }
}
