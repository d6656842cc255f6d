//! The quadratic `P` of Newton's method on the cone step (`newton.rs`),
//! kept packed: half a dense matrix, so that the Hessians can be formed
//! and factored in the caller's matrix itself.

use crate::base::dense::{par_for, product};
use crate::error::Result;
use crate::memory::try_grow;
use faer::linalg::matmul::triangular::{matmul, BlockStructure};
use faer::{Accum, Mat, MatMut, MatRef};

/// The upper triangle of a symmetric matrix, column by column (the
/// column `j` holds rows `0..=j`).
pub(super) struct Packed(Vec<f64>);

impl Packed {
    pub(super) fn of(p: &Mat<f64>) -> Result<Self> {
        let n = p.nrows();
        let mut v = Vec::new();
        try_grow(
            &mut v,
            n * (n + 1) / 2,
            "the quadratic of a Newton cone step",
        )?;
        for j in 0..n {
            v.extend_from_slice(&p.col_as_slice(j)[..=j]);
        }
        Ok(Packed(v))
    }

    fn column(&self, j: usize) -> &[f64] {
        let start = j * (j + 1) / 2;
        &self.0[start..start + j + 1]
    }

    /// Write the whole symmetric matrix into `p`.
    pub(super) fn fill(&self, p: &mut Mat<f64>) {
        for j in 0..p.ncols() {
            p.col_as_slice_mut(j)[..=j].copy_from_slice(self.column(j));
        }
        self.fill_lower(p);
    }

    /// Write the lower triangle into `p` (all the factorisation reads), in
    /// tiles: the lower triangle's rows are the packed columns, so this
    /// half is a transpose, read and written a tile at a time. Written
    /// entry by entry (both halves, as this module once did: one write a
    /// whole column apart for every entry), forming the Hessians took 1.1
    /// of the n = 16 path's 8.6 s of Newton solves.
    pub(super) fn fill_lower(&self, p: &mut Mat<f64>) {
        const TILE: usize = 32;
        let n = p.ncols();
        for j0 in (0..n).step_by(TILE) {
            for i0 in (j0..n).step_by(TILE) {
                for j in j0..(j0 + TILE).min(n) {
                    let col = p.col_as_slice_mut(j);
                    for (i, slot) in col
                        .iter_mut()
                        .enumerate()
                        .take((i0 + TILE).min(n))
                        .skip(i0.max(j))
                    {
                        *slot = self.0[i * (i + 1) / 2 + j];
                    }
                }
            }
        }
    }

    /// `P x`.
    pub(super) fn times(&self, x: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; x.len()];
        for (j, &xj) in x.iter().enumerate() {
            let col = self.column(j);
            let mut dot_j = 0.0;
            for (i, &v) in col[..j].iter().enumerate() {
                out[i] += v * xj;
                dot_j += v * x[i];
            }
            out[j] += dot_j + col[j] * xj;
        }
        out
    }
}

/// The quadratic of a Newton cone step: `P` packed, less `W^T W` where the
/// caller left the Schur complement of the parameters outside every group
/// to the products (`W` `nu x nk`). On the factored route the solves do
/// not read `P`, and `P x - W^T (W x)` costs `4 nu nk` against the
/// `nu nk^2` of forming `P - W^T W` once (at n = 16, 0.8 M against 540 M
/// multiplications a cone step).
pub(super) struct Quadratic<'a> {
    packed: Packed,
    schur: Option<MatRef<'a, f64>>,
}

impl<'a> Quadratic<'a> {
    /// `P` (the upper triangle of `p`), less `W^T W` when `schur` is `W`.
    pub(super) fn of(p: &Mat<f64>, schur: Option<MatRef<'a, f64>>) -> Result<Self> {
        Ok(Quadratic {
            packed: Packed::of(p)?,
            schur,
        })
    }

    /// Write `P` (without the Schur term) back into `p`, both triangles.
    pub(super) fn fill(&self, p: &mut Mat<f64>) {
        self.packed.fill(p);
    }

    /// Write the lower triangle of the quadratic into `p`.
    pub(super) fn fill_lower(&self, p: &mut Mat<f64>) {
        self.packed.fill_lower(p);
        if let Some(w) = self.schur {
            subtract_gram(p.as_mut(), w, BlockStructure::TriangularLower);
        }
    }

