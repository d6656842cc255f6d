//! Every scheduling point's Gram matrix as a factor of its rank, and the
//! Levenberg-Marquardt step through those factors.
//!
//! The Gauss-Newton matrix of FRF data is a sum over the points,
//! `J^T J = sum_q (psi_q psi_q^T) (x) H_q`, with `H_q` the Gram matrix of
//! the frozen LTI model's `(n + l)(n + r)` parameters at point `q`. The
//! frozen response does not see the `n^2` similarity transformations of the
//! state, so `H_q` has rank at most `n (l + r) + l r` (68 of 324 at n = 16
//! 2x2; measured: the 69th eigenvalue is 1e-16 of the largest, the 68th
//! 4e-9), and `J^T J = U U^T` with `U = [psi_q (x) L_q]`, `H_q = L_q L_q^T`:
//! 612 columns against 1620 parameters at n = 16, 2448 against 6480 at
//! n = 32 4x4. The gradient is `U c` too (`2 J_q^T r_q` lies in the range of
//! `H_q`). So the damped system `(U U^T + mu D) d = -U c / 2` is solved by
//! `d = D^-1 U y` with `(K + mu I) y = -c / 2`, `K = U^T D^-1 U`: a system
//! of the rank's size, whose blocks `K_qq' = L_q^T W_qq' L_q'` (`W_qq'`
//! diagonal) cost far less than the parameters' Cholesky factorisation (at
//! n = 32, 9.6e9 flops against 9.1e10), and no subtraction: the step is as
//! accurate as the dense solve (their difference is the conditioning of
//! the system, 1e-10 relative at `lambda = 1e-2` on n = 16).
//!
//! Each `L_q` comes from a pivoted Cholesky factorisation of `H_q` scaled
//! to a unit diagonal, stopped when every scaled pivot left is below
//! [`RANK_TOL`]: measured on n = 16 the last kept pivot is 2e-2 or more,
//! the first left out 6e-15 or less. Where a point's pivots do not fall so
//! clearly, more are kept: the factor is then wider, never wrong.
//!
//! Which way a step is solved is a property of the shape alone
//! ([`worth_it`]), never of the values: a fit takes the same route on
//! every machine.

use crate::base::dense::{cholesky_solve, factor_lower};
use crate::base::gram_product::{gram_product, scratch_len};
use crate::base::spread::{self, worth_spreading};
use crate::error::Result;
use crate::memory::{try_vec, try_zeros};
use faer::{Accum, Mat};

/// A pivot of the unit-diagonal `H_q` below this ends its factorisation.
pub const RANK_TOL: f64 = 1e-12;

/// Fewest free parameters for the factored step: below, the dense
/// factorisation is a few milliseconds and the models keep the bits they
/// have always had (the gantry, the 9 x 9 grid, n = 10).
pub const FEWEST_FREE: usize = 1000;

/// Whether the factored step costs at most half the dense one, by the
/// shape alone: `n_points` points of `lti` frozen parameters each, whose
/// Gram matrices have rank at most `bound`, and `n_free` free parameters.
pub fn worth_it(lti: usize, bound: usize, n_points: usize, n_free: usize) -> bool {
    if n_free < FEWEST_FREE {
        return false;
    }
    let factors = (n_points * lti) as f64 * (bound * bound) as f64 / 2.0;
    factors + solve_cost(lti, bound, n_points) <= half_dense(n_free)
}

/// Flops of the reduced matrix's blocks and its factorisation.
fn solve_cost(lti: usize, bound: usize, n_points: usize) -> f64 {
    let (lti, bound, points) = (lti as f64, bound as f64, n_points as f64);
    let rank = points * bound;
    points * (points + 1.0) / 2.0 * bound * bound * lti + rank * rank * rank / 3.0
}

/// Half the flops of the dense factorisation of `n` parameters.
fn half_dense(n: usize) -> f64 {
    let n = n as f64;
    0.5 * n * n * n / 3.0
}

