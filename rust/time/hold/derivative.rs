//! Van Loan's block-triangular exponential gives them: the upper-right
//! block of `exp([[M, X], [0, M^T]])` is `int_0^1 exp(M (1 - s)) X
//! exp(M^T s) ds`, and with `X = e_a z^T` its column `b` is
//! `int exp(M (1 - s)) e_a (exp(M s) z)_b ds = L(M, e_a e_b^T) z`. These
//! blocks are linear in `X` and zero below row `n` (as `M` is), so the
//! blocks of every `a` are kept together, top rows only, as
//! `Y[c][a][b]`: a product on the left by a power of `M` is one product
//! of its top-left `n x n` block with the `n x n (n + 1)` matrix of all
//! blocks, a product on the right by its transpose one product per row
//! `(c, a)`. The diagonal blocks (`M` and `M^T`) follow the exponential
//! of `M` itself.

// Small matrix kernels index several arrays at once; an index reads best.
#![allow(clippy::needless_range_loop)]

use super::dense::{lu_solve, row_times, transpose};
use super::{Hold, PADE6};

impl Hold {
    /// `out (+)= y p^T` for blocks `y` (`n^2` rows of `w`) and the `k x k`
    /// matrix `p`, whose transpose is formed in `pt` first.
    #[inline(always)]
    fn right(k: usize, w: usize, y: &[f64], p: &[f64], pt: &mut [f64], out: &mut [f64], add: bool) {
        transpose(k, w, p, pt);
        for (yr, or) in y.chunks_exact(w).zip(out.chunks_exact_mut(w)) {
            row_times(&yr[..k], pt, w, or, add);
        }
    }

    /// `out (+)= p y` for the top-left `n x n` block of `p` and the blocks
    /// `y` (`n` rows of `n w`).
    #[inline(always)]
    fn left(n: usize, w: usize, p: &[f64], y: &[f64], out: &mut [f64], add: bool) {
        let nw = n * w;
        for (c, or) in out.chunks_exact_mut(nw).enumerate() {
            row_times(&p[c * w..c * w + n], y, nw, or, add);
        }
    }

    /// The blocks `Y[c][a][b] = (L(M, e_a e_b^T) z)_c` (in the balanced
    /// coordinates), `z = [x; beta]`, into `rx`.
    #[inline(always)]
    pub(super) fn derivative(&mut self, x: &[f64]) {
        let (n, w, k) = (self.n, self.w, self.k);
        let nw = n * w;
        let c = PADE6;
        for j in 0..n {
            self.zs[j] = x[j] * self.scale;
        }
        self.zs[n] = self.beta * self.scale;
        // X B^T = e_a (A zs)^T and X T_B^T = e_a (T_A zs)^T for the
        // lower-right blocks B = A^T, T_B = T_A^T.
        for i in 0..k {
            let row = i * w..i * w + k;
            let dot = |m: &[f64]| {
                m[row.clone()]
                    .iter()
                    .zip(&self.zs)
                    .map(|(p, q)| p * q)
                    .sum()
            };
            self.az[i] = dot(&self.a);
            self.tz[i] = dot(&self.ta);
        }
        // D2 = A X + X A^T (rank two per a).
        for cc in 0..n {
            let row = &mut self.d2[cc * nw..(cc + 1) * nw];
            for (a, blk) in row.chunks_exact_mut(w).enumerate() {
                let f = self.a[cc * w + a];
                for b in 0..w {
                    blk[b] = f * self.zs[b];
                }
                if a == cc {
                    for b in 0..w {
                        blk[b] += self.az[b];
                    }
                }
            }
        }
        // D4 = A2 D2 + D2 A2^T, D6 = A4 D2 + D4 A2^T.
        Self::left(n, w, &self.a2, &self.d2, &mut self.d4, false);
        Self::right(k, w, &self.d2, &self.a2, &mut self.pt, &mut self.d4, true);
        Self::left(n, w, &self.a4, &self.d2, &mut self.d6, false);
        Self::right(k, w, &self.d4, &self.a2, &mut self.pt, &mut self.d6, true);
        // T_X = c3 D2 + c5 D4; U_X = A T_X + X T_A^T (into tmp).
        for e in 0..n * nw {
            self.tx[e] = c[3] * self.d2[e] + c[5] * self.d4[e];
        }
        Self::left(n, w, &self.a, &self.tx, &mut self.tmp, false);
        for a in 0..n {
            let blk = &mut self.tmp[a * nw + a * w..a * nw + (a + 1) * w];
            blk.iter_mut().zip(&self.tz).for_each(|(o, t)| *o += t);
        }
        // V_X = c2 D2 + c4 D4 + c6 D6; the numerator's derivative minus
        // the denominator's times R^T: rx = (V_X + U_X) + (U_X - V_X) R^T,
        // then R_X = den^-1 rx.
        for e in 0..n * nw {
            let vx = c[2] * self.d2[e] + c[4] * self.d4[e] + c[6] * self.d6[e];
            let ux = self.tmp[e];
            self.rx[e] = vx + ux;
            self.tx[e] = ux - vx;
        }
        Self::right(
            k,
            w,
            &self.tx,
            &self.powers[0],
            &mut self.pt,
            &mut self.rx,
            true,
        );
        lu_solve(n, w, &self.den, &self.piv, &mut self.rx, nw);
        // Squarings: R_X <- R R_X + R_X R^T.
        for j in 0..self.squarings {
            let p = &self.powers[j];
            Self::left(n, w, p, &self.rx, &mut self.tmp, false);
            Self::right(k, w, &self.rx, p, &mut self.pt, &mut self.tmp, true);
            std::mem::swap(&mut self.rx, &mut self.tmp);
        }
    }
}
