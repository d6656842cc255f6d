//! Time-domain simulation of an LPV model along a scheduling trajectory.
//!
//! Discrete time, with `X(p) = X(0) + sum_i psi_i(p) X(i)`:
//!
//! ```text
//! x(t+1) = A(p(t)) x(t) + B(p(t)) u(t)
//! y(t)   = C(p(t)) x(t) + D(p(t)) u(t)
//! ```
//!
//! Only the state recursion is sequential: the input term `B(p(t)) u(t)`
//! and the outputs do not feed back. Two paths compute the same thing:
//!
//! - models with `n + l <= 32` (the common case): state and output
//!   equations in one, `[x(t+1); y(t)] = S(t) [x(t); u(t)]` with
//!   `S(t) = sum_i psi_i(t) [[A(i), B(i)], [C(i), D(i)]]`, in register-sized
//!   blocks, with AVX2 and FMA where the CPU has them (chosen at run time).
//!   Forming `S(t)` does not depend on the state, so the processor works on
//!   it ahead; only the product with the state is on the sequential path.
//! - larger models: with `k(v) = [v; psi_1 v; ...; psi_Nb v]` every product
//!   is one matrix times a vector, `A(p) x = [A(0) ... A(Nb)] k(x)`; the
//!   input term and the outputs are computed in bulk, in parallel over
//!   blocks of samples, and the recursion runs in order in between.
//!
//! Continuous time (`dx/dt = A(p) x + B(p) u`) is simulated with a
//! zero-order hold of both `u` and `p` over each sample of length `dt`: the
//! exact solution for piecewise-constant input and scheduling,
//! `x(t+1) = Ad x(t) + Bd u(t)` with
//! `[[Ad, Bd], [0, I]] = exp([[A, B], [0, 0]] dt)` and `A`, `B` frozen at
//! `p(t)`; `y(t) = C(p(t)) x(t) + D(p(t)) u(t)`. At a constant `p` this is
//! the usual ZOH discretisation of the frozen model.

// Small matrix kernels index several arrays at once; an index reads best.
#![allow(clippy::needless_range_loop)]

use crate::error::{invalid, Error, Result};
use crate::layout::{Matrix, Shape};
use rayon::prelude::*;

/// Samples per task of the bulk (parallel) parts.
const BLOCK: usize = 4096;

/// Samples per task when the continuous-time discretisation is computed.
const ZOH_BLOCK: usize = 256;

/// A simulated trajectory.
#[derive(Debug, Clone, PartialEq)]
pub struct Trajectory {
    /// Outputs `y(0..T)`, `T x l` row-major.
    pub y: Vec<f64>,
    /// States `x(0..=T)`, `(T + 1) x n` row-major, when asked for; the last
    /// row is the state after the last sample (to continue a simulation).
    pub x: Option<Vec<f64>>,
}

/// The coefficient matrices of one state-space matrix side by side,
/// `[X(0) X(1) ... X(Nb)]`, row-major.
#[derive(Debug, Clone)]
struct Wide {
    width: usize,
    data: Vec<f64>,
}