/// One point's factor: `H_q = L L^T` (to the truncation) and `2 J_q^T r_q = L c`.
#[derive(Debug, Clone)]
struct PointFactor {
    /// `[1, psi_1(p_q), ...]`.
    psi: Vec<f64>,
    /// `L`, `lti x rank`, column-major.
    l: Vec<f64>,
    rank: usize,
    c: Vec<f64>,
}

/// The factors of every point, and where each free parameter sits.
#[derive(Debug, Clone)]
pub struct PointFactors {
    lti: usize,
    /// The shape's bound on every point's rank.
    bound: usize,
    /// Basis index and LTI index of every free parameter.
    map: Vec<(usize, usize)>,
    points: Vec<PointFactor>,
}

/// The pivoted Cholesky factor of the symmetric positive semi-definite
/// `h` (`lti x lti`, column-major) scaled to a unit diagonal, unscaled:
/// `h = L L^T` up to pivots below [`RANK_TOL`]. Returns `L`
/// (`lti x rank`, column-major), the pivots in order, and the rank.
pub fn pivoted_factor(h: &[f64], lti: usize) -> Result<(Vec<f64>, Vec<usize>, usize)> {
    let root: Vec<f64> = (0..lti).map(|p| h[p + p * lti].max(0.0).sqrt()).collect();
    let scale: Vec<f64> = root
        .iter()
        .map(|&s| if s > 0.0 { 1.0 / s } else { 0.0 })
        .collect();
    // Scaled pivots left: 1 for every parameter the point sees, else 0.
    let mut left: Vec<f64> = scale
        .iter()
        .map(|&s| if s > 0.0 { 1.0 } else { 0.0 })
        .collect();
    let mut l = Vec::new();
    let mut pivots = Vec::new();
    let mut col = vec![0.0; lti];
    for j in 0..lti {
        let (i, best) =
            left.iter()
                .enumerate()
                .fold((0, f64::NEG_INFINITY), |(bi, bv), (k, &v)| {
                    if v > bv {
                        (k, v)
                    } else {
                        (bi, bv)
                    }
                });
        if best <= RANK_TOL {
            break;
        }
        for p in 0..lti {
            col[p] = scale[p] * scale[i] * h[p + i * lti];
        }
        for k in 0..j {
            let lik = l[i + k * lti];
            if lik != 0.0 {
                let lk = &l[k * lti..(k + 1) * lti];
                col.iter_mut().zip(lk).for_each(|(c, &x)| *c -= x * lik);
            }
        }
        let d = best.sqrt();
        col.iter_mut().for_each(|c| *c /= d);
        col[i] = d;
        for &q in &pivots {
            col[q] = 0.0;
        }
        left.iter_mut().zip(&col).for_each(|(v, &c)| *v -= c * c);
        left[i] = 0.0;
        for &q in &pivots {
            left[q] = 0.0;
        }
        pivots.push(i);
        crate::memory::try_grow(&mut l, lti, "a point's Gram factor")?;
        l.extend_from_slice(&col);
    }
    // Unscaled: H = S^-1 (Ls Ls^T) S^-1 with S the scaling.
    for c in l.chunks_mut(lti.max(1)) {
        c.iter_mut().zip(&root).for_each(|(x, &s)| *x *= s);
    }
    let rank = pivots.len();
    Ok((l, pivots, rank))
}

impl PointFactors {
    /// The factors of every point from its Gram matrix `grams[q]`
    /// (`lti x lti`, column-major) and `jtr[q] = J_q^T r_q`, the points in
    /// parallel; `psi[q]` is `[1, psi_1(p_q), ...]` and `map` the basis
    /// and LTI index of every free parameter.
    pub fn new(
        grams: &[Vec<f64>],
        jtr: &[Vec<f64>],
        psi: Vec<Vec<f64>>,
        map: Vec<(usize, usize)>,
        lti: usize,
        bound: usize,
    ) -> Result<Self> {
        // a pivoted factorisation of lti^3 / 3 flops a point
        let work = grams.len() as f64 * (lti as f64).powi(3) / 3.0;
        let items: Vec<_> = grams.iter().zip(jtr).zip(psi).collect();
        let points = spread::map(
            items,
            worth_spreading(grams.len(), work),
            |((h, g), psi)| {
                let (l, pivots, rank) = pivoted_factor(h, lti)?;
                // L[pivots, :] is lower triangular in the pivots' order.
                let mut c = vec![0.0; rank];
                for (k, &p) in pivots.iter().enumerate() {
                    let mut s = 2.0 * g[p];
                    for (m, cm) in c.iter().enumerate().take(k) {
                        s -= l[p + m * lti] * cm;
                    }
                    c[k] = s / l[p + k * lti];
                }
                Ok(PointFactor { psi, l, rank, c })
            },
        )
        .into_iter()
        .collect::<Result<Vec<_>>>()?;
        Ok(PointFactors {
            lti,
            bound,
            map,
            points,
        })
    }

