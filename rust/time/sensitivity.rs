//! The forward sensitivity recursion of one record and the Gram matrix of
//! its Jacobian, block of samples by block of samples.
//!
//! For the state columns (see [`super::columns`]) the sensitivities
//! `S(t)` (`n` rows, one column per parameter) follow
//! `S(t+1) = Ad(t) S(t) + F(t)`, and their outputs are `C(t) S(t)`; the
//! output columns are `psi_i(t) z_b(t)` in one output and zero in the
//! others. Each block of samples fills the weighted Jacobian rows of its
//! samples (`l` per sample, zero before `skip`) and adds `J^T J` and
//! `J^T r` to the sums, using the zeros of the output columns (their
//! products are formed output by output).
//!
//! Both cores work on both stages: the state columns are cut into one
//! slice per thread for the recursion (the recursion of one column does
//! not depend on the others), and the samples of a block into one share
//! per thread for the products (faer's, each thread with its own sums).

// Small kernels index several arrays at once; an index reads best.
#![allow(clippy::needless_range_loop)]

use super::columns::{Columns, OutputColumn, StateColumn};
use super::frames::{Coefficients, Frames};
pub(crate) use super::gram::Normal;
use super::gram::{ByOutput, Sums};
use super::record::Record;
use super::StageTimes;
use crate::error::Result;
use crate::memory::try_vec;
use faer::MatMut;
use std::time::Instant;

/// Jacobian rows per block of samples (a multiple of 8).
pub(crate) const BLOCK_ROWS: usize = 2048;

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
    /// Tests: the hold's derivative as computed before.
    #[cfg(test)]
    pub reference: bool,
}

/// Columns advanced together: one register block of the kernels.
const GROUP: usize = 8;

/// `acc += w v`, with a fused multiply-add when `FUSED` (only where the
/// CPU has it: elsewhere `mul_add` is a slow library call).
#[inline(always)]
fn axpy<const FUSED: bool>(acc: &mut [f64; GROUP], w: f64, v: &[f64]) {
    for k in 0..GROUP {
        acc[k] = if FUSED {
            w.mul_add(v[k], acc[k])
        } else {
            acc[k] + w * v[k]
        };
    }
}

/// The state columns one thread advances.
struct Slice {
    /// `(column, i, a, zb)` of every theta column (see [`StateColumn`]).
    theta: Vec<(usize, usize, usize, usize)>,
    width: usize,
    /// Width rounded up to whole groups; the padding columns stay zero.
    padded: usize,
    /// `S(t)`, `n x padded` row-major.
    s: Vec<f64>,
    next: Vec<f64>,
    /// `C(t) S(t)`, `l x padded` row-major.
    ybuf: Vec<f64>,
}

impl Slice {
    fn new(cols: &[StateColumn], n: usize, l: usize) -> Result<Slice> {
        let width = cols.len();
        let padded = width.div_ceil(GROUP) * GROUP;
        let what = "the state sensitivities";
        let mut s = try_vec(n * padded, 0.0, what)?;
        let mut theta = Vec::new();
        for (k, col) in cols.iter().enumerate() {
            match *col {
                StateColumn::Initial { a } => s[a * padded + k] = 1.0,
                StateColumn::Theta { i, a, zb } => theta.push((k, i, a, zb)),
            }
        }
        Ok(Slice {
            theta,
            width,
            padded,
            s,
            next: try_vec(n * padded, 0.0, what)?,
            ybuf: try_vec(l * padded, 0.0, what)?,
        })
    }

    /// Write the Jacobian rows of samples `t0..t1` into the slice's
    /// columns of `jac` and advance the recursion past `t1`, with AVX2 and
    /// FMA where the CPU has them (checked at run time).
    fn advance(
        &mut self,
        pass: &Pass<'_>,
        frames: &Frames,
        span: (usize, usize),
        jac: MatMut<'_, f64>,
    ) {
        let run = Advance {
            slice: self,
            pass,
            frames,
            span,
            jac,
        };
        #[cfg(target_arch = "x86_64")]
        if let Some(simd) = pulp::x86::V3::try_new().filter(|_| crate::base::route::Route::avx2()) {
            pulp::Simd::vectorize(simd, run);
            return;
        }
        run.kernel::<false>();
    }
}

/// One block of samples of one slice, as an operation that `pulp`
/// compiles for the instruction set found at run time.
struct Advance<'a, 'p> {
    slice: &'a mut Slice,
    pass: &'a Pass<'p>,
    frames: &'a Frames,
    span: (usize, usize),
    jac: MatMut<'a, f64>,
}

