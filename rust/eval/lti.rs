//! Frozen (LTI) models: the LPV matrices evaluated at one scheduling value,
//! and their frequency response.
//!
//! The response at many frequencies uses the Hessenberg form of `A`
//! (Laub, 1981): `A = Q H Q^T` once per model, after which every frequency
//! costs one `O(n^2)` factorisation of the Hessenberg matrix `zI - H`.

use crate::base::lanes::{Cx, LANES};
use crate::base::layout::{Matrix, Shape};
use num_complex::Complex64 as C64;

/// `A(p)`, `B(p)`, `C(p)`, `D(p)` at one scheduling value, column-major.
#[derive(Debug, Clone)]
pub struct Frozen {
    /// `n x n`.
    pub a: Vec<f64>,
    /// `n x r`.
    pub b: Vec<f64>,
    /// `l x n`.
    pub c: Vec<f64>,
    /// `l x r`.
    pub d: Vec<f64>,
}

impl Frozen {
    /// Evaluate `X(p) = sum_i psi_i X(i)` for every matrix, with
    /// `psi = [1, psi_1(p), ..., psi_Nb(p)]`.
    pub fn at(shape: &Shape, theta: &[f64], psi: &[f64]) -> Self {
        let eval = |x: Matrix| {
            let mut out = vec![0.0; shape.matrix_len(x)];
            for (i, &w) in psi.iter().enumerate() {
                if w != 0.0 {
                    for (o, &t) in out.iter_mut().zip(&theta[shape.block(x, i)]) {
                        *o += w * t;
                    }
                }
            }
            out
        };
        Frozen {
            a: eval(Matrix::A),
            b: eval(Matrix::B),
            c: eval(Matrix::C),
            d: eval(Matrix::D),
        }
    }
}

/// A frozen model in Hessenberg coordinates: `H = Q^T A Q` upper Hessenberg,
/// `Bh = Q^T B`, `Ch = C Q`, with the orthogonal `Q` kept to map results
/// back to the original coordinates.
#[derive(Debug, Clone)]
pub struct Hessenberg {
    r: usize,
    l: usize,
    h: Vec<f64>,
    q: Vec<f64>,
    bh: Vec<f64>,
    ch: Vec<f64>,
    d: Vec<f64>,
}

impl Hessenberg {
    /// Reduce a frozen model (Householder reflections).
    pub fn new(shape: &Shape, m: &Frozen) -> Self {
        let (n, r, l) = (shape.n, shape.r, shape.l);
        let mut h = m.a.clone();
        let mut q = vec![0.0; n * n];
        for k in 0..n {
            q[k + k * n] = 1.0;
        }
        let mut v = vec![0.0; n];
        for k in 0..n.saturating_sub(2) {
            // Householder vector annihilating h[k+2.., k].
            let alpha: f64 = (k + 1..n).map(|i| h[i + k * n].powi(2)).sum::<f64>().sqrt();
            if alpha == 0.0 {
                continue;
            }
            let x0 = h[k + 1 + k * n];
            let beta = if x0 >= 0.0 { -alpha } else { alpha };
            v[..=k].iter_mut().for_each(|e| *e = 0.0);
            v[k + 1] = x0 - beta;
            for i in k + 2..n {
                v[i] = h[i + k * n];
            }
            let vv: f64 = v[k + 1..].iter().map(|e| e * e).sum();
            if vv == 0.0 {
                continue;
            }
            let tau = 2.0 / vv;
            // H <- (I - tau v v^T) H
            for j in 0..n {
                let col = &mut h[j * n..(j + 1) * n];
                let s: f64 = (k + 1..n).map(|i| v[i] * col[i]).sum::<f64>() * tau;
                for i in k + 1..n {
                    col[i] -= s * v[i];
                }
            }
            // H <- H (I - tau v v^T), Q <- Q (I - tau v v^T)
            for mat in [&mut h, &mut q] {
                let mut w = vec![0.0; n];
                for j in k + 1..n {
                    for i in 0..n {
                        w[i] += mat[i + j * n] * v[j];
                    }
                }
                for j in k + 1..n {
                    let f = tau * v[j];
                    for i in 0..n {
                        mat[i + j * n] -= w[i] * f;
                    }
                }
            }
            for i in k + 2..n {
                h[i + k * n] = 0.0;
            }
        }
        let mut bh = vec![0.0; n * r];
        for c in 0..r {
            for i in 0..n {
                bh[i + c * n] = (0..n).map(|a| q[a + i * n] * m.b[a + c * n]).sum();
            }
        }
        let mut ch = vec![0.0; l * n];
        for j in 0..n {
            for i in 0..l {
                ch[i + j * l] = (0..n).map(|a| m.c[i + a * l] * q[a + j * n]).sum();
            }
        }
        Hessenberg {
            r,
            l,
            h,
            q,
            bh,
            ch,
            d: m.d.clone(),
        }
    }
}