    /// The factors of two sums of points over the same free parameters as one.
    pub fn join(mut self, other: PointFactors) -> Option<PointFactors> {
        if self.lti != other.lti || self.bound != other.bound || self.map != other.map {
            return None;
        }
        self.points.extend(other.points);
        Some(self)
    }

    /// Whether a Newton system of `n` parameters is solved for at most half
    /// the dense price through the factors, by the shape alone.
    pub fn newton_worth_it(&self, n: usize) -> bool {
        solve_cost(self.lti, self.bound, self.points.len()) <= half_dense(n)
    }

    /// Columns of `U`: the sum of the points' ranks.
    pub fn rank(&self) -> usize {
        self.points.iter().map(|p| p.rank).sum()
    }

    /// Ranks of the points, in order.
    pub fn ranks(&self) -> Vec<usize> {
        self.points.iter().map(|p| p.rank).collect()
    }

    fn offsets(&self) -> Vec<usize> {
        let mut out = vec![0];
        for p in &self.points {
            out.push(out[out.len() - 1] + p.rank);
        }
        out
    }

    /// `U^T diag(w) U` (`rank x rank`, `w` over the free parameters): its
    /// blocks `L_q^T W_qq' L_q'`, the pairs of points in parallel, each on
    /// the core's Gram kernel (the same bits on any number of threads and
    /// any processor).
    pub fn weighted_gram(&self, weights: &[f64]) -> Result<Mat<f64>> {
        let (lti, n) = (self.lti, self.points.len());
        let offsets = self.offsets();
        let size = offsets[n];
        let pairs: Vec<(usize, usize)> = (0..n).flat_map(|q| (q..n).map(move |s| (q, s))).collect();
        // a block of rank_q x rank_s x lti multiply-adds a pair
        let work: f64 = pairs
            .iter()
            .map(|&(q, s)| 2.0 * (self.points[q].rank * self.points[s].rank * lti) as f64)
            .sum();
        let blocks = spread::map(
            pairs.clone(),
            worth_spreading(pairs.len(), work),
            |(q, s)| {
                let (a, b) = (&self.points[q], &self.points[s]);
                let mut w = vec![0.0; lti];
                for (&(i, p), &c) in self.map.iter().zip(weights) {
                    w[p] += a.psi[i] * b.psi[i] * c;
                }
                let mut wl = try_vec(b.l.len(), 0.0, "a block of the reduced Gram matrix")?;
                for (dst, src) in wl.chunks_mut(lti.max(1)).zip(b.l.chunks(lti.max(1))) {
                    dst.iter_mut()
                        .zip(src.iter().zip(&w))
                        .for_each(|(x, (&y, &z))| *x = y * z);
                }
                let mut block = try_zeros(a.rank, b.rank, "a block of the reduced Gram matrix")?;
                let mut scratch = try_vec(
                    scratch_len(b.rank, lti),
                    0.0,
                    "the scratch of the reduced Gram matrix",
                )?;
                gram_product(
                    block.as_mut(),
                    Accum::Add,
                    &a.l,
                    &wl,
                    lti,
                    lti,
                    &mut scratch,
                );
                Ok(block)
            },
        )
        .into_iter()
        .collect::<Result<Vec<_>>>()?;
        let mut k = try_zeros(size, size, "the reduced Gram matrix")?;
        for (&(q, s), block) in pairs.iter().zip(&blocks) {
            for jj in 0..block.ncols() {
                for ii in 0..block.nrows() {
                    let v = block[(ii, jj)];
                    k[(offsets[q] + ii, offsets[s] + jj)] = v;
                    k[(offsets[s] + jj, offsets[q] + ii)] = v;
                }
            }
        }
        Ok(k)
    }

