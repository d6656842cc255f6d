//! The Newton systems of the cone step through every point's factor
//! ([`crate::eval::point_factors`]), where the Gauss-Newton pieces carry them.
//!
//! In the scaled variables of a round the quadratic is
//! `P = V V^T + Delta` over the open parameters, `V = sqrt(2/M) S U` and
//! `Delta = (2/M) S^2 mu D` diagonal (the parameters outside every group
//! are eliminated from the dense `P` by a Schur complement; here they stay
//! in, with no right-hand side: the grouped part of the solution is the
//! same). Newton's Hessian adds, per open group, `(c/s) diag(alpha^2)`
//! and `-(c/s) a a^T` (`a = alpha o z / s`). So it is `B + V V^T` with `B`
//! diagonal but for one rank-one term per group, inverted in closed form
//! (Sherman and Morrison, the groups disjoint), and
//!
//! ```text
//! H^-1 r = B^-1 r - B^-1 V C^-1 V^T B^-1 r,   C = I + V^T B^-1 V,
//! ```
//!
//! `C` of the rank's size (612 at n = 16 against up to 1296 grouped
//! parameters; 2448 against 5000 and more at n = 32), its blocks formed as
//! [`PointFactors::weighted_gram`] forms them. No subtraction loses
//! digits that the dense factorisation keeps: on a problem of n = 16 2x2
//! (`tests/core_factors.rs`) the cone steps agree with the dense solve's
//! to 1e-13 relative with `mu` from 1e-8 to 1e-2 (one sweep of iterative
//! refinement against the dense Hessian changed nothing there, and was
//! left out).

use super::group::NewtonGroup;
use crate::base::dense::{cholesky_solve, factor_lower};
use crate::error::Result;
use crate::eval::point_factors::PointFactors;
use faer::Mat;

/// The round's pieces of the factored Newton solve.
pub(super) struct FactoredHessian<'a> {
    factors: &'a PointFactors,
    /// Free index of every Newton variable (the grouped parameters, in the
    /// groups' order).
    grouped: &'a [usize],
    /// Free indices of the open parameters outside every group.
    others: &'a [usize],
    /// `sqrt(2/M) S_f` and `(2/M) S_f^2 mu D_f` of every free parameter.
    root: Vec<f64>,
    base: Vec<f64>,
}

/// One group's rank-one term: `B_g^-1 = Delta^-1 + kappa e e^T`, and
/// `y = V^T e`.
struct Term {
    start: usize,
    e: Vec<f64>,
    kappa: f64,
}

/// The factored solve at one Newton iterate.
pub(super) struct Prepared<'a, 'b> {
    hessian: &'b FactoredHessian<'a>,
    /// `Delta'` of every free parameter in the system, 0 outside it.
    diag: Vec<f64>,
    terms: Vec<Term>,
    /// The Cholesky factor of `C` (lower triangle).
    c: Mat<f64>,
}

impl<'a> FactoredHessian<'a> {
    /// The pieces of a round: `grouped` and `others` as the round orders
    /// them, `scale` the Jacobi scaling `S`, `diag` the Marquardt diagonal,
    /// `n_residuals` `M`.
    pub(super) fn new(
        factors: &'a PointFactors,
        grouped: &'a [usize],
        others: &'a [usize],
        scale: &[f64],
        diag: &[f64],
        mu: f64,
        n_residuals: f64,
    ) -> Self {
        let two = 2.0 / n_residuals;
        let root = scale.iter().map(|s| two.sqrt() * s).collect();
        let base = scale
            .iter()
            .zip(diag)
            .map(|(s, d)| two * s * s * mu * d)
            .collect();
        FactoredHessian {
            factors,
            grouped,
            others,
            root,
            base,
        }
    }

