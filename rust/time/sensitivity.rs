//! The forward sensitivity recursion of one record and the Gram matrix of
//! its Jacobian, block of samples by block of samples.
//!
//! For the state columns (see [`super::columns`]) the sensitivities
//! `S(t)` (`n` rows, one column per parameter) follow
//! `S(t+1) = Ad(t) S(t) + F(t)`, and their outputs are `C(t) S(t)`; the
//! output columns are `psi_i(t) z_b(t)` in one output. Each block of
//! samples fills the weighted Jacobian rows of its samples (`l` per
//! sample, zero before `skip`) and adds `J^T J` and `J^T r` to the sums.
//! The columns are cut into one slice per thread (the recursion of one
//! column does not depend on the others); the Gram product is faer's,
//! parallel over the output blocks.

// Small kernels index several arrays at once; an index reads best.
#![allow(clippy::needless_range_loop)]

use super::columns::{Columns, OutputColumn, StateColumn};
use super::frames::{Coefficients, Frames};
use super::record::Record;
use super::StageTimes;
use crate::error::Result;
use faer::linalg::matmul::matmul;
use faer::linalg::matmul::triangular::{matmul as tri_matmul, BlockStructure};
use faer::{Accum, Mat, MatRef, Par};
use std::time::Instant;

/// Jacobian rows per block of samples (a multiple of 8).
const BLOCK_ROWS: usize = 2048;

/// `J^T J` (full, symmetric, column-major) and `J^T r` of a record.
#[derive(Debug, Clone)]
pub(crate) struct Normal {
    pub k: usize,
    pub gram: Vec<f64>,
    pub jtr: Vec<f64>,
}

/// One pass over a record at one parameter vector.
pub(crate) struct Pass<'a> {
    pub coef: &'a Coefficients,
    pub record: &'a Record,
    /// Sample time of a continuous-time model (zero-order hold).
    pub hold: Option<f64>,
    /// Samples left out of the cost at the start.
    pub skip: usize,
    /// Nominal states `x(0..=T)`, `(T + 1) x n` (may be empty when no
    /// column needs them).
    pub states: &'a [f64],
    /// Weighted residual, `T x l`.
    pub residual: &'a [f64],
    pub columns: &'a Columns,
}

/// The state columns one thread advances.
struct Slice {
    cols: Vec<StateColumn>,
    width: usize,
    /// `S(t)`, `n x width` row-major.
    s: Vec<f64>,
    next: Vec<f64>,
    tmp: Vec<f64>,
}

impl Slice {
    fn new(cols: &[StateColumn], n: usize) -> Slice {
        let width = cols.len();
        let mut s = vec![0.0; n * width];
        for (k, col) in cols.iter().enumerate() {
            if let StateColumn::Initial { a } = *col {
                s[a * width + k] = 1.0;
            }
        }
        Slice {
            cols: cols.to_vec(),
            width,
            s,
            next: vec![0.0; n * width],
            tmp: vec![0.0; width],
        }
    }

    /// Write the Jacobian rows of samples `t0..t1` into the slice's columns
    /// of `jac` (column stride `ld`) and advance the recursion past `t1`.
    fn advance(
        &mut self,
        pass: &Pass<'_>,
        frames: &Frames,
        (t0, t1): (usize, usize),
        jac: &mut [f64],
        ld: usize,
    ) {
        let (n, r, l) = (pass.coef.n, pass.coef.r, pass.coef.l);
        let width = self.width;
        let w = pass.record.weight();
        let u = pass.record.u();
        for t in t0..t1 {
            let k = t - t0;
            let c = frames.c(k);
            for j in 0..l {
                let row = k * l + j;
                if t < pass.skip {
                    for col in 0..width {
                        jac[col * ld + row] = 0.0;
                    }
                    continue;
                }
                self.tmp.fill(0.0);
                for cc in 0..n {
                    let coef = c[j * n + cc];
                    let src = &self.s[cc * width..(cc + 1) * width];
                    for (d, &v) in self.tmp.iter_mut().zip(src) {
                        *d += coef * v;
                    }
                }
                let wj = w[t * l + j];
                for (col, &v) in self.tmp.iter().enumerate() {
                    jac[col * ld + row] = wj * v;
                }
            }
            let ad = frames.ad(k);
            for a in 0..n {
                let dst = &mut self.next[a * width..(a + 1) * width];
                dst.fill(0.0);
                for cc in 0..n {
                    let coef = ad[a * n + cc];
                    let src = &self.s[cc * width..(cc + 1) * width];
                    for (d, &v) in dst.iter_mut().zip(src) {
                        *d += coef * v;
                    }
                }
            }
            let psi1 = frames.psi1(k);
            match frames.forcing(k) {
                None => {
                    for (col, sc) in self.cols.iter().enumerate() {
                        if let StateColumn::Theta { i, a, zb } = *sc {
                            let z = if zb < n {
                                pass.states[t * n + zb]
                            } else {
                                u[t * r + zb - n]
                            };
                            self.next[a * width + col] += psi1[i] * z;
                        }
                    }
                }
                Some(f) => {
                    let s = n + r;
                    for (col, sc) in self.cols.iter().enumerate() {
                        if let StateColumn::Theta { i, a, zb } = *sc {
                            let v = &f[(a * s + zb) * n..(a * s + zb + 1) * n];
                            for cc in 0..n {
                                self.next[cc * width + col] += psi1[i] * v[cc];
                            }
                        }
                    }
                }
            }
            std::mem::swap(&mut self.s, &mut self.next);
        }
    }
}