    /// `U y` over the free parameters (`y` of length [`Self::rank`]).
    pub fn times(&self, y: &[f64]) -> Vec<f64> {
        let offsets = self.offsets();
        let z: Vec<Vec<f64>> = self
            .points
            .iter()
            .enumerate()
            .map(|(q, pt)| {
                let yq = &y[offsets[q]..offsets[q + 1]];
                let mut z = vec![0.0; self.lti];
                for (col, &yk) in pt.l.chunks(self.lti.max(1)).zip(yq) {
                    z.iter_mut().zip(col).for_each(|(a, &b)| *a += b * yk);
                }
                z
            })
            .collect();
        self.map
            .iter()
            .map(|&(i, p)| {
                self.points
                    .iter()
                    .zip(&z)
                    .fold(0.0, |acc, (pt, zq)| acc + pt.psi[i] * zq[p])
            })
            .collect()
    }

    /// `U^T v` (`v` over the free parameters).
    pub fn transpose_times(&self, v: &[f64]) -> Vec<f64> {
        let mut out = Vec::with_capacity(self.rank());
        for pt in &self.points {
            let mut agg = vec![0.0; self.lti];
            for (&(i, p), &x) in self.map.iter().zip(v) {
                agg[p] += pt.psi[i] * x;
            }
            out.extend(
                pt.l.chunks(self.lti.max(1))
                    .map(|col| col.iter().zip(&agg).map(|(a, b)| a * b).sum::<f64>()),
            );
        }
        out
    }

    /// The gradient's coefficients: `2 J^T r = U c`.
    pub fn gradient_coefficients(&self) -> Vec<f64> {
        self.points
            .iter()
            .flat_map(|p| p.c.iter().copied())
            .collect()
    }
}

/// The pieces of the factored step that do not change with the damping:
/// `K = U^T D^-1 U` and `-c / 2`. A rejected step's successor (another
/// `mu`) refactors `K + mu I` alone.
#[derive(Debug)]
pub struct FactoredSystem {
    k: Mat<f64>,
    rhs: Vec<f64>,
}

impl FactoredSystem {
    /// The reduced system of `factors` with the Marquardt diagonal `diag`.
    pub fn new(factors: &PointFactors, diag: &[f64]) -> Result<Self> {
        let inverse: Vec<f64> = diag.iter().map(|d| 1.0 / d).collect();
        let k = factors.weighted_gram(&inverse)?;
        let rhs = factors
            .gradient_coefficients()
            .iter()
            .map(|c| -0.5 * c)
            .collect();
        Ok(FactoredSystem { k, rhs })
    }

    /// The step `d` of `(U U^T + mu D) d = -U c / 2`; `None` when `K + mu I`
    /// is not numerically positive definite or the step is not finite.
    pub fn step(&self, factors: &PointFactors, diag: &[f64], mu: f64) -> Result<Option<Vec<f64>>> {
        let size = self.k.nrows();
        let mut a = try_zeros(
            size,
            size,
            "the factor of the reduced Levenberg-Marquardt step",
        )?;
        for j in 0..size {
            for i in j..size {
                a[(i, j)] = self.k[(i, j)] + if i == j { mu } else { 0.0 };
            }
        }
        if !factor_lower(a.as_mut())? {
            return Ok(None);
        }
        let mut y = Mat::from_fn(size, 1, |i, _| self.rhs[i]);
        cholesky_solve(a.as_ref(), y.as_mut());
        let y: Vec<f64> = (0..size).map(|i| y[(i, 0)]).collect();
        let d: Vec<f64> = factors
            .times(&y)
            .iter()
            .zip(diag)
            .map(|(u, d)| u / d)
            .collect();
        Ok(d.iter().all(|v| v.is_finite()).then_some(d))
    }
}

#[cfg(test)]
#[path = "point_factors_tests.rs"]
pub(crate) mod tests;