/// Workspace and result of the evaluation of `G(z) = C (zI - A)^-1 B + D`
/// at [`LANES`] values of `z` at once.
///
/// After [`Resolvent::evaluate`]: `x = (zI - A)^-1 B` (`n x r`), `g = G(z)`
/// (`l x r`), and when asked for, `yt` (`n x l`) whose column `j` is row `j`
/// of `Y = C (zI - A)^-1`; all column-major, in the original coordinates,
/// one lane per value of `z`.
#[derive(Debug, Clone)]
pub struct Resolvent {
    n: usize,
    u: Vec<Cx>,
    inv_diag: Vec<Cx>,
    mult: Vec<Cx>,
    swap: Vec<[bool; LANES]>,
    xh: Vec<Cx>,
    yh: Vec<Cx>,
    /// `(zI - A)^-1 B`, `n x r`.
    pub x: Vec<Cx>,
    /// `(zI - A)^-T C^T`, `n x l`.
    pub yt: Vec<Cx>,
    /// `G(z)`, `l x r`.
    pub g: Vec<Cx>,
}

impl Resolvent {
    /// Workspace for a model of the given shape.
    pub fn new(shape: &Shape) -> Self {
        let (n, r, l) = (shape.n, shape.r, shape.l);
        let zero = Cx::default();
        Resolvent {
            n,
            u: vec![zero; n * n],
            inv_diag: vec![zero; n],
            mult: vec![zero; n],
            swap: vec![[false; LANES]; n],
            xh: vec![zero; n * r],
            yh: vec![zero; n * l],
            x: vec![zero; n * r],
            yt: vec![zero; n * l],
            g: vec![zero; l * r],
        }
    }

    /// Evaluate at the lanes of `z`. With `left` true, also compute `yt`
    /// (for the Jacobian). On a numerically singular `zI - A` returns the
    /// offending lane.
    pub fn evaluate(&mut self, m: &Hessenberg, z: &Cx, left: bool) -> Result<(), usize> {
        let n = self.n;
        let (r, l) = (m.r, m.l);
        self.factor(m, z)?;
        for (dst, &b) in self.xh.iter_mut().zip(&m.bh) {
            *dst = Cx::real(b);
        }
        for c in 0..r {
            self.solve(c);
        }
        // G = Ch Xh + D, X = Q Xh
        for c in 0..r {
            let xh = &self.xh[c * n..(c + 1) * n];
            for j in 0..l {
                let mut acc = Cx::real(m.d[j + c * l]);
                for (a, &xa) in xh.iter().enumerate() {
                    acc += xa * m.ch[j + a * l];
                }
                self.g[j + c * l] = acc;
            }
            map_back(&m.q, n, xh, &mut self.x[c * n..(c + 1) * n]);
        }
        if left {
            for j in 0..l {
                for a in 0..n {
                    self.yh[a + j * n] = Cx::real(m.ch[j + a * l]);
                }
                self.solve_transposed(j);
                map_back(
                    &m.q,
                    n,
                    &self.yh[j * n..(j + 1) * n],
                    &mut self.yt[j * n..(j + 1) * n],
                );
            }
        }
        Ok(())
    }