impl Wide {
    fn new(shape: &Shape, theta: &[f64], x: Matrix) -> Wide {
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
fn dot(a: &[f64], b: &[f64]) -> f64 {
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

/// Whether every value is finite, without an early exit per value (so that
/// the check vectorises: it runs over every sample of a long trajectory).
fn all_finite(v: &[f64]) -> bool {
    v.chunks(64)
        .all(|c| c.iter().fold(true, |ok, a| ok & a.is_finite()))
}

/// Check the sizes of a simulation's arguments and that `theta` and `x0`
/// are finite; returns the number of samples `T`.
fn check_sizes(
    shape: &Shape,
    theta: &[f64],
    basis: &[f64],
    u: &[f64],
    x0: &[f64],
) -> Result<usize> {
    shape.check_theta(theta)?;
    let (n, r, nb) = (shape.n, shape.r, shape.nb);
    if u.len() % r != 0 {
        return Err(invalid(
            "u",
            format!("expected T x {r} input values, got {}", u.len()),
        ));
    }
    let t = u.len() / r;
    if basis.len() != t * nb {
        return Err(invalid(
            "psi",
            format!(
                "expected {} basis values ({t} samples x {nb} functions), got {}",
                t * nb,
                basis.len()
            ),
        ));
    }
    if x0.len() != n {
        return Err(invalid(
            "x0",
            format!("expected {n} initial states, got {}", x0.len()),
        ));
    }
    if !all_finite(x0) {
        return Err(invalid("x0", "contains NaN or Inf"));
    }
    Ok(t)
}

/// Check that the basis values and inputs are finite.
fn check_values(basis: &[f64], u: &[f64]) -> Result<()> {
    for (name, v) in [("psi", basis), ("u", u)] {
        if !all_finite(v) {
            return Err(invalid(name, "contains NaN or Inf"));
        }
    }
    Ok(())
}

/// Simulate a discrete-time LPV model.
///
/// `basis` holds the `T x Nb` values `psi_1..psi_Nb` at `p(0..T)`
/// (row-major), `u` the `T x r` inputs (row-major) and `x0` the initial
/// state; with `states` the trajectory keeps `x(0..=T)`. Unstable models
/// give non-finite values, not an error.
pub fn simulate(
    shape: &Shape,
    theta: &[f64],
    basis: &[f64],
    u: &[f64],
    x0: &[f64],
    states: bool,
) -> Result<Trajectory> {
    check_sizes(shape, theta, basis, u, x0)?;
    // Monomorphised kernels: K = ceil((n + l) / 4) register blocks and,
    // for K <= 4, the number of basis functions (small models are the
    // common case; the rest runs with Nb known at run time).
    let traj = match (shape.n + shape.l).div_ceil(4) {
        1 => lanes_by_nb::<1>(shape, theta, basis, u, x0, states),
        2 => lanes_by_nb::<2>(shape, theta, basis, u, x0, states),
        3 => lanes_by_nb::<3>(shape, theta, basis, u, x0, states),
        4 => lanes_by_nb::<4>(shape, theta, basis, u, x0, states),
        5 => Lanes::<5>::new(shape, theta).simulate::<DYN>(basis, u, x0, states),
        6 => Lanes::<6>::new(shape, theta).simulate::<DYN>(basis, u, x0, states),
        7 => Lanes::<7>::new(shape, theta).simulate::<DYN>(basis, u, x0, states),
        8 => Lanes::<8>::new(shape, theta).simulate::<DYN>(basis, u, x0, states),
        _ => {
            let (y, x) = simulate_wide(shape, theta, basis, u, x0);
            Trajectory {
                y,
                x: states.then_some(x),
            }
        }
    };
    // Every output y(t) is a sum of products that involve every psi_i(t),
    // every u(t) and (through the state) every earlier value, and a NaN or
    // Inf factor makes such a sum NaN (0 * Inf = NaN). So finite outputs
    // prove finite inputs, and the inputs are only scanned (to name the bad
    // one) when an output is not finite, which an unstable model may also
    // cause.
    if !all_finite(&traj.y) {
        check_values(basis, u)?;
    }
    Ok(traj)
}

/// Four doubles side by side: one AVX register's worth.
type V4 = [f64; 4];

/// `acc += s v`, lane by lane, with fused multiply-adds when `FUSED` (only
/// where the CPU has them: elsewhere `mul_add` is a slow library call).
#[inline(always)]
fn axpy4<const FUSED: bool>(acc: &mut V4, s: f64, v: &V4) {
    for k in 0..4 {
        acc[k] = if FUSED {
            s.mul_add(v[k], acc[k])
        } else {
            acc[k] + s * v[k]
        };
    }
}

/// A number of basis functions known only at run time.
const DYN: usize = usize::MAX;

/// The fast path with the number of basis functions fixed at compile time
/// when it is at most 4.
fn lanes_by_nb<const K: usize>(
    shape: &Shape,
    theta: &[f64],
    basis: &[f64],
    u: &[f64],
    x0: &[f64],
    states: bool,
) -> Trajectory {
    let lanes = Lanes::<K>::new(shape, theta);
    match shape.nb {
        0 => lanes.simulate::<0>(basis, u, x0, states),
        1 => lanes.simulate::<1>(basis, u, x0, states),
        2 => lanes.simulate::<2>(basis, u, x0, states),
        3 => lanes.simulate::<3>(basis, u, x0, states),
        4 => lanes.simulate::<4>(basis, u, x0, states),
        _ => lanes.simulate::<DYN>(basis, u, x0, states),
    }
}

/// The fast path for `n + l <= 32`. State and output equations together:
/// with `w(t) = [x(t); u(t)]` and the `(n + l) x (n + r)` blocks
/// `S(i) = [[A(i), B(i)], [C(i), D(i)]]`,
///
/// ```text
/// [x(t+1); y(t)] = S(t) w(t),   S(t) = sum_i psi_i(t) S(i),
/// ```
///
/// column by column: column `b` of `S(t)` does not depend on the state, so
/// the processor forms it ahead while the previous step finishes, and
/// only `z += w_b S(t)[:, b]` lies on the sequential path. Columns are
/// padded to `4 K` rows so that every operation works on whole registers
/// and the accumulators stay in registers.
struct Lanes<const K: usize> {
    n: usize,
    r: usize,
    l: usize,
    nb: usize,
    /// Column `b` of `S(i)` at index `b (Nb + 1) + i`.
    cols: Vec<[V4; K]>,
}

impl<const K: usize> Lanes<K> {
    fn new(shape: &Shape, theta: &[f64]) -> Self {
        let (n, r) = (shape.n, shape.r);
        let m = shape.n_coef();
        let mut cols = vec![[[0.0; 4]; K]; (n + r) * m];
        for i in 0..m {
            for (x, row0, col0) in [
                (Matrix::A, 0, 0),
                (Matrix::B, 0, n),
                (Matrix::C, n, 0),
                (Matrix::D, n, n),
            ] {
                let (rows, ncols) = shape.dims(x);
                let block = &theta[shape.block(x, i)];
                for col in 0..ncols {
                    for row in 0..rows {
                        let at = row0 + row;
                        cols[(col0 + col) * m + i][at / 4][at % 4] = block[row + col * rows];
                    }
                }
            }
        }
        Lanes {
            n,
            r,
            l: shape.l,
            nb: shape.nb,
            cols,
        }
    }

    /// Run with AVX2 and FMA when the CPU has them (checked at run time);
    /// `NB` is the number of basis functions or [`DYN`].
    fn simulate<const NB: usize>(
        &self,
        basis: &[f64],
        u: &[f64],
        x0: &[f64],
        states: bool,
    ) -> Trajectory {
        let t_len = u.len() / self.r;
        let mut traj = Trajectory {
            y: vec![0.0; t_len * self.l],
            x: states.then(|| vec![0.0; (t_len + 1) * self.n]),
        };
        let mut run = Run::<K, NB> {
            lanes: self,
            basis,
            u,
            x0,
            y: &mut traj.y,
            xs: traj.x.as_deref_mut(),
        };
        #[cfg(target_arch = "x86_64")]
        if let Some(simd) = pulp::x86::V3::try_new() {
            pulp::Simd::vectorize(simd, run);
            return traj;
        }
        run.recursion::<false>();
        traj
    }

    /// The portable kernel even where AVX2 is available (for tests).
    #[cfg(test)]
    fn simulate_portable<const NB: usize>(&self, basis: &[f64], u: &[f64], x0: &[f64]) -> Vec<f64> {
        let mut y = vec![0.0; u.len() / self.r * self.l];
        Run::<K, NB> {
            lanes: self,
            basis,
            u,
            x0,
            y: &mut y,
            xs: None,
        }
        .recursion::<false>();
        y
    }
}

/// One simulation on the fast path, as an operation that `pulp` compiles
/// for the instruction set found at run time.
struct Run<'a, const K: usize, const NB: usize> {
    lanes: &'a Lanes<K>,
    basis: &'a [f64],
    u: &'a [f64],
    x0: &'a [f64],
    y: &'a mut [f64],
    xs: Option<&'a mut [f64]>,
}

impl<const K: usize, const NB: usize> pulp::WithSimd for Run<'_, K, NB> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(mut self, _simd: S) {
        // Only reached through an instruction set with FMA.
        self.recursion::<true>();
    }
}

