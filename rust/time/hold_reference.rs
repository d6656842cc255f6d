//! The reference for [`super::hold`] (tests only): the zero-order hold's
//! derivative as it was computed before, one Van Loan exponential per row
//! `a` on the full matrix `[[A, B], [0, 0]] dt` of size `s = n + r`, with
//! no balancing.
//!
//! With `M = [[A, B], [0, 0]] dt`, `exp(M) = [[Ad, Bd], [0, I]]`, and an
//! entry `(a, b)` of the top `n` rows of `M` moves `x(t+1)` by
//! `L(M, e_a e_b^T) z` with `z = [x; u]`: column `b` of the upper-right
//! block of `exp([[M, e_a z^T], [0, M^T]])`.

// Small matrix kernels index several arrays at once; an index reads best.
#![allow(clippy::needless_range_loop)]

use crate::error::{Error, Result};

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

/// `out = a b` for `s x s` row-major matrices.
#[inline(always)]
fn mul(s: usize, a: &[f64], b: &[f64], out: &mut [f64]) {
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

/// `out += d p^T` for `s x s` row-major matrices.
#[inline(always)]
fn mul_add_bt(s: usize, d: &[f64], p: &[f64], out: &mut [f64]) {
    for i in 0..s {
        let di = &d[i * s..(i + 1) * s];
        for j in 0..s {
            let pj = &p[j * s..(j + 1) * s];
            out[i * s + j] += di.iter().zip(pj).map(|(x, y)| x * y).sum::<f64>();
        }
    }
}

/// LU factorisation with partial pivoting in place; false when singular.
#[inline(always)]
fn lu_factor(s: usize, a: &mut [f64], piv: &mut [usize]) -> bool {
    for k in 0..s {
        let p = (k..s)
            .max_by(|&i, &j| a[i * s + k].abs().total_cmp(&a[j * s + k].abs()))
            .unwrap_or(k);
        piv[k] = p;
        let pivot = a[p * s + k];
        if !(pivot.abs() > 0.0 && pivot.is_finite()) {
            return false;
        }
        if p != k {
            for j in 0..s {
                a.swap(k * s + j, p * s + j);
            }
        }
        for i in k + 1..s {
            let f = a[i * s + k] / pivot;
            a[i * s + k] = f;
            for j in k + 1..s {
                a[i * s + j] -= f * a[k * s + j];
            }
        }
    }
    true
}

/// Solve `A X = b` in place for an `s x s` right-hand side, `A` as factored
/// by [`lu_factor`].
#[inline(always)]
fn lu_solve(s: usize, lu: &[f64], piv: &[usize], b: &mut [f64]) {
    for k in 0..s {
        if piv[k] != k {
            for j in 0..s {
                b.swap(k * s + j, piv[k] * s + j);
            }
        }
        for i in k + 1..s {
            let f = lu[i * s + k];
            if f != 0.0 {
                for j in 0..s {
                    b[i * s + j] -= f * b[k * s + j];
                }
            }
        }
    }
    for k in (0..s).rev() {
        for j in 0..s {
            let mut v = b[k * s + j];
            for i in k + 1..s {
                v -= lu[k * s + i] * b[i * s + j];
            }
            b[k * s + j] = v / lu[k * s + k];
        }
    }
}

/// Workspace for the hold of one model size.
#[derive(Debug, Clone)]
pub(crate) struct Hold {
    n: usize,
    s: usize,
    a: Vec<f64>,
    a2: Vec<f64>,
    a4: Vec<f64>,
    a6: Vec<f64>,
    ta: Vec<f64>,
    va: Vec<f64>,
    ua: Vec<f64>,
    den: Vec<f64>,
    piv: Vec<usize>,
    /// `R^(2^k)` for `k = 0..=squarings`.
    powers: Vec<Vec<f64>>,
    zs: Vec<f64>,
    az: Vec<f64>,
    tz: Vec<f64>,
    d2: Vec<f64>,
    d4: Vec<f64>,
    d6: Vec<f64>,
    tx: Vec<f64>,
    ux: Vec<f64>,
    rx: Vec<f64>,
    tmp: Vec<f64>,
}

impl Hold {
    /// Workspace for `n` states and `r` inputs.
    pub fn new(n: usize, r: usize) -> Hold {
        let s = n + r;
        let z = vec![0.0; s * s];
        Hold {
            n,
            s,
            a: z.clone(),
            a2: z.clone(),
            a4: z.clone(),
            a6: z.clone(),
            ta: z.clone(),
            va: z.clone(),
            ua: z.clone(),
            den: z.clone(),
            piv: vec![0; s],
            powers: Vec::new(),
            zs: vec![0.0; s],
            az: vec![0.0; s],
            tz: vec![0.0; s],
            d2: z.clone(),
            d4: z.clone(),
            d6: z.clone(),
            tx: z.clone(),
            ux: z.clone(),
            rx: z.clone(),
            tmp: z,
        }
    }

    /// `e = exp(m)` (`s x s` row-major) and, when `z` is given,
    /// `forcing[(a s + b) n + c] = (L(m, e_a e_b^T) z)_c` for `a, c < n`
    /// and `b < s`. Fails ([`Error::Numerical`]) only when `m` is not
    /// finite or the Padé denominator is singular.
    #[inline(always)]
    pub fn compute(
        &mut self,
        m: &[f64],
        z: Option<&[f64]>,
        e: &mut [f64],
        forcing: &mut [f64],
    ) -> Result<()> {
        let s = self.s;
        let norm1 = (0..s)
            .map(|j| (0..s).map(|i| m[i * s + j].abs()).sum::<f64>())
            .fold(0.0, f64::max);
        let norm_inf = (0..s)
            .map(|i| m[i * s..(i + 1) * s].iter().map(|v| v.abs()).sum::<f64>())
            .fold(0.0, f64::max);
        // The lower-right block is M^T: scale for the larger of both norms.
        let norm = norm1.max(norm_inf);
        if !norm.is_finite() {
            return Err(Error::Numerical(
                "matrix exponential of a non-finite matrix".into(),
            ));
        }
        let squarings = if norm > 0.5 {
            (norm / 0.5).log2().ceil() as usize
        } else {
            0
        };
        let scale = 0.5f64.powi(squarings as i32);
        for (x, &v) in self.a.iter_mut().zip(m) {
            *x = v * scale;
        }
        let c = PADE6;
        mul(s, &self.a, &self.a, &mut self.a2);
        mul(s, &self.a2, &self.a2, &mut self.a4);
        mul(s, &self.a4, &self.a2, &mut self.a6);
        for k in 0..s * s {
            self.ta[k] = c[3] * self.a2[k] + c[5] * self.a4[k];
            self.va[k] = c[2] * self.a2[k] + c[4] * self.a4[k] + c[6] * self.a6[k];
        }
        for i in 0..s {
            self.ta[i * s + i] += c[1];
            self.va[i * s + i] += c[0];
        }
        mul(s, &self.a, &self.ta, &mut self.ua);
        while self.powers.len() <= squarings {
            self.powers.push(vec![0.0; s * s]);
        }
        let r = &mut self.powers[0];
        for k in 0..s * s {
            r[k] = self.va[k] + self.ua[k];
            self.den[k] = self.va[k] - self.ua[k];
        }
        if !lu_factor(s, &mut self.den, &mut self.piv) {
            return Err(Error::Numerical(
                "singular Pade denominator in the matrix exponential".into(),
            ));
        }
        lu_solve(s, &self.den, &self.piv, r);
        for k in 0..squarings {
            let (done, rest) = self.powers.split_at_mut(k + 1);
            mul(s, &done[k], &done[k], &mut rest[0]);
        }
        e.copy_from_slice(&self.powers[squarings]);
        if let Some(z) = z {
            self.derivative(z, scale, squarings, forcing);
        }
        Ok(())
    }

    /// The upper-right blocks for `X = e_a z^T`, `a < n` (see the module
    /// documentation), into `forcing`.
    #[inline(always)]
    fn derivative(&mut self, z: &[f64], scale: f64, squarings: usize, forcing: &mut [f64]) {
        let (n, s) = (self.n, self.s);
        let c = PADE6;
        for (v, &x) in self.zs.iter_mut().zip(z) {
            *v = x * scale;
        }
        // A zs and T_A zs: X B = e_a (A zs)^T and X T_B = e_a (T_A zs)^T
        // (B = A^T, T_B = T_A^T).
        for i in 0..s {
            let row = i * s..(i + 1) * s;
            self.az[i] = self.a[row.clone()]
                .iter()
                .zip(&self.zs)
                .map(|(p, q)| p * q)
                .sum();
            self.tz[i] = self.ta[row].iter().zip(&self.zs).map(|(p, q)| p * q).sum();
        }
        for a in 0..n {
            // D2 = A X + X A^T (rank two), D4 = A2 D2 + D2 A2^T, D6 = A4 D2 + D4 A2^T.
            for i in 0..s {
                let col = self.a[i * s + a];
                for k in 0..s {
                    self.d2[i * s + k] = col * self.zs[k];
                }
            }
            for k in 0..s {
                self.d2[a * s + k] += self.az[k];
            }
            mul(s, &self.a2, &self.d2, &mut self.d4);
            mul_add_bt(s, &self.d2, &self.a2, &mut self.d4);
            mul(s, &self.a4, &self.d2, &mut self.d6);
            mul_add_bt(s, &self.d4, &self.a2, &mut self.d6);
            // T_X = c3 D2 + c5 D4; U_X = A T_X + X T_A^T;
            // V_X = c2 D2 + c4 D4 + c6 D6.
            for k in 0..s * s {
                self.tx[k] = c[3] * self.d2[k] + c[5] * self.d4[k];
            }
            mul(s, &self.a, &self.tx, &mut self.ux);
            for k in 0..s {
                self.ux[a * s + k] += self.tz[k];
            }
            // rx = (V_X + U_X) - (V_X - U_X) R^T, then R_X = den^-1 rx.
            for k in 0..s * s {
                let vx = c[2] * self.d2[k] + c[4] * self.d4[k] + c[6] * self.d6[k];
                self.tmp[k] = vx - self.ux[k];
                self.rx[k] = vx + self.ux[k];
            }
            for k in 0..s * s {
                self.tx[k] = -self.tmp[k];
            }
            mul_add_bt(s, &self.tx, &self.powers[0], &mut self.rx);
            lu_solve(s, &self.den, &self.piv, &mut self.rx);
            // Squarings: R_X <- R R_X + R_X R^T.
            for k in 0..squarings {
                let p = &self.powers[k];
                mul(s, p, &self.rx, &mut self.tmp);
                mul_add_bt(s, &self.rx, p, &mut self.tmp);
                std::mem::swap(&mut self.rx, &mut self.tmp);
            }
            for b in 0..s {
                let out = &mut forcing[(a * s + b) * n..(a * s + b + 1) * n];
                for (cc, o) in out.iter_mut().enumerate() {
                    *o = self.rx[cc * s + b];
                }
            }
        }
    }
}