    /// The quadratic times `x`.
    pub(super) fn times(&self, x: &[f64]) -> Vec<f64> {
        let mut out = self.packed.times(x);
        if let Some(w) = self.schur {
            let xm = MatRef::from_column_major_slice(x, x.len(), 1);
            let wx = product(w, xm);
            let wtwx = product(w.transpose(), wx.as_ref());
            for (o, v) in out.iter_mut().zip(wtwx.col_as_slice(0)) {
                *o -= v;
            }
        }
        out
    }
}

/// `P -= W^T W` on one triangle of `p` (`structure`), on as many threads as
/// the size pays for (every entry one dot product of two columns of `W`,
/// summed in one order on any number of threads).
pub(super) fn subtract_gram(p: MatMut<'_, f64>, w: MatRef<'_, f64>, structure: BlockStructure) {
    let (nu, nk) = w.shape();
    matmul(
        p,
        structure,
        Accum::Add,
        w.transpose(),
        BlockStructure::Rectangular,
        w,
        BlockStructure::Rectangular,
        -1.0,
        par_for((nk * nk * nu) as f64),
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    fn symmetric(n: usize) -> Mat<f64> {
        Mat::from_fn(n, n, |i, j| (1 + i.min(j) * 7 + i.max(j) * 13) as f64)
    }

    /// `fill_lower` writes the lower triangle that `fill` writes, over
    /// tiles that do not divide the width, and nothing above it.
    #[test]
    fn fill_lower_writes_the_lower_triangle_and_only_it() {
        for n in [1, 31, 32, 33, 70] {
            let p = symmetric(n);
            let packed = Packed::of(&p).unwrap();
            let mut full = Mat::<f64>::zeros(n, n);
            packed.fill(&mut full);
            let mut lower = Mat::from_fn(n, n, |_, _| f64::NAN);
            packed.fill_lower(&mut lower);
            for j in 0..n {
                for i in 0..n {
                    if i >= j {
                        assert_eq!(lower[(i, j)], p[(i, j)], "n {n} ({i}, {j})");
                        assert_eq!(full[(i, j)], p[(i, j)]);
                    } else {
                        assert!(lower[(i, j)].is_nan(), "n {n} ({i}, {j}) written");
                    }
                }
            }
        }
    }

    /// The packed triangle's room is taken whole before it is filled: a
    /// quadratic too large for the memory left fails there, as an error,
    /// and never in a reallocation halfway through the columns.
    #[test]
    fn the_packed_triangle_is_reserved_whole_before_it_is_filled() {
        for n in [1, 2, 31, 70] {
            let packed = Packed::of(&symmetric(n)).unwrap();
            assert_eq!(packed.0.len(), n * (n + 1) / 2, "n {n}");
            assert_eq!(packed.0.capacity(), n * (n + 1) / 2, "n {n}");
        }
    }

    #[test]
    fn times_is_the_product_with_the_whole_matrix() {
        let p = symmetric(9);
        let x: Vec<f64> = (0..9).map(|k| 0.5 - k as f64).collect();
        let y = Packed::of(&p).unwrap().times(&x);
        for (i, yi) in y.iter().enumerate() {
            let want: f64 = (0..9).map(|j| p[(i, j)] * x[j]).sum();
            assert!((yi - want).abs() <= 1e-12 * want.abs(), "{i}");
        }
    }

    /// `P - W^T W` formed (the dense route) against `W` left to the
    /// products (the factored route): the same products, and the same
    /// lower triangle for a dense Newton step.
    #[test]
    fn a_schur_term_left_to_the_products_is_the_quadratic_less_w_t_w() {
        let p = symmetric(13);
        let w = Mat::from_fn(5, 13, |k, i| ((3 * k + 5 * i) as f64 * 0.37).sin());
        let formed = Mat::from_fn(13, 13, |i, j| {
            p[(i, j)] - (0..5).map(|k| w[(k, i)] * w[(k, j)]).sum::<f64>()
        });
        let lazy = Quadratic::of(&p, Some(w.as_ref())).unwrap();
        let x: Vec<f64> = (0..13).map(|k| (0.61 * k as f64).cos()).collect();
        for (i, got) in lazy.times(&x).iter().enumerate() {
            let want: f64 = (0..13).map(|j| formed[(i, j)] * x[j]).sum();
            assert!((got - want).abs() <= 1e-12 * want.abs().max(1.0), "{i}");
        }
        let mut lower = Mat::from_fn(13, 13, |_, _| f64::NAN);
        lazy.fill_lower(&mut lower);
        for j in 0..13 {
            for i in j..13 {
                let want = formed[(i, j)];
                assert!((lower[(i, j)] - want).abs() <= 1e-12 * want.abs().max(1.0));
            }
        }
    }
}
