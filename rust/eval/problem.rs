//! An identification problem: a model shape, FRF data and the basis values
//! at the data's scheduling points. Evaluates the weighted residual, V_NLS
//! (method.md (7)), its gradient and the Gauss-Newton matrix `J^T J` from the
//! analytic Jacobian without forming the full Jacobian (method.md section 3):
//! per point `q` the Gram matrix `H_q = J_q^T J_q` of the frozen LTI model is
//! accumulated from the Kronecker structure of its rows ([`crate::eval::kron_gram`]),
//! and `J^T J = sum_q (psi_q psi_q^T) kron H_q`.

use crate::base::data::FrfData;
use crate::base::lanes::{Cx, LANES};
use crate::base::layout::{FreeSet, Matrix, Shape};
use crate::base::spread::{self, worth_spreading};
use crate::error::{invalid, Error, Result};
use crate::eval::kron_gram::GramParts;
use crate::eval::lti::{lanes_of, Frozen, Hessenberg, Resolvent};
use crate::eval::model::with_constant;
use crate::eval::objective::{GaussNewton, Objective};
use crate::eval::point_factors::{worth_it, PointFactors};
use crate::eval::point_sums::PointSums;
use crate::eval::workspace::{Spares, Workspace};
use crate::memory::{try_par_columns_by, try_vec};
use num_complex::Complex64 as C64;
use std::mem::MaybeUninit;

/// Real residuals per task (the unit of parallel work).
const TASK_COLUMNS: usize = 1024;

/// Frequency lines per task: about [`TASK_COLUMNS`] real residuals, whole
/// batches of [`LANES`] lines.
pub(crate) fn lines_per_task(shape: &Shape) -> usize {
    (TASK_COLUMNS / (2 * shape.l * shape.r * LANES)).max(1) * LANES
}

/// Whether unfolding the Gram sums of `points` points of `lti` LTI
/// parameters goes to the pool. Unfolding a point's sums writes its
/// `lti^2` entries out of order, counted as 8 flops each: at n = 16 2x2
/// nine points of 105 000 entries go to the pool, at the gantry's size
/// five of 3136 not.
fn unfold_spreads(points: usize, lti: usize) -> bool {
    worth_spreading(points, (8 * points * lti * lti) as f64)
}

/// Whether the Hessenberg forms of order `n` at `points` points go to the
/// pool. A reduction takes about as long as 60 n^3 flops of the Gram
/// kernels (measured 4 us at n = 10, 12 us at 16): n = 16's nine points
/// go, the gantry's five of order 6 not.
fn forms_spread(n: usize, points: usize) -> bool {
    worth_spreading(points, (60 * n * n * n * points) as f64)
}

/// Shape, data and basis values of one identification problem.
#[derive(Debug, Clone)]
pub struct Problem {
    shape: Shape,
    data: FrfData,
    /// `N x (Nb + 1)` row-major, first column all ones.
    psi: Vec<f64>,
    /// For every entry of theta: its basis index `i` and its index in the
    /// LTI parameter vector `[vec A; vec B; vec C; vec D]`.
    param_map: Vec<(usize, usize)>,
    /// The evaluations' scratch space, kept for the next one.
    spares: Spares,
}

/// A half-open range of frequency lines at one point: the unit of parallel work.
#[derive(Debug, Clone, Copy)]
struct Task {
    point: usize,
    first: usize,
    end: usize,
}

impl Problem {
    /// Checked constructor. `basis` holds `psi_1..psi_Nb` at every point,
    /// `N x Nb` row-major.
    pub fn new(shape: Shape, data: FrfData, basis: &[f64]) -> Result<Self> {
        if data.l() != shape.l || data.r() != shape.r {
            return Err(invalid(
                "data",
                format!(
                    "data has {} outputs and {} inputs, the model {} and {}",
                    data.l(),
                    data.r(),
                    shape.l,
                    shape.r
                ),
            ));
        }
        let psi = with_constant(basis, data.n_points(), shape.nb)?;
        let mut param_map = Vec::with_capacity(shape.len());
        for x in Matrix::ALL {
            for i in 0..shape.n_coef() {
                let off = shape.lti_offset(x);
                param_map.extend((0..shape.matrix_len(x)).map(|p| (i, off + p)));
            }
        }
        Ok(Problem {
            shape,
            data,
            psi,
            param_map,
            spares: Spares::default(),
        })
    }

    /// The model shape.
    pub fn shape(&self) -> &Shape {
        &self.shape
    }

    /// The data.
    pub fn data(&self) -> &FrfData {
        &self.data
    }

