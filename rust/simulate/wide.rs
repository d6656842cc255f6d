//! The general path (any size): with `k(v) = [v; psi_1 v; ...; psi_Nb v]`
//! every product is one matrix times a vector; the input term and the
//! outputs are computed in bulk, in parallel over blocks of samples, and
//! the state recursion runs in order in between.

// Small kernels index several arrays at once; an index reads best.
#![allow(clippy::needless_range_loop)]

use super::BLOCK;
use crate::base::layout::{Matrix, Shape};
use crate::eval::model::ModelAt;
use rayon::prelude::*;

/// The coefficient matrices of one state-space matrix side by side,
/// `[X(0) X(1) ... X(Nb)]`, row-major.
#[derive(Debug, Clone)]
pub(super) struct Wide {
    pub(super) width: usize,
    pub(super) data: Vec<f64>,
}

impl Wide {
    pub(super) fn new(shape: &Shape, theta: &[f64], x: Matrix) -> Wide {
        let (rows, cols) = shape.dims(x);
        let width = shape.n_coef() * cols;
        let mut data = vec![0.0; rows * width];
        for i in 0..shape.n_coef() {
            let block = &theta[shape.block(x, i)];
            for col in 0..cols {
                for row in 0..rows {
                    data[row * width + i * cols + col] = block[row + col * rows];
                }
            }
        }
        Wide { width, data }
    }

    /// `out += [X(0) ... X(Nb)] kron`.
    #[inline(always)]
    fn apply_add(&self, kron: &[f64], out: &mut [f64]) {
        for (o, row) in out.iter_mut().zip(self.data.chunks_exact(self.width)) {
            *o += dot(row, kron);
        }
    }
}

/// Dot product with four independent accumulators (so that it vectorises
/// and its latency is not one long chain).
#[inline(always)]
pub(super) fn dot(a: &[f64], b: &[f64]) -> f64 {
    let ca = a.chunks_exact(4);
    let cb = b.chunks_exact(4);
    let (ra, rb) = (ca.remainder(), cb.remainder());
    let mut acc = [0.0; 4];
    for (x, y) in ca.zip(cb) {
        for k in 0..4 {
            acc[k] += x[k] * y[k];
        }
    }
    let mut s = (acc[0] + acc[1]) + (acc[2] + acc[3]);
    for (x, y) in ra.iter().zip(rb) {
        s += x * y;
    }
    s
}

/// `out = [v; psi_1 v; ...; psi_Nb v]`.
#[inline(always)]
fn kron(psi: &[f64], v: &[f64], out: &mut [f64]) {
    let m = v.len();
    out[..m].copy_from_slice(v);
    for (chunk, &w) in out[m..].chunks_exact_mut(m).zip(psi) {
        for (o, &x) in chunk.iter_mut().zip(v) {
            *o = w * x;
        }
    }
}

/// The general path (any size): input term and outputs in bulk, in
/// parallel over blocks of samples; the state recursion in order.
pub(super) fn simulate_wide(model: &ModelAt<'_>, u: &[f64], x0: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let (shape, theta, basis) = (&model.shape, model.theta, model.basis);
    let (n, r, nb) = (shape.n, shape.r, shape.nb);
    let t_len = u.len() / r;
    let mut x = vec![0.0; (t_len + 1) * n];
    x[..n].copy_from_slice(x0);
    // x(t+1) <- B(p(t)) u(t), in bulk.
    let b = Wide::new(shape, theta, Matrix::B);
    x[n..]
        .par_chunks_mut(BLOCK * n)
        .enumerate()
        .for_each(|(k, chunk)| {
            let mut ku = vec![0.0; b.width];
            for (s, next) in chunk.chunks_exact_mut(n).enumerate() {
                let t = k * BLOCK + s;
                kron(
                    &basis[t * nb..(t + 1) * nb],
                    &u[t * r..(t + 1) * r],
                    &mut ku,
                );
                b.apply_add(&ku, next);
            }
        });
    // x(t+1) += A(p(t)) x(t), in order.
    let a = Wide::new(shape, theta, Matrix::A);
    let mut kx = vec![0.0; a.width];
    for t in 0..t_len {
        let (past, next) = x.split_at_mut((t + 1) * n);
        kron(&basis[t * nb..(t + 1) * nb], &past[t * n..], &mut kx);
        a.apply_add(&kx, &mut next[..n]);
    }
    let y = outputs(model, u, &x);
    (y, x)
}

/// `y(t) = C(p(t)) x(t) + D(p(t)) u(t)` for every sample, in bulk.
pub(super) fn outputs(model: &ModelAt<'_>, u: &[f64], x: &[f64]) -> Vec<f64> {
    let (shape, theta, basis) = (&model.shape, model.theta, model.basis);
    let (n, r, l, nb) = (shape.n, shape.r, shape.l, shape.nb);
    let t_len = u.len() / r;
    let c = Wide::new(shape, theta, Matrix::C);
    let d = Wide::new(shape, theta, Matrix::D);
    let mut y = vec![0.0; t_len * l];
    y.par_chunks_mut(BLOCK * l)
        .enumerate()
        .for_each(|(k, chunk)| {
            let mut kx = vec![0.0; c.width];
            let mut ku = vec![0.0; d.width];
            for (s, yt) in chunk.chunks_exact_mut(l).enumerate() {
                let t = k * BLOCK + s;
                let psi = &basis[t * nb..(t + 1) * nb];
                kron(psi, &x[t * n..(t + 1) * n], &mut kx);
                kron(psi, &u[t * r..(t + 1) * r], &mut ku);
                c.apply_add(&kx, yt);
                d.apply_add(&ku, yt);
            }
        });
    y
}
