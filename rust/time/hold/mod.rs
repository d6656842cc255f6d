//! The zero-order hold of a frozen continuous-time model and its
//! derivative with respect to the model's matrices.
//!
//! Over one sample, with `A`, `B` frozen and `u` held,
//! `x(t+1) = Ad x(t) + Gamma v` with `Ad = exp(A dt)`,
//! `Gamma = int_0^1 exp(A dt s) ds` and `v = B u dt`: the top rows of
//! `exp(M) [x; 1]` for the matrix `M = [[A dt, v], [0, 0]]` of size
//! `n + 1` (the simulation, [`crate::simulate::simulate_zoh`], uses
//! `[[A, B], [0, 0]] dt` of size `n + r`: the same map).
//!
//! Derivatives: entry `(a, b)` of `A dt` moves `x(t+1)` by the Fréchet
//! derivative of the exponential applied to `z = [x; 1]`,
//! `L(M, e_a e_b^T) z`; entry `(a, k)` of `B dt` moves `v` by `u_k e_a`,
//! hence `x(t+1)` by `u_k L(M, e_a e_n^T) z = u_k Gamma[:, a]`. The
//! `n^2 + n r` derivatives of a sample therefore need the `n (n + 1)`
//! vectors `L(M, e_a e_b^T) z` whatever `r` is, and the basis functions
//! share them (`dA(p) / dA(i)[a, b] = psi_i(p) e_a e_b^T`).
//!
//! The derivative blocks: [`derivative`]; the small dense kernels: [`dense`].
//!
//! Scaling and squaring with the [6/6] Padé approximant at norm at most
//! 1/2 (Higham, 2005; for the Fréchet derivative, Al-Mohy and Higham,
//! 2009). Before scaling, the last column is balanced: `M` becomes
//! `D M D^-1` with `D = diag(I, beta)`, `beta` a power of two that brings
//! `|v| / beta` well below the size of `A dt`, and `exp(M) =
//! D^-1 exp(D M D^-1) D` exactly in floating point. A large input term
//! (a strong `B` or a large `u`) then adds no squarings.

// Small matrix kernels index several arrays at once; an index reads best.
#![allow(clippy::needless_range_loop)]

use crate::error::{Error, Result};
use crate::memory::try_vec;
use dense::{lu_factor, lu_solve, mul, norm};

mod dense;
mod derivative;
#[cfg(test)]
mod tests;

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

/// Largest norm of the scaled matrix handed to the approximant.
const THETA: f64 = 0.5;

/// Workspace for the hold of one model size.
#[derive(Debug, Clone)]
pub(crate) struct Hold {
    n: usize,
    /// Row stride: `n + 1` rounded up to a multiple of 4 (zero padding).
    w: usize,
    /// Size of the last matrix: `n` (exponential only) or `n + 1`.
    k: usize,
    beta: f64,
    scale: f64,
    squarings: usize,
    a: Vec<f64>,
    a2: Vec<f64>,
    a4: Vec<f64>,
    a6: Vec<f64>,
    ta: Vec<f64>,
    va: Vec<f64>,
    ua: Vec<f64>,
    den: Vec<f64>,
    /// A transposed matrix, for products on the right.
    pt: Vec<f64>,
    piv: Vec<usize>,
    /// `R^(2^j)` for `j = 0..=squarings`.
    powers: Vec<Vec<f64>>,
    zs: Vec<f64>,
    az: Vec<f64>,
    tz: Vec<f64>,
    /// The derivative blocks, `n x n w` each (`Y[c][a w + b]`).
    d2: Vec<f64>,
    d4: Vec<f64>,
    d6: Vec<f64>,
    tx: Vec<f64>,
    rx: Vec<f64>,
    tmp: Vec<f64>,
}

impl Hold {
    /// Workspace for `n` states; [`Error::OutOfMemory`] when its
    /// derivative blocks (`6 n^2 (n + 4)` numbers) cannot be had.
    pub fn new(n: usize) -> Result<Hold> {
        let w = (n + 1).div_ceil(4) * 4;
        let sq = vec![0.0; (n + 1) * w];
        let what = "the derivative of the zero-order hold";
        let block = || try_vec(n * n * w, 0.0, what);
        Ok(Hold {
            n,
            w,
            k: n,
            beta: 1.0,
            scale: 1.0,
            squarings: 0,
            a: sq.clone(),
            a2: sq.clone(),
            a4: sq.clone(),
            a6: sq.clone(),
            ta: sq.clone(),
            va: sq.clone(),
            ua: sq.clone(),
            den: sq.clone(),
            pt: sq,
            piv: vec![0; n + 1],
            powers: Vec::new(),
            zs: vec![0.0; w],
            az: vec![0.0; w],
            tz: vec![0.0; w],
            d2: block()?,
            d4: block()?,
            d6: block()?,
            tx: block()?,
            rx: block()?,
            tmp: block()?,
        })
    }