    /// `[1, psi_1(p[q]), ..., psi_Nb(p[q])]`.
    pub fn psi(&self, q: usize) -> &[f64] {
        let m = self.shape.n_coef();
        &self.psi[q * m..(q + 1) * m]
    }

    /// Number of complex residuals `N F l r`.
    pub fn n_residuals(&self) -> usize {
        self.data.n_residuals()
    }

    /// Weighted complex residual `(G - Gm) / sigma`, `(N, F, l, r)` row-major.
    pub fn residual(&self, theta: &[f64]) -> Result<Vec<C64>> {
        self.shape.check_theta(theta)?;
        let forms = self.forms(theta);
        let mut out = try_vec(self.n_residuals(), C64::new(0.0, 0.0), "the residuals")?;
        let tasks = self.split(&mut out);
        let spread = worth_spreading(tasks.len(), self.work(false));
        spread::try_for_each_init(
            tasks,
            spread,
            || Resolvent::new(&self.shape),
            |res, (task, slice)| {
                for first in (task.first..task.end).step_by(LANES) {
                    let end = (first + LANES).min(task.end);
                    self.batch(&forms[task.point], res, task.point, (first, end), false)?;
                    self.write_residual(res, task, (first, end), slice);
                }
                Ok::<_, Error>(())
            },
        )?;
        Ok(out)
    }

    /// `V_NLS(theta)`.
    pub fn cost(&self, theta: &[f64]) -> Result<f64> {
        Ok(self.residual(theta)?.iter().map(|e| e.norm_sqr()).sum())
    }

    /// Residual, V_NLS, gradient and `J^T J`, the last two restricted to `free`.
    pub fn gauss_newton(&self, theta: &[f64], free: &FreeSet) -> Result<GaussNewton> {
        // The workspaces live to the end of the evaluation, and after it
        // only when small (`crate::eval::workspace`).
        let out = self.evaluate(theta, free);
        self.spares.trim(&self.shape);
        out
    }

    /// [`Problem::gauss_newton`], the workspaces left to the spares.
    fn evaluate(&self, theta: &[f64], free: &FreeSet) -> Result<GaussNewton> {
        self.shape.check_theta(theta)?;
        if free.full_len() != self.shape.len() {
            return Err(invalid("free", "mask length differs from theta"));
        }
        let forms = self.forms(theta);
        let lti = self.shape.lti_len();
        let mut residual = try_vec(self.n_residuals(), C64::new(0.0, 0.0), "the residuals")?;
        // The tasks in parallel, every point's parts summed in task order
        // as they finish; then every point's Gram matrix unfolded, the
        // points in parallel.
        let per_task = lines_per_task(&self.shape);
        let sums = PointSums::new(self.data.n_points());
        let tasks = self.split(&mut residual);
        let spread = worth_spreading(tasks.len(), self.work(true));
        spread::try_for_each_init(
            tasks,
            spread,
            || self.spares.lend(&self.shape),
            |ws, (task, slice)| {
                let ws = ws.as_mut().map_err(|e| e.clone())?.get()?;
                let part = self.task_gram(&forms[task.point], task, slice, ws, &sums)?;
                sums.add(task.point, task.first / per_task, part);
                Ok::<_, Error>(())
            },
        )?;
        let sums = sums
            .into_sums()
            .ok_or_else(|| Error::Internal("a task's Gram pieces went missing".into()))?;
        let unfolded = spread::map(
            sums,
            unfold_spreads(self.data.n_points(), lti),
            |sum| match sum {
                Some(sum) => Ok((sum.gram(&self.shape)?, sum.jtr)),
                None => {
                    let empty = "the Gram matrix of one scheduling point";
                    Ok((try_vec(lti * lti, 0.0, empty)?, vec![0.0; lti]))
                }
            },
        )
        .into_iter()
        .collect::<Result<Vec<_>>>()?;
        let (grams, jtr): (Vec<Vec<f64>>, Vec<Vec<f64>>) = unfolded.into_iter().unzip();
        let vnls = residual.iter().map(|e| e.norm_sqr()).sum();
        let (gradient, gram) = self.assemble(&grams, &jtr, free)?;
        let bound = self.rank_bound();
        let factors = if worth_it(lti, bound, self.data.n_points(), free.len()) {
            let psi = (0..self.data.n_points())
                .map(|q| self.psi(q).to_vec())
                .collect();
            let map = free.indices().iter().map(|&u| self.param_map[u]).collect();
            Some(PointFactors::new(&grams, &jtr, psi, map, lti, bound)?)
        } else {
            None
        };
        Ok(GaussNewton {
            vnls,
            gradient,
            gram,
            factors,
        })
    }