    /// LU factorisation with partial pivoting of the Hessenberg `zI - H`:
    /// row `k` may only swap with row `k + 1`. `U` is kept row-major so
    /// that every row operation runs over contiguous memory.
    fn factor(&mut self, m: &Hessenberg, z: &Cx) -> Result<(), usize> {
        let n = self.n;
        let u = &mut self.u;
        for i in 0..n {
            let row = &mut u[i * n..(i + 1) * n];
            let first = i.saturating_sub(1);
            for (j, v) in row.iter_mut().enumerate().skip(first) {
                *v = Cx::real(-m.h[i + j * n]);
            }
            row[i] += *z;
        }
        for k in 0..n {
            let (upper, lower) = u.split_at_mut((k + 1) * n);
            let row_k = &mut upper[k * n..];
            if k + 1 < n {
                let row_next = &mut lower[..n];
                let (below, diag) = (row_next[k].norm_sqr(), row_k[k].norm_sqr());
                let mut mask = [false; LANES];
                for lane in 0..LANES {
                    mask[lane] = below[lane] > diag[lane];
                }
                self.swap[k] = mask;
                if mask.iter().any(|&s| s) {
                    for (a, b) in row_k[k..].iter_mut().zip(row_next[k..].iter_mut()) {
                        Cx::swap_where(&mask, a, b);
                    }
                }
            }
            let inv = row_k[k]
                .inv()
                .ok_or_else(|| row_k[k].bad_lane().unwrap_or(0))?;
            self.inv_diag[k] = inv;
            if k + 1 < n {
                let row_next = &mut lower[..n];
                let f = row_next[k] * inv;
                self.mult[k] = f;
                for (d, &s) in row_next[k + 1..].iter_mut().zip(&row_k[k + 1..]) {
                    *d -= f * s;
                }
            }
        }
        Ok(())
    }

    /// Solve `(zI - H) x = b` for column `c` of `xh`, in place.
    fn solve(&mut self, c: usize) {
        let n = self.n;
        let b = &mut self.xh[c * n..(c + 1) * n];
        for k in 0..n.saturating_sub(1) {
            let (lo, hi) = b.split_at_mut(k + 1);
            Cx::swap_where(&self.swap[k], &mut lo[k], &mut hi[0]);
            hi[0] -= self.mult[k] * lo[k];
        }
        for k in (0..n).rev() {
            let row = &self.u[k * n + k + 1..(k + 1) * n];
            let mut acc = b[k];
            for (&ukj, &bj) in row.iter().zip(&b[k + 1..]) {
                acc -= ukj * bj;
            }
            b[k] = acc * self.inv_diag[k];
        }
    }

    /// Solve `(zI - H)^T y = c` for column `j` of `yh`, in place.
    fn solve_transposed(&mut self, j: usize) {
        let n = self.n;
        let b = &mut self.yh[j * n..(j + 1) * n];
        // U^T s = c, column-oriented so that row k of U is read contiguously.
        for k in 0..n {
            let sk = b[k] * self.inv_diag[k];
            b[k] = sk;
            let row = &self.u[k * n + k + 1..(k + 1) * n];
            for (bj, &ukj) in b[k + 1..].iter_mut().zip(row) {
                *bj -= ukj * sk;
            }
        }
        for k in (0..n.saturating_sub(1)).rev() {
            let (lo, hi) = b.split_at_mut(k + 1);
            lo[k] -= self.mult[k] * hi[0];
            Cx::swap_where(&self.swap[k], &mut lo[k], &mut hi[0]);
        }
    }
}

/// Rows of `out` that [`map_back`] sums at a time, in registers.
const MAP_ROWS: usize = 4;

/// `out = Q v` for a real `Q` and complex lanes `v`: every entry
/// `((0 + v_0 q_i0) + v_1 q_i1) + ...` in that order, [`MAP_ROWS`] rows at
/// a time so that their sums stay in registers.
fn map_back(q: &[f64], n: usize, v: &[Cx], out: &mut [Cx]) {
    let whole = n / MAP_ROWS * MAP_ROWS;
    for first in (0..whole).step_by(MAP_ROWS) {
        let mut re = [[0.0f64; LANES]; MAP_ROWS];
        let mut im = [[0.0f64; LANES]; MAP_ROWS];
        for (a, va) in v[..n].iter().enumerate() {
            let col: &[f64; MAP_ROWS] = q[a * n + first..a * n + first + MAP_ROWS]
                .try_into()
                .expect("MAP_ROWS values");
            for i in 0..MAP_ROWS {
                for k in 0..LANES {
                    re[i][k] += va.re[k] * col[i];
                    im[i][k] += va.im[k] * col[i];
                }
            }
        }
        for i in 0..MAP_ROWS {
            out[first + i] = Cx {
                re: re[i],
                im: im[i],
            };
        }
    }
    for (i, o) in out[..n].iter_mut().enumerate().skip(whole) {
        *o = Cx::default();
        for (a, &va) in v[..n].iter().enumerate() {
            *o += va * q[i + a * n];
        }
    }
}

/// Fill `z` lanes with lines `first..end` of `points`, repeating the last
/// line in unused lanes.
pub fn lanes_of(points: &[C64], first: usize, end: usize) -> Cx {
    let mut v = [C64::new(0.0, 0.0); LANES];
    for (k, slot) in v.iter_mut().enumerate() {
        *slot = points[(first + k).min(end - 1)];
    }
    Cx::from_lanes(&v)
}