    /// The solve at the iterate `x` (Newton variables) with the groups'
    /// norms `norms` and those held at zero marked in `held`; `None` when
    /// `C` is not numerically positive definite or a group's term is
    /// not (the caller factors the dense Hessian then).
    pub(super) fn prepare<'b>(
        &'b self,
        groups: &[NewtonGroup],
        norms: &[f64],
        held: &[bool],
        x: &[f64],
    ) -> Result<Option<Prepared<'a, 'b>>> {
        let nf = self.root.len();
        let mut diag = vec![0.0; nf];
        for &f in self.others {
            diag[f] = self.base[f];
        }
        let mut terms = Vec::new();
        for ((g, &s), _) in groups.iter().zip(norms).zip(held).filter(|(_, &h)| !h) {
            let rho = g.weight / s;
            let mut a = Vec::with_capacity(g.alpha.len());
            for (k, (z, &alpha)) in g.z(x).zip(&g.alpha).enumerate() {
                let f = self.grouped[g.start + k];
                diag[f] = self.base[f] + rho * alpha * alpha;
                a.push(alpha * z / s);
            }
            let e: Vec<f64> = a
                .iter()
                .enumerate()
                .map(|(k, ak)| ak / diag[self.grouped[g.start + k]])
                .collect();
            let ae: f64 = a.iter().zip(&e).map(|(a, e)| a * e).sum();
            let denominator = 1.0 - rho * ae;
            if !(denominator > 0.0 && denominator.is_finite()) {
                return Ok(None);
            }
            terms.push(Term {
                start: g.start,
                e,
                kappa: rho / denominator,
            });
        }
        let weights: Vec<f64> = (0..nf)
            .map(|f| {
                if diag[f] > 0.0 {
                    self.root[f] * self.root[f] / diag[f]
                } else {
                    0.0
                }
            })
            .collect();
        let mut c = self.factors.weighted_gram(&weights)?;
        let size = c.nrows();
        for i in 0..size {
            c[(i, i)] += 1.0;
        }
        for t in &terms {
            let y = self.transpose_times(&self.spread(t.start, &t.e));
            for j in 0..size {
                let kj = t.kappa * y[j];
                for i in j..size {
                    c[(i, j)] += kj * y[i];
                }
            }
        }
        if !factor_lower(c.as_mut())? {
            return Ok(None);
        }
        Ok(Some(Prepared {
            hessian: self,
            diag,
            terms,
            c,
        }))
    }

    /// A vector over the free parameters with `values` at the Newton
    /// variables from `start` on, zero elsewhere.
    fn spread(&self, start: usize, values: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; self.root.len()];
        for (k, v) in values.iter().enumerate() {
            out[self.grouped[start + k]] = *v;
        }
        out
    }

    /// `V^T v`.
    fn transpose_times(&self, v: &[f64]) -> Vec<f64> {
        let scaled: Vec<f64> = v.iter().zip(&self.root).map(|(v, r)| v * r).collect();
        self.factors.transpose_times(&scaled)
    }
}

impl Prepared<'_, '_> {
    /// `B^-1 r` (over the free parameters, zero outside the system).
    fn b_inverse(&self, r: &[f64]) -> Vec<f64> {
        let h = self.hessian;
        let mut out: Vec<f64> = r
            .iter()
            .zip(&self.diag)
            .map(|(r, d)| if *d > 0.0 { r / d } else { 0.0 })
            .collect();
        for t in &self.terms {
            let er: f64 =
                t.e.iter()
                    .enumerate()
                    .map(|(k, e)| e * r[h.grouped[t.start + k]])
                    .sum();
            for (k, e) in t.e.iter().enumerate() {
                out[h.grouped[t.start + k]] += t.kappa * e * er;
            }
        }
        out
    }

    /// `H^-1 rhs` over the Newton variables (zero at the held groups').
    pub(super) fn solve(&self, rhs: &[f64]) -> Vec<f64> {
        let h = self.hessian;
        let nf = h.root.len();
        let mut r = vec![0.0; nf];
        for (a, &f) in h.grouped.iter().enumerate() {
            if self.diag[f] > 0.0 {
                r[f] = rhs[a];
            }
        }
        let w = self.b_inverse(&r);
        let t = h.transpose_times(&w);
        let mut s = Mat::from_fn(t.len(), 1, |i, _| t[i]);
        cholesky_solve(self.c.as_ref(), s.as_mut());
        let s: Vec<f64> = (0..t.len()).map(|i| s[(i, 0)]).collect();
        let vs: Vec<f64> = h
            .factors
            .times(&s)
            .iter()
            .zip(&h.root)
            .map(|(u, r)| u * r)
            .collect();
        let correction = self.b_inverse(&vs);
        h.grouped
            .iter()
            .map(|&f| {
                if self.diag[f] > 0.0 {
                    w[f] - correction[f]
                } else {
                    0.0
                }
            })
            .collect()
    }
}