impl<const K: usize, const NB: usize> Run<'_, K, NB> {
    #[inline(always)]
    fn recursion<const FUSED: bool>(&mut self) {
        let lanes = self.lanes;
        let (n, r, l) = (lanes.n, lanes.r, lanes.l);
        let nb = if NB == DYN { lanes.nb } else { NB };
        let m = nb + 1;
        let width = n + r;
        let mut w = vec![0.0; width];
        w[..n].copy_from_slice(self.x0);
        if let Some(xs) = self.xs.as_deref_mut() {
            xs[..n].copy_from_slice(self.x0);
        }
        for (t, (yt, ut)) in self
            .y
            .chunks_exact_mut(l)
            .zip(self.u.chunks_exact(r))
            .enumerate()
        {
            let psi = &self.basis[t * nb..(t + 1) * nb];
            for (v, &x) in w[n..].iter_mut().zip(ut) {
                *v = x;
            }
            // Column b of S(t), formed from the coefficients.
            let column = |col: &[[V4; K]]| {
                let mut s = col[0];
                for (c, &weight) in col[1..].iter().zip(psi) {
                    for k in 0..K {
                        axpy4::<FUSED>(&mut s[k], weight, &c[k]);
                    }
                }
                s
            };
            // z = S(t) w, columns in pairs into two accumulators (half the
            // sequential chain, both kept in registers).
            let mut even = [[0.0; 4]; K];
            let mut odd = [[0.0; 4]; K];
            let pairs = lanes.cols.chunks_exact(2 * m);
            let last = pairs.remainder();
            for (cols, wb) in pairs.zip(w.chunks_exact(2)) {
                let (s0, s1) = (column(&cols[..m]), column(&cols[m..]));
                for k in 0..K {
                    axpy4::<FUSED>(&mut even[k], wb[0], &s0[k]);
                    axpy4::<FUSED>(&mut odd[k], wb[1], &s1[k]);
                }
            }
            if !last.is_empty() {
                let s0 = column(last);
                for k in 0..K {
                    axpy4::<FUSED>(&mut even[k], w[width - 1], &s0[k]);
                }
            }
            for k in 0..K {
                for j in 0..4 {
                    even[k][j] += odd[k][j];
                }
            }
            for (a, v) in w[..n].iter_mut().enumerate() {
                *v = even[a / 4][a % 4];
            }
            for (j, v) in yt.iter_mut().enumerate() {
                *v = even[(n + j) / 4][(n + j) % 4];
            }
            if let Some(xs) = self.xs.as_deref_mut() {
                xs[(t + 1) * n..(t + 2) * n].copy_from_slice(&w[..n]);
            }
        }
    }
}