    /// The rank of a point's Gram matrix is at most `n (l + r) + l r`: the
    /// frozen response does not see the `n^2` similarity transformations
    /// (the Levenberg-Marquardt steps go through every point's factor
    /// where [`crate::eval::point_factors::worth_it`] says so).
    fn rank_bound(&self) -> usize {
        let s = &self.shape;
        (s.n * (s.l + s.r) + s.l * s.r).min(s.lti_len())
    }

    /// Hessenberg forms of the frozen models at every point.
    fn forms(&self, theta: &[f64]) -> Vec<Hessenberg> {
        let points = self.data.n_points();
        spread::map(0..points, forms_spread(self.shape.n, points), |q| {
            Hessenberg::new(&self.shape, &Frozen::at(&self.shape, theta, self.psi(q)))
        })
    }

    /// Flops of one evaluation of the residuals (`gram` false: a
    /// Hessenberg solve of about `8 n^2` for each input column of a line)
    /// or of the Gram pieces too (about `8 L^2` more a line, `L` the LTI
    /// parameters, and the solves of the output side), over every point.
    fn work(&self, gram: bool) -> f64 {
        let (s, lines) = (&self.shape, self.data.n_points() * self.data.n_lines());
        let solves = 8 * s.n * s.n * if gram { s.l + s.r } else { s.r };
        let per_line = solves
            + if gram {
                8 * s.lti_len() * s.lti_len()
            } else {
                0
            };
        (per_line * lines) as f64
    }