impl pulp::WithSimd for Advance<'_, '_> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) {
        // Only reached through an instruction set with FMA.
        self.kernel::<true>();
    }
}

impl Advance<'_, '_> {
    /// The kernel with the number of states fixed at compile time when it
    /// is at most 8 (the sources of a group of columns then stay in
    /// registers), known at run time otherwise.
    #[inline(always)]
    fn kernel<const FUSED: bool>(self) {
        match self.pass.coef.n {
            1 => self.run::<1, FUSED>(),
            2 => self.run::<2, FUSED>(),
            3 => self.run::<3, FUSED>(),
            4 => self.run::<4, FUSED>(),
            5 => self.run::<5, FUSED>(),
            6 => self.run::<6, FUSED>(),
            7 => self.run::<7, FUSED>(),
            8 => self.run::<8, FUSED>(),
            _ => self.run::<0, FUSED>(),
        }
    }

    /// `N` states, or any number when `N = 0`.
    #[inline(always)]
    fn run<const N: usize, const FUSED: bool>(self) {
        let Advance {
            slice,
            pass,
            frames,
            span: (t0, t1),
            mut jac,
        } = self;
        let (n, r, l) = (
            if N == 0 { pass.coef.n } else { N },
            pass.coef.r,
            pass.coef.l,
        );
        let (width, padded) = (slice.width, slice.padded);
        let w = pass.record.weight();
        let u = pass.record.u();
        for t in t0..t1 {
            let k = t - t0;
            let ad = &frames.ad(k)[..n * n];
            let c = &frames.c(k)[..l * n];
            // S(t+1) = Ad(t) S(t) and the outputs C(t) S(t), a group of
            // columns at a time.
            for g in (0..padded).step_by(GROUP) {
                if N > 0 {
                    let mut src = [[0.0; GROUP]; N];
                    for (cc, v) in src.iter_mut().enumerate() {
                        v.copy_from_slice(&slice.s[cc * padded + g..][..GROUP]);
                    }
                    for (a, row) in ad.chunks_exact(N).enumerate() {
                        let mut acc = [0.0; GROUP];
                        for (coef, v) in row.iter().zip(&src) {
                            axpy::<FUSED>(&mut acc, *coef, v);
                        }
                        slice.next[a * padded + g..][..GROUP].copy_from_slice(&acc);
                    }
                    for (j, row) in c.chunks_exact(N).enumerate() {
                        let mut acc = [0.0; GROUP];
                        for (coef, v) in row.iter().zip(&src) {
                            axpy::<FUSED>(&mut acc, *coef, v);
                        }
                        slice.ybuf[j * padded + g..][..GROUP].copy_from_slice(&acc);
                    }
                } else {
                    for (a, row) in ad.chunks_exact(n).chain(c.chunks_exact(n)).enumerate() {
                        let mut acc = [0.0; GROUP];
                        for (cc, &coef) in row.iter().enumerate() {
                            axpy::<FUSED>(&mut acc, coef, &slice.s[cc * padded + g..][..GROUP]);
                        }
                        let dst = if a < n {
                            &mut slice.next[a * padded + g..]
                        } else {
                            &mut slice.ybuf[(a - n) * padded + g..]
                        };
                        dst[..GROUP].copy_from_slice(&acc);
                    }
                }
            }
            // Row (k, j) of the block: w_j(t) C_j(t) S(t).
            for j in 0..l {
                let row = jac
                    .as_mut()
                    .row_mut(k * l + j)
                    .try_as_row_major_mut()
                    .expect("the Jacobian block is row-major")
                    .as_slice_mut();
                if t < pass.skip {
                    row.fill(0.0);
                } else {
                    let wj = w[t * l + j];
                    for (o, y) in row.iter_mut().zip(&slice.ybuf[j * padded..][..width]) {
                        *o = wj * y;
                    }
                }
            }
            // + F(t).
            let psi1 = frames.psi1(k);
            match frames.forcing(k) {
                None => {
                    for &(col, i, a, zb) in &slice.theta {
                        let z = if zb < n {
                            pass.states[t * n + zb]
                        } else {
                            u[t * r + zb - n]
                        };
                        slice.next[a * padded + col] += psi1[i] * z;
                    }
                }
                Some(f) => {
                    let s = n + r;
                    for &(col, i, a, zb) in &slice.theta {
                        let v = &f[(a * s + zb) * n..(a * s + zb + 1) * n];
                        for (cc, &x) in v.iter().enumerate() {
                            slice.next[cc * padded + col] += psi1[i] * x;
                        }
                    }
                }
            }
            std::mem::swap(&mut slice.s, &mut slice.next);
        }
    }
}