/// The output columns' rows of samples `t0..t1`, one column after the other.
fn output_columns(
    pass: &Pass<'_>,
    frames: &Frames,
    (t0, t1): (usize, usize),
    cols: &[OutputColumn],
    jac: &mut [f64],
    ld: usize,
) {
    let (n, r, l) = (pass.coef.n, pass.coef.r, pass.coef.l);
    let w = pass.record.weight();
    let u = pass.record.u();
    let rows = (t1 - t0) * l;
    for (k, oc) in cols.iter().enumerate() {
        let dst = &mut jac[k * ld..k * ld + rows];
        dst.fill(0.0);
        for t in t0.max(pass.skip)..t1 {
            let z = if oc.zb < n {
                pass.states[t * n + oc.zb]
            } else {
                u[t * r + oc.zb - n]
            };
            dst[(t - t0) * l + oc.j] = w[t * l + oc.j] * frames.psi1(t - t0)[oc.i] * z;
        }
    }
}

impl Pass<'_> {
    /// `J^T J` and `J^T r` over the columns, in their engine order.
    pub fn run(&self, times: &mut StageTimes) -> Result<Normal> {
        let (n, l) = (self.coef.n, self.coef.l);
        let total = self.record.len();
        let kcols = self.columns.len();
        let n_state = self.columns.state.len();
        let block = (BLOCK_ROWS / l).max(8);
        // Column stride: a multiple of 8 plus 8, so that the columns of a
        // block do not all map to the same cache sets.
        let ld = (block * l).div_ceil(8) * 8 + 8;
        let mut jac = vec![0.0; ld * kcols];
        let mut rr = vec![0.0; block * l];
        let threads = rayon::current_num_threads().max(1);
        let pieces = threads.min(n_state).max(1);
        let mut slices: Vec<Slice> = (0..pieces)
            .map(|p| {
                let (a, b) = (p * n_state / pieces, (p + 1) * n_state / pieces);
                Slice::new(&self.columns.state[a..b], n)
            })
            .filter(|s| s.width > 0)
            .collect();
        let forcing = self.hold.is_some() && self.columns.theta_state > 0;
        let mut frames = Frames::new(self.coef, block, forcing);
        let mut gram = Mat::<f64>::zeros(kcols, kcols);
        let mut jtr = Mat::<f64>::zeros(kcols, 1);
        for t0 in (0..total).step_by(block) {
            let t1 = (t0 + block).min(total);
            let clock = Instant::now();
            frames.fill(self.coef, self.record, self.states, self.hold, (t0, t1))?;
            times.discretisation += clock.elapsed().as_secs_f64();
            let clock = Instant::now();
            let (state_part, out_part) = jac.split_at_mut(n_state * ld);
            let mut parts = Vec::with_capacity(slices.len());
            let mut rest = state_part;
            for s in &slices {
                let (head, tail) = rest.split_at_mut(s.width * ld);
                parts.push(head);
                rest = tail;
            }
            let frames_ref = &frames;
            rayon::scope(|scope| {
                for (slice, part) in slices.iter_mut().zip(parts) {
                    scope.spawn(move |_| slice.advance(self, frames_ref, (t0, t1), part, ld));
                }
                if !self.columns.output.is_empty() {
                    scope.spawn(move |_| {
                        output_columns(
                            self,
                            frames_ref,
                            (t0, t1),
                            &self.columns.output,
                            out_part,
                            ld,
                        )
                    });
                }
            });
            times.sensitivities += clock.elapsed().as_secs_f64();
            if t1 <= self.skip {
                continue;
            }
            let clock = Instant::now();
            let rows = (t1 - t0) * l;
            for (k, v) in rr[..rows].iter_mut().enumerate() {
                let t = t0 + k / l;
                *v = if t < self.skip {
                    0.0
                } else {
                    self.residual[t0 * l + k]
                };
            }
            let jm = MatRef::from_column_major_slice_with_stride(
                &jac[..(kcols - 1) * ld + rows],
                rows,
                kcols,
                ld,
            );
            tri_matmul(
                gram.as_mut(),
                BlockStructure::TriangularLower,
                Accum::Add,
                jm.transpose(),
                BlockStructure::Rectangular,
                jm,
                BlockStructure::Rectangular,
                1.0,
                Par::rayon(0),
            );
            let rm = MatRef::from_column_major_slice(&rr[..rows], rows, 1);
            matmul(jtr.as_mut(), Accum::Add, jm.transpose(), rm, 1.0, Par::Seq);
            times.gram += clock.elapsed().as_secs_f64();
        }
        let mut full = vec![0.0; kcols * kcols];
        for j in 0..kcols {
            for i in j..kcols {
                full[i + j * kcols] = gram[(i, j)];
                full[j + i * kcols] = gram[(i, j)];
            }
        }
        Ok(Normal {
            k: kcols,
            gram: full,
            jtr: (0..kcols).map(|i| jtr[(i, 0)]).collect(),
        })
    }
}