    /// Cut the lines of every point into tasks, each with its slice of `out`.
    fn split<'a>(&self, out: &'a mut [C64]) -> Vec<(Task, &'a mut [C64])> {
        let lr = self.shape.l * self.shape.r;
        let nf = self.data.n_lines();
        let per_task = lines_per_task(&self.shape);
        let mut rest = out;
        let mut tasks = Vec::new();
        for point in 0..self.data.n_points() {
            for first in (0..nf).step_by(per_task) {
                let end = (first + per_task).min(nf);
                let (head, tail) = std::mem::take(&mut rest).split_at_mut((end - first) * lr);
                tasks.push((Task { point, first, end }, head));
                rest = tail;
            }
        }
        tasks
    }

    /// Evaluate the frozen model at lines `first..end` (at most [`LANES`]) of point `q`.
    fn batch(
        &self,
        form: &Hessenberg,
        res: &mut Resolvent,
        q: usize,
        (first, end): (usize, usize),
        left: bool,
    ) -> Result<()> {
        res.evaluate(form, &lanes_of(self.data.z(), first, end), left)
            .map_err(|lane| Error::Singular {
                point: q,
                line: (first + lane).min(end - 1),
            })
    }

    /// Write `(G - Gm) / sigma` of lines `first..end` into the task's slice.
    fn write_residual(
        &self,
        res: &Resolvent,
        task: Task,
        (first, end): (usize, usize),
        slice: &mut [C64],
    ) {
        let (l, r) = (self.shape.l, self.shape.r);
        for (lane, k) in (first..end).enumerate() {
            let off = self.data.offset(task.point, k);
            let (gm, w) = (&self.data.g()[off..], &self.data.weight()[off..]);
            let dst = &mut slice[(k - task.first) * l * r..];
            for j in 0..l {
                for c in 0..r {
                    let e = j * r + c;
                    dst[e] = (res.g[j + c * l].lane(lane) - gm[e]) * w[e];
                }
            }
        }
    }

    /// The Gram pieces and `J^T r` of one task's lines (see [`crate::eval::kron_gram`]).
    fn task_gram(
        &self,
        form: &Hessenberg,
        task: Task,
        slice: &mut [C64],
        ws: &mut Workspace,
        sums: &PointSums,
    ) -> Result<GramParts> {
        let lr = self.shape.l * self.shape.r;
        let q = task.point;
        let acc = &mut ws.gram;
        // The accumulator's next sums, had before it fills (it is empty now).
        let next = sums.next_sums(&self.shape)?;
        let mut w = vec![[0.0; LANES]; lr];
        let mut err = vec![Cx::default(); lr];
        for first in (task.first..task.end).step_by(LANES) {
            let end = (first + LANES).min(task.end);
            if let Err(e) = self.batch(form, &mut ws.resolvent, q, (first, end), true) {
                // The next task on this thread starts from an empty accumulator.
                acc.clear();
                return Err(e);
            }
            self.write_residual(&ws.resolvent, task, (first, end), slice);
            w.iter_mut().for_each(|x| *x = [0.0; LANES]);
            err.iter_mut().for_each(|x| *x = Cx::default());
            for (lane, k) in (first..end).enumerate() {
                let off = self.data.offset(q, k);
                for e in 0..lr {
                    w[e][lane] = self.data.weight()[off + e];
                    let v = slice[(k - task.first) * lr + e];
                    err[e].re[lane] = v.re;
                    err[e].im[lane] = v.im;
                }
            }
            acc.add(&ws.resolvent, &w, &err);
        }
        Ok(acc.finish(&self.shape, next))
    }

    /// Gradient and `J^T J` over the free parameters from the per-point
    /// Gram matrices: entry `(u, v)` of `J^T J`, `u` and `v` of basis
    /// indices `i` and `j` and LTI indices `p_u` and `p_v`, is
    /// `sum_q psi_qi psi_qj H_q[p_u, p_v]`.
    fn assemble(
        &self,
        full: &[Vec<f64>],
        jtr: &[Vec<f64>],
        free: &FreeSet,
    ) -> Result<(Vec<f64>, Vec<f64>)> {
        let lti = self.shape.lti_len();
        let n_points = self.data.n_points();
        // Basis index and LTI index of every free parameter.
        let map: Vec<(usize, usize)> = free.indices().iter().map(|&u| self.param_map[u]).collect();
        let nf = free.len();
        // Runs of consecutive free parameters of one basis index: their
        // entries of a column of `J^T J` come from consecutive entries of a
        // column of every `H_q`.
        let mut runs: Vec<(usize, usize, usize)> = Vec::new(); // (first, basis, lti index)
        for (u, &(i, p)) in map.iter().enumerate() {
            match runs.last() {
                Some(&(first, ri, rp)) if ri == i && rp + (u - first) == p => {}
                _ => runs.push((u, i, p)),
            }
        }
        // Whole columns, in parallel, straight from the `H_q` (no sums per
        // pair of basis functions to copy from): each entry the sum over
        // the points in their order, its first term written into the empty
        // room (no pass of zeros), with `psi_qi psi_qj` taken smaller basis
        // index first.
        let fill = |v: usize, column: &mut [MaybeUninit<f64>]| {
            let (j, pv) = map[v];
            for (k, &(first, i, pu)) in runs.iter().enumerate() {
                let end = runs.get(k + 1).map_or(nf, |r| r.0);
                let out = &mut column[first..end];
                let mut written = false;
                for (q, hq) in full.iter().enumerate().take(n_points) {
                    let c = self.psi(q)[i.min(j)] * self.psi(q)[i.max(j)];
                    if c == 0.0 {
                        continue;
                    }
                    let source = &hq[pu + pv * lti..pu + pv * lti + out.len()];
                    if written {
                        for (d, h) in out.iter_mut().zip(source) {
                            // SAFETY: written by the first term below.
                            unsafe { *d.assume_init_mut() += c * h };
                        }
                    } else {
                        for (d, h) in out.iter_mut().zip(source) {
                            d.write(c * h);
                        }
                        written = true;
                    }
                }
                if !written {
                    out.fill(MaybeUninit::new(0.0)); // every psi_qi psi_qj zero
                }
            }
        };
        // SAFETY: the runs cover 0..nf in order (the first starts at 0,
        // each ends where the next starts, the last at nf), and `fill`
        // writes every entry of each run.
        // A term of every point an entry.
        let spread = worth_spreading(nf, (nf * nf * n_points) as f64);
        let what = "the Gauss-Newton matrix J^T J";
        let gram = unsafe { try_par_columns_by(nf, nf, fill, spread, what) }?;
        let gradient = free
            .indices()
            .iter()
            .map(|&u| {
                let (i, p) = self.param_map[u];
                2.0 * (0..n_points)
                    .map(|q| self.psi(q)[i] * jtr[q][p])
                    .sum::<f64>()
            })
            .collect();
        Ok((gradient, gram))
    }
}

impl Objective for Problem {
    fn shape(&self) -> &Shape {
        Problem::shape(self)
    }

    fn n_residuals(&self) -> usize {
        Problem::n_residuals(self)
    }

    fn cost(&self, theta: &[f64]) -> Result<f64> {
        Problem::cost(self, theta)
    }

    fn gauss_newton(&self, theta: &[f64], free: &FreeSet) -> Result<GaussNewton> {
        Problem::gauss_newton(self, theta, free)
    }

    fn response(&self, theta: &[f64]) -> Result<Vec<f64>> {
        Ok(self
            .residual(theta)?
            .iter()
            .flat_map(|e| [e.re, e.im])
            .collect())
    }
}

#[cfg(test)]
#[path = "problem_tests.rs"]
mod tests;