/// The general path (any size): input term and outputs in bulk, in
/// parallel over blocks of samples; the state recursion in order.
fn simulate_wide(
    shape: &Shape,
    theta: &[f64],
    basis: &[f64],
    u: &[f64],
    x0: &[f64],
) -> (Vec<f64>, Vec<f64>) {
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
    let y = outputs(shape, theta, basis, u, &x);
    (y, x)
}

/// `y(t) = C(p(t)) x(t) + D(p(t)) u(t)` for every sample, in bulk.
fn outputs(shape: &Shape, theta: &[f64], basis: &[f64], u: &[f64], x: &[f64]) -> Vec<f64> {
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

/// Simulate a continuous-time LPV model with a zero-order hold of `u` and
/// `p` over samples of `dt` seconds (see the module documentation).
/// Other arguments as for [`simulate`].
pub fn simulate_zoh(
    shape: &Shape,
    theta: &[f64],
    basis: &[f64],
    u: &[f64],
    x0: &[f64],
    dt: f64,
    states: bool,
) -> Result<Trajectory> {
    let t_len = check_sizes(shape, theta, basis, u, x0)?;
    check_values(basis, u)?;
    if !(dt.is_finite() && dt > 0.0) {
        return Err(invalid(
            "dt",
            format!("expected a finite sample time > 0, got {dt}"),
        ));
    }
    let (n, r, nb) = (shape.n, shape.r, shape.nb);
    let nn = n * n;
    let mut x = vec![0.0; (t_len + 1) * n];
    x[..n].copy_from_slice(x0);
    let mut ad = vec![0.0; BLOCK * nn];
    for start in (0..t_len).step_by(BLOCK) {
        let end = (start + BLOCK).min(t_len);
        // Ad(t) into `ad`, x(t+1) <- Bd(t) u(t), in parallel.
        ad[..(end - start) * nn]
            .par_chunks_mut(ZOH_BLOCK * nn)
            .zip(x[(start + 1) * n..(end + 1) * n].par_chunks_mut(ZOH_BLOCK * n))
            .enumerate()
            .try_for_each(|(k, (ads, nexts))| {
                let mut hold = Hold::new(shape, theta, dt);
                for (s, (adt, next)) in ads
                    .chunks_exact_mut(nn)
                    .zip(nexts.chunks_exact_mut(n))
                    .enumerate()
                {
                    let t = start + k * ZOH_BLOCK + s;
                    hold.at(&basis[t * nb..(t + 1) * nb]).map_err(|e| {
                        Error::Numerical(format!("{e} (zero-order hold at sample {t})"))
                    })?;
                    adt.copy_from_slice(&hold.ad);
                    let ut = &u[t * r..(t + 1) * r];
                    for (a, v) in next.iter_mut().enumerate() {
                        *v = dot(&hold.bd[a * r..(a + 1) * r], ut);
                    }
                }
                Ok(())
            })?;
        // x(t+1) += Ad(t) x(t), in order.
        for t in start..end {
            let (past, next) = x.split_at_mut((t + 1) * n);
            let xt = &past[t * n..];
            let adt = &ad[(t - start) * nn..(t - start + 1) * nn];
            for (v, row) in next[..n].iter_mut().zip(adt.chunks_exact(n)) {
                *v += dot(row, xt);
            }
        }
    }
    let y = outputs(shape, theta, basis, u, &x);
    Ok(Trajectory {
        y,
        x: states.then_some(x),
    })
}

/// The zero-order-hold discretisation of the frozen model, with a cache
/// for runs of equal scheduling values.
struct Hold {
    n: usize,
    r: usize,
    dt: f64,
    a: Wide,
    b: Wide,
    last: Option<Vec<f64>>,
    kron: Vec<f64>,
    m: Vec<f64>,
    e: Vec<f64>,
    expm: Expm,
    /// `Ad`, `n x n` row-major.
    ad: Vec<f64>,
    /// `Bd`, `n x r` row-major.
    bd: Vec<f64>,
}

impl Hold {
    fn new(shape: &Shape, theta: &[f64], dt: f64) -> Hold {
        let (n, r) = (shape.n, shape.r);
        let s = n + r;
        Hold {
            n,
            r,
            dt,
            a: Wide::new(shape, theta, Matrix::A),
            b: Wide::new(shape, theta, Matrix::B),
            last: None,
            kron: vec![0.0; shape.n_coef()],
            m: vec![0.0; s * s],
            e: vec![0.0; s * s],
            expm: Expm::new(s),
            ad: vec![0.0; n * n],
            bd: vec![0.0; n * r],
        }
    }

    /// Discretise at the basis values `psi` (unless they equal the last ones).
    fn at(&mut self, psi: &[f64]) -> Result<()> {
        if self.last.as_deref() == Some(psi) {
            return Ok(());
        }
        let (n, r) = (self.n, self.r);
        let s = n + r;
        // [1, psi]: the weights of X(0..=Nb).
        self.kron[0] = 1.0;
        self.kron[1..].copy_from_slice(psi);
        self.m.fill(0.0);
        for (wide, cols, offset) in [(&self.a, n, 0), (&self.b, r, n)] {
            for row in 0..n {
                let coefs = &wide.data[row * wide.width..(row + 1) * wide.width];
                for (i, &w) in self.kron.iter().enumerate() {
                    for col in 0..cols {
                        self.m[row * s + offset + col] += w * coefs[i * cols + col] * self.dt;
                    }
                }
            }
        }
        self.expm.compute(&self.m, &mut self.e)?;
        for row in 0..n {
            self.ad[row * n..(row + 1) * n].copy_from_slice(&self.e[row * s..row * s + n]);
            self.bd[row * r..(row + 1) * r].copy_from_slice(&self.e[row * s + n..(row + 1) * s]);
        }
        self.last = Some(psi.to_vec());
        Ok(())
    }
}

/// Coefficients of the diagonal [6/6] Padé approximant of `exp`.
const PADE6: [f64; 7] = [
    1.0,
    1.0 / 2.0,
    5.0 / 44.0,
    1.0 / 66.0,
    1.0 / 792.0,
    1.0 / 15840.0,
    1.0 / 665280.0,
];

/// The matrix exponential of small dense matrices (row-major) by scaling
/// and squaring with the [6/6] Padé approximant: the matrix is scaled by
/// `2^-j` until its 1-norm is at most 1/2, where the approximant's backward
/// error is below the unit round-off (Higham, 2005).
#[derive(Debug, Clone)]
pub struct Expm {
    s: usize,
    x: Vec<f64>,
    x2: Vec<f64>,
    x4: Vec<f64>,
    x6: Vec<f64>,
    t: Vec<f64>,
    num: Vec<f64>,
    den: Vec<f64>,
}

impl Expm {
    /// Workspace for `s x s` matrices.
    pub fn new(s: usize) -> Expm {
        let z = vec![0.0; s * s];
        Expm {
            s,
            x: z.clone(),
            x2: z.clone(),
            x4: z.clone(),
            x6: z.clone(),
            t: z.clone(),
            num: z.clone(),
            den: z,
        }
    }

    /// `out = exp(m)`; fails ([`Error::Numerical`]) only when `m` is not
    /// finite or the Padé denominator is singular (which the scaling rules
    /// out for finite `m`).
    pub fn compute(&mut self, m: &[f64], out: &mut [f64]) -> Result<()> {
        let s = self.s;
        let norm = (0..s)
            .map(|j| (0..s).map(|i| m[i * s + j].abs()).sum::<f64>())
            .fold(0.0, f64::max);
        if !norm.is_finite() {
            return Err(Error::Numerical(
                "matrix exponential of a non-finite matrix".into(),
            ));
        }
        let squarings = if norm > 0.5 {
            (norm / 0.5).log2().ceil() as i32
        } else {
            0
        };
        let scale = 0.5f64.powi(squarings);
        for (x, &v) in self.x.iter_mut().zip(m) {
            *x = v * scale;
        }
        matmul(s, &self.x, &self.x, &mut self.x2);
        matmul(s, &self.x2, &self.x2, &mut self.x4);
        matmul(s, &self.x4, &self.x2, &mut self.x6);
        // U = X (c1 I + c3 X2 + c5 X4), V = c0 I + c2 X2 + c4 X4 + c6 X6.
        let c = PADE6;
        for k in 0..s * s {
            self.t[k] = c[3] * self.x2[k] + c[5] * self.x4[k];
            self.den[k] = c[2] * self.x2[k] + c[4] * self.x4[k] + c[6] * self.x6[k];
        }
        for i in 0..s {
            self.t[i * s + i] += c[1];
            self.den[i * s + i] += c[0];
        }
        matmul(s, &self.x, &self.t, &mut self.num);
        // num = V + U, den = V - U.
        for k in 0..s * s {
            let (u, v) = (self.num[k], self.den[k]);
            self.num[k] = v + u;
            self.den[k] = v - u;
        }
        if !solve_in_place(s, &mut self.den, &mut self.num) {
            return Err(Error::Numerical(
                "singular Pade denominator in the matrix exponential".into(),
            ));
        }
        for _ in 0..squarings {
            matmul(s, &self.num, &self.num, &mut self.t);
            std::mem::swap(&mut self.num, &mut self.t);
        }
        out.copy_from_slice(&self.num);
        Ok(())
    }
}

/// `out = a b` for `s x s` row-major matrices.
fn matmul(s: usize, a: &[f64], b: &[f64], out: &mut [f64]) {
    out.fill(0.0);
    for i in 0..s {
        let row = &mut out[i * s..(i + 1) * s];
        for k in 0..s {
            let aik = a[i * s + k];
            for (o, &bkj) in row.iter_mut().zip(&b[k * s..(k + 1) * s]) {
                *o += aik * bkj;
            }
        }
    }
}

/// Solve `a X = b` for `s x s` row-major `a` and `b` by LU with partial
/// pivoting; `a` is overwritten, `b` becomes `X`. False when `a` is
/// singular.
fn solve_in_place(s: usize, a: &mut [f64], b: &mut [f64]) -> bool {
    for k in 0..s {
        let p = (k..s)
            .max_by(|&i, &j| a[i * s + k].abs().total_cmp(&a[j * s + k].abs()))
            .unwrap_or(k);
        let pivot = a[p * s + k];
        if !(pivot.abs() > 0.0 && pivot.is_finite()) {
            return false;
        }
        if p != k {
            for j in 0..s {
                a.swap(k * s + j, p * s + j);
                b.swap(k * s + j, p * s + j);
            }
        }
        for i in k + 1..s {
            let f = a[i * s + k] / pivot;
            if f != 0.0 {
                for j in k..s {
                    a[i * s + j] -= f * a[k * s + j];
                }
                for j in 0..s {
                    b[i * s + j] -= f * b[k * s + j];
                }
            }
        }
    }
    for k in (0..s).rev() {
        let pivot = a[k * s + k];
        for j in 0..s {
            let mut v = b[k * s + j];
            for i in k + 1..s {
                v -= a[k * s + i] * b[i * s + j];
            }
            b[k * s + j] = v / pivot;
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lti::Frozen;
    use crate::testing::Lcg;

    fn model(n: usize, r: usize, l: usize, nb: usize, a0: f64) -> (Shape, Vec<f64>) {
        let shape = Shape::new(n, r, l, nb).unwrap();
        let mut rng = Lcg(3 + n as u64);
        let mut theta: Vec<f64> = (0..shape.len()).map(|_| 0.4 * rng.next_f64()).collect();
        let blk = shape.block(Matrix::A, 0);
        for k in 0..n {
            theta[blk.start + k * (n + 1)] += a0;
        }
        (shape, theta)
    }

    /// The recursion written out with the frozen matrices at every sample:
    /// `(y, x(0..=T))`.
    fn naive(
        shape: &Shape,
        theta: &[f64],
        basis: &[f64],
        u: &[f64],
        x0: &[f64],
    ) -> (Vec<f64>, Vec<f64>) {
        let (n, r, l, nb) = (shape.n, shape.r, shape.l, shape.nb);
        let t_len = u.len() / r;
        let mut x = x0.to_vec();
        let mut xs = x0.to_vec();
        let mut y = Vec::new();
        for t in 0..t_len {
            let mut psi = vec![1.0];
            psi.extend_from_slice(&basis[t * nb..(t + 1) * nb]);
            let m = Frozen::at(shape, theta, &psi);
            let ut = &u[t * r..(t + 1) * r];
            for j in 0..l {
                let cx: f64 = (0..n).map(|a| m.c[j + a * l] * x[a]).sum();
                let du: f64 = (0..r).map(|c| m.d[j + c * l] * ut[c]).sum();
                y.push(cx + du);
            }
            x = (0..n)
                .map(|a| {
                    (0..n).map(|b| m.a[a + b * n] * x[b]).sum::<f64>()
                        + (0..r).map(|c| m.b[a + c * n] * ut[c]).sum::<f64>()
                })
                .collect();
            xs.extend_from_slice(&x);
        }
        (y, xs)
    }

    fn assert_close(a: &[f64], b: &[f64], scale: f64) {
        assert_eq!(a.len(), b.len());
        for (p, q) in a.iter().zip(b) {
            assert!((p - q).abs() <= 1e-12 * scale, "{p} vs {q}");
        }
    }

    #[test]
    fn recursion_matches_the_frozen_matrices_sample_by_sample() {
        // Sizes on the lane path (n, l <= 16), with padding (n = 3, 6, 13)
        // and without (n = 4, 16), and on the general path (n or l > 16),
        // which also runs over several blocks.
        for (n, r, l, nb, t_len) in [
            (1, 1, 1, 0, 7),
            (3, 2, 2, 2, 300),
            (4, 3, 5, 1, 40),
            (6, 1, 2, 4, 50),
            (13, 2, 9, 3, 30),
            (16, 1, 16, 2, 30),
            (17, 2, 3, 2, 9000),
            (2, 1, 18, 1, 20),
            (3, 1, 2, 6, 50),
            (20, 2, 14, 1, 5000),
        ] {
            let (shape, theta) = model(n, r, l, nb, 0.5 / (1.0 + n as f64 / 8.0));
            let mut rng = Lcg(99);
            let basis: Vec<f64> = (0..t_len * nb).map(|_| rng.next_f64()).collect();
            let u: Vec<f64> = (0..t_len * r).map(|_| rng.next_f64()).collect();
            let x0: Vec<f64> = (0..n).map(|_| rng.next_f64()).collect();
            let (y, x) = naive(&shape, &theta, &basis, &u, &x0);
            let scale = y.iter().fold(1.0f64, |m, v| m.max(v.abs()));
            let with = simulate(&shape, &theta, &basis, &u, &x0, true).unwrap();
            assert_close(&with.y, &y, scale);
            assert_close(with.x.as_deref().unwrap(), &x, scale);
            let without = simulate(&shape, &theta, &basis, &u, &x0, false).unwrap();
            assert_eq!(without.y, with.y);
            assert!(without.x.is_none());
        }
    }

    #[test]
    fn portable_kernel_matches_too() {
        let (shape, theta) = model(6, 1, 2, 4, 0.5);
        let t_len = 200;
        let mut rng = Lcg(5);
        let basis: Vec<f64> = (0..t_len * 4).map(|_| rng.next_f64()).collect();
        let u: Vec<f64> = (0..t_len).map(|_| rng.next_f64()).collect();
        let x0: Vec<f64> = (0..6).map(|_| rng.next_f64()).collect();
        let (y, _) = naive(&shape, &theta, &basis, &u, &x0);
        let scale = y.iter().fold(1.0f64, |m, v| m.max(v.abs()));
        let lanes = Lanes::<2>::new(&shape, &theta);
        assert_close(&lanes.simulate_portable::<4>(&basis, &u, &x0), &y, scale);
        assert_close(&lanes.simulate_portable::<DYN>(&basis, &u, &x0), &y, scale);
    }

    #[test]
    fn unstable_models_give_non_finite_values_but_nan_inputs_are_named() {
        let (shape, theta) = model(2, 1, 1, 1, 3.0);
        let t_len = 2000;
        let basis = vec![0.1; t_len];
        let u = vec![1.0; t_len];
        let traj = simulate(&shape, &theta, &basis, &u, &[0.0, 0.0], false).unwrap();
        assert!(!traj.y.iter().all(|v| v.is_finite()));
        let mut bad = basis.clone();
        bad[1234] = f64::INFINITY;
        let (shape, theta) = model(2, 1, 1, 1, 0.5);
        assert!(matches!(
            simulate(&shape, &theta, &bad, &u, &[0.0, 0.0], false),
            Err(Error::InvalidArgument { name: "psi", .. })
        ));
    }

    #[test]
    fn bad_sizes_and_values_are_named() {
        let (shape, theta) = model(2, 2, 1, 1, 0.5);
        let err = |basis: &[f64], u: &[f64], x0: &[f64]| match simulate(
            &shape, &theta, basis, u, x0, false,
        ) {
            Err(Error::InvalidArgument { name, .. }) => name,
            other => panic!("expected an error, got {other:?}"),
        };
        assert_eq!(err(&[0.0; 3], &[0.0; 5], &[0.0; 2]), "u");
        assert_eq!(err(&[0.0; 2], &[0.0; 6], &[0.0; 2]), "psi");
        assert_eq!(err(&[0.0; 3], &[0.0; 6], &[0.0; 3]), "x0");
        assert_eq!(err(&[0.0; 3], &[f64::NAN; 6], &[0.0; 2]), "u");
        assert!(matches!(
            simulate_zoh(&shape, &theta, &[0.0; 3], &[0.0; 6], &[0.0; 2], 0.0, false),
            Err(Error::InvalidArgument { name: "dt", .. })
        ));
    }

    #[test]
    fn expm_of_known_matrices() {
        // A rotation generator, scaled so that several squarings happen.
        let w = 7.3;
        let mut e = vec![0.0; 4];
        Expm::new(2).compute(&[0.0, w, -w, 0.0], &mut e).unwrap();
        let want = [w.cos(), w.sin(), -w.sin(), w.cos()];
        for (a, b) in e.iter().zip(want) {
            assert!((a - b).abs() < 1e-13, "{a} vs {b}");
        }
        // A Jordan block: exp(J) = e^lambda [[1, 1, 1/2], [0, 1, 1], [0, 0, 1]].
        let lam = -0.8;
        let j = [lam, 1.0, 0.0, 0.0, lam, 1.0, 0.0, 0.0, lam];
        let mut e = vec![0.0; 9];
        Expm::new(3).compute(&j, &mut e).unwrap();
        let el = lam.exp();
        let want = [el, el, el / 2.0, 0.0, el, el, 0.0, 0.0, el];
        for (a, b) in e.iter().zip(want) {
            assert!((a - b).abs() < 1e-15, "{a} vs {b}");
        }
    }

    #[test]
    fn zoh_of_a_first_order_system() {
        // dx/dt = a(p) x + b u with a(p) = -2 + p, b = 3; y = x.
        let shape = Shape::new(1, 1, 1, 1).unwrap();
        let theta = vec![-2.0, 1.0, 3.0, 0.0, 1.0, 0.0, 0.0, 0.0];
        let dt = 0.05;
        let basis = vec![0.0, 0.5, 0.5, -1.0];
        let u = vec![1.0, -2.0, 0.5, 4.0];
        let traj = simulate_zoh(&shape, &theta, &basis, &u, &[0.2], dt, true).unwrap();
        let xs = traj.x.unwrap();
        let mut x = 0.2;
        for t in 0..4 {
            let a = -2.0 + basis[t];
            assert!((traj.y[t] - x).abs() < 1e-14);
            x = (a * dt).exp() * x + ((a * dt).exp() - 1.0) / a * 3.0 * u[t];
            assert!((xs[t + 1] - x).abs() < 1e-14, "{} vs {x}", xs[t + 1]);
        }
    }
}