/// The output columns of one output `j`: their values `w_j(t) psi_i(t)
/// z_b(t)` at the rows of output `j` (their other rows are zero), samples
/// `t0..t1` row-major, zero before `skip`.
fn output_values(
    pass: &Pass<'_>,
    frames: &Frames,
    (t0, t1): (usize, usize),
    j: usize,
    cols: &[OutputColumn],
    out: &mut [f64],
) {
    let (n, r, l) = (pass.coef.n, pass.coef.r, pass.coef.l);
    let w = pass.record.weight();
    let u = pass.record.u();
    let width = cols.len();
    for (t, row) in (t0..t1).zip(out.chunks_exact_mut(width)) {
        if t < pass.skip {
            row.fill(0.0);
            continue;
        }
        let psi1 = frames.psi1(t - t0);
        let wj = w[t * l + j];
        for (o, oc) in row.iter_mut().zip(cols) {
            let z = if oc.zb < n {
                pass.states[t * n + oc.zb]
            } else {
                u[t * r + oc.zb - n]
            };
            *o = wj * psi1[oc.i] * z;
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
        // The state columns' rows of a block, row-major (row (t, j) at t l + j).
        let mut jac = try_vec(
            block * l * n_state,
            0.0,
            "the Jacobian of a block of samples",
        )?;
        let mut rr = vec![0.0; block * l];
        let threads = rayon::current_num_threads().max(1);
        let pieces = threads.min(n_state).max(1);
        let mut slices: Vec<Slice> = (0..pieces)
            .map(|p| {
                let (a, b) = (p * n_state / pieces, (p + 1) * n_state / pieces);
                Slice::new(&self.columns.state[a..b], n, l)
            })
            .collect::<Result<Vec<_>>>()?;
        slices.retain(|s| s.width > 0);
        let mut outs = ByOutput::new(&self.columns.output, l, block)?;
        let forcing = self.hold.is_some() && self.columns.theta_state > 0;
        let mut frames = Frames::new(self.coef, block, forcing)?;
        #[cfg(test)]
        {
            frames.reference = self.reference;
        }
        let mut sums: Vec<Sums> = (0..threads)
            .map(|_| Sums::new(n_state, &outs))
            .collect::<Result<_>>()?;
        for t0 in (0..total).step_by(block) {
            let t1 = (t0 + block).min(total);
            let (len, rows) = (t1 - t0, (t1 - t0) * l);
            let clock = Instant::now();
            frames.fill(self.coef, self.record, self.states, self.hold, (t0, t1))?;
            times.discretisation += clock.elapsed().as_secs_f64();
            let clock = Instant::now();
            let mut rest =
                MatMut::from_row_major_slice_mut(&mut jac[..rows * n_state], rows, n_state);
            let mut parts = Vec::with_capacity(slices.len());
            for s in &slices {
                let (head, tail) = rest.split_at_col_mut(s.width);
                parts.push(head);
                rest = tail;
            }
            let frames_ref = &frames;
            rayon::scope(|scope| {
                for (slice, part) in slices.iter_mut().zip(parts) {
                    scope.spawn(move |_| slice.advance(self, frames_ref, (t0, t1), part));
                }
                for (j, (cols, values)) in outs.cols.iter().zip(outs.values.iter_mut()).enumerate()
                {
                    if !cols.is_empty() {
                        let out = &mut values[..len * cols.len()];
                        scope.spawn(move |_| {
                            output_values(self, frames_ref, (t0, t1), j, cols, out)
                        });
                    }
                }
            });
            times.sensitivities += clock.elapsed().as_secs_f64();
            if t1 <= self.skip {
                continue;
            }
            let clock = Instant::now();
            for (k, v) in rr[..rows].iter_mut().enumerate() {
                let t = t0 + k / l;
                *v = if t < self.skip {
                    0.0
                } else {
                    self.residual[t0 * l + k]
                };
            }
            // Each thread sums the products of its share of the samples.
            let parts = sums.len();
            let (jac_ref, rr_ref, outs_ref) = (&jac, &rr, &outs);
            rayon::scope(|scope| {
                for (p, acc) in sums.iter_mut().enumerate() {
                    let span = (p * len / parts, (p + 1) * len / parts);
                    scope.spawn(move |_| acc.add(jac_ref, rr_ref, outs_ref, l, span));
                }
            });
            times.gram += clock.elapsed().as_secs_f64();
        }
        Sums::total(&mut sums).assemble(&outs, kcols)
    }
}