    /// `ad = exp(a)` for `a = A dt` (`n x n` row-major) and, when `input`
    /// is `Some((v, x))` with `v = B u dt` and the state `x`, the
    /// derivatives of `x(t+1)` (read with [`Hold::forcing`]). Fails
    /// ([`Error::Numerical`]) only when the matrices are not finite or the
    /// Padé denominator is singular.
    #[inline(always)]
    pub fn compute(
        &mut self,
        a: &[f64],
        input: Option<(&[f64], &[f64])>,
        ad: &mut [f64],
    ) -> Result<()> {
        let (n, w) = (self.n, self.w);
        let k = if input.is_some() { n + 1 } else { n };
        self.k = k;
        let finite = a
            .iter()
            .chain(input.map_or(&[][..], |(v, _)| v))
            .map(|x| x.abs())
            .sum::<f64>();
        if !finite.is_finite() {
            return Err(Error::Numerical(
                "matrix exponential of a non-finite matrix".into(),
            ));
        }
        self.a.fill(0.0);
        for i in 0..n {
            self.a[i * w..i * w + n].copy_from_slice(&a[i * n..(i + 1) * n]);
        }
        let size = norm(n, n, w, &self.a, false).max(norm(n, n, w, &self.a, true));
        self.beta = 1.0;
        if let Some((v, _)) = input {
            // Balance the last column to an eighth of A dt's size (and
            // not below the norm where no squaring is needed).
            let target = size.max(THETA) / 8.0;
            let vnorm: f64 = v.iter().map(|x| x.abs()).sum();
            if vnorm > target {
                let e = (vnorm / target).log2().ceil().min(900.0);
                self.beta = 2f64.powi(e as i32);
            }
            for i in 0..n {
                self.a[i * w + n] = v[i] / self.beta;
            }
        }
        let size = norm(k, k, w, &self.a, false).max(norm(k, k, w, &self.a, true));
        self.squarings = if size > THETA {
            (size / THETA).log2().ceil() as usize
        } else {
            0
        };
        self.scale = 0.5f64.powi(self.squarings as i32);
        let scale = self.scale;
        self.a.iter_mut().for_each(|x| *x *= scale);
        self.pade()?;
        let e = &self.powers[self.squarings];
        for i in 0..n {
            ad[i * n..(i + 1) * n].copy_from_slice(&e[i * w..i * w + n]);
        }
        if let Some((_, x)) = input {
            self.derivative(x);
        }
        Ok(())
    }

    /// The Padé approximant of the scaled matrix, its factored
    /// denominator and the squarings, into `powers`.
    #[inline(always)]
    fn pade(&mut self) -> Result<()> {
        let (k, w) = (self.k, self.w);
        let c = PADE6;
        mul(k, w, &self.a, &self.a, &mut self.a2);
        mul(k, w, &self.a2, &self.a2, &mut self.a4);
        mul(k, w, &self.a4, &self.a2, &mut self.a6);
        for e in 0..k * w {
            self.ta[e] = c[3] * self.a2[e] + c[5] * self.a4[e];
            self.va[e] = c[2] * self.a2[e] + c[4] * self.a4[e] + c[6] * self.a6[e];
        }
        for i in 0..k {
            self.ta[i * w + i] += c[1];
            self.va[i * w + i] += c[0];
        }
        mul(k, w, &self.a, &self.ta, &mut self.ua);
        while self.powers.len() <= self.squarings {
            self.powers.push(vec![0.0; (self.n + 1) * w]);
        }
        let r = &mut self.powers[0];
        for e in 0..k * w {
            r[e] = self.va[e] + self.ua[e];
            self.den[e] = self.va[e] - self.ua[e];
        }
        if !lu_factor(k, w, &mut self.den, &mut self.piv) {
            return Err(Error::Numerical(
                "singular Pade denominator in the matrix exponential".into(),
            ));
        }
        lu_solve(k, w, &self.den, &self.piv, r, w);
        for j in 0..self.squarings {
            let (done, rest) = self.powers.split_at_mut(j + 1);
            mul(k, w, &done[j], &done[j], &mut rest[0]);
        }
        Ok(())
    }

    /// After [`Hold::compute`] with an input: the derivatives of `x(t+1)`
    /// times `dt`, for the `n + r` columns of `[A, B]`:
    /// `out[(a (n + r) + b) n + c]` is `dt (L(M, e_a e_b^T) z)_c` for
    /// `b < n` and `dt u_k Gamma[c, a]` for `b = n + k`.
    #[inline(always)]
    pub fn forcing(&self, dt: f64, u: &[f64], out: &mut [f64]) {
        let (n, w) = (self.n, self.w);
        let nw = n * w;
        let s = n + u.len();
        let gamma = dt / self.beta;
        for a in 0..n {
            for b in 0..n {
                let o = &mut out[(a * s + b) * n..(a * s + b + 1) * n];
                for (cc, v) in o.iter_mut().enumerate() {
                    *v = dt * self.rx[cc * nw + a * w + b];
                }
            }
            for (kk, &uk) in u.iter().enumerate() {
                let b = n + kk;
                let o = &mut out[(a * s + b) * n..(a * s + b + 1) * n];
                for (cc, v) in o.iter_mut().enumerate() {
                    *v = gamma * uk * self.rx[cc * nw + a * w + n];
                }
            }
        }
    }
}