#[cfg(test)]
mod tests {
    use super::*;
    use faer::linalg::solvers::Solve;
    use faer::Mat;

    fn model(n: usize, r: usize, l: usize, seed: u64) -> (Shape, Frozen) {
        let shape = Shape::new(n, r, l, 0).unwrap();
        let mut rng = crate::testing::Lcg(seed);
        let mut rnd = || rng.next_f64();
        let m = Frozen {
            a: (0..n * n).map(|_| rnd()).collect(),
            b: (0..n * r).map(|_| rnd()).collect(),
            c: (0..l * n).map(|_| rnd()).collect(),
            d: (0..l * r).map(|_| rnd()).collect(),
        };
        (shape, m)
    }

    #[test]
    fn hessenberg_is_similar_and_orthogonal() {
        let (shape, m) = model(6, 2, 3, 3);
        let hs = Hessenberg::new(&shape, &m);
        let n = 6;
        let a = Mat::from_fn(n, n, |i, j| m.a[i + j * n]);
        let q = Mat::from_fn(n, n, |i, j| hs.q[i + j * n]);
        let h = Mat::from_fn(n, n, |i, j| hs.h[i + j * n]);
        let back = &q * &h * q.transpose();
        let qtq = q.transpose() * &q;
        for i in 0..n {
            for j in 0..n {
                assert!((back[(i, j)] - a[(i, j)]).abs() < 1e-13);
                let id = if i == j { 1.0 } else { 0.0 };
                assert!((qtq[(i, j)] - id).abs() < 1e-13);
                if i > j + 1 {
                    assert_eq!(h[(i, j)], 0.0);
                }
            }
        }
    }

    #[test]
    fn resolvent_matches_dense_lu() {
        for (n, r, l) in [(1, 1, 1), (2, 1, 2), (5, 2, 3), (7, 3, 1)] {
            let (shape, m) = model(n, r, l, 11 + n as u64);
            let hs = Hessenberg::new(&shape, &m);
            let mut res = Resolvent::new(&shape);
            let zs = [C64::new(0.3, 0.9), C64::new(-1.0, 0.1), C64::new(0.0, 2.0)];
            let batch = lanes_of(&zs, 0, zs.len());
            assert!(res.evaluate(&hs, &batch, true).is_ok());
            for (lane, &z) in zs.iter().enumerate() {
                let zia = Mat::from_fn(n, n, |i, j| {
                    let d = if i == j { z } else { C64::new(0.0, 0.0) };
                    d - C64::new(m.a[i + j * n], 0.0)
                });
                let lu = zia.partial_piv_lu();
                let b = Mat::from_fn(n, r, |i, j| C64::new(m.b[i + j * n], 0.0));
                let x = lu.solve(&b);
                let ct = Mat::from_fn(n, l, |i, j| C64::new(m.c[j + i * l], 0.0));
                let yt = zia.transpose().to_owned().partial_piv_lu().solve(&ct);
                for i in 0..n {
                    for c in 0..r {
                        assert!((x[(i, c)] - res.x[i + c * n].lane(lane)).norm() < 1e-12);
                    }
                    for j in 0..l {
                        assert!((yt[(i, j)] - res.yt[i + j * n].lane(lane)).norm() < 1e-12);
                    }
                }
                for j in 0..l {
                    for c in 0..r {
                        let g: C64 = (0..n).map(|a| x[(a, c)] * m.c[j + a * l]).sum::<C64>()
                            + m.d[j + c * l];
                        assert!((g - res.g[j + c * l].lane(lane)).norm() < 1e-12);
                    }
                }
            }
        }
    }

    #[test]
    fn pole_on_the_evaluation_point_is_singular() {
        let shape = Shape::new(2, 1, 1, 0).unwrap();
        let m = Frozen {
            a: vec![0.5, 0.0, 0.0, -0.25],
            b: vec![1.0, 1.0],
            c: vec![1.0, 1.0],
            d: vec![0.0],
        };
        let hs = Hessenberg::new(&shape, &m);
        let mut res = Resolvent::new(&shape);
        let zs = [C64::new(0.1, 0.0), C64::new(0.5, 1e-3), C64::new(0.5, 0.0)];
        assert_eq!(res.evaluate(&hs, &lanes_of(&zs, 0, 3), false), Err(2));
        assert_eq!(res.evaluate(&hs, &lanes_of(&zs, 0, 2), false), Ok(()));
    }
}
