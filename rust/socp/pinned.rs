//! Directions the cone steps are kept off: moves that cost nothing at the
//! data but change the model between the scheduling points.
//!
//! With as many scheduling points as coefficient matrices, a state
//! transformation applied at one point alone is a direction of theta along
//! which V_NLS does not change; the l2,1 term can then buy smaller groups
//! with moves that only the points in between see. A step is kept off such
//! directions by a curvature `weight` added along them, measured in the
//! Jacobi-scaled variables of the fit's first step (where the quadratic has
//! a unit diagonal). Transformations that are the same at every point (the
//! exempt directions) change nothing anywhere, so the steps stay free along
//! them.

use crate::base::dense::{par_for, product, thin_svd};
use crate::error::Result;
use crate::memory::try_zeros;
use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, MatRef};

/// Singular values below this fraction of the largest are dropped when the
/// directions are made orthonormal.
const RANK_TOL: f64 = 1e-9;

/// Directions over the free parameters that the cone steps are kept off.
#[derive(Debug, Clone)]
pub struct Pinned {
    /// Directions to keep off, one per column (free parameters, unscaled).
    pub dirs: Mat<f64>,
    /// Directions left free (the same transformation at every point).
    pub exempt: Mat<f64>,
    /// Curvature along each kept-off direction, relative to the unit
    /// diagonal of the scaled quadratic.
    pub weight: f64,
}

/// The kept-off directions of one fit, made orthonormal once in the metric
/// of its first step.
#[derive(Debug, Clone)]
pub struct PinnedBasis {
    /// `S0^-1 V`: the orthonormal directions `V` (scaled variables of the
    /// first step, scale `S0`) as rows over the unscaled parameters.
    u: Mat<f64>,
    weight: f64,
}

/// Orthonormal columns spanning those of `m` (by a thin SVD), singular
/// values up to `RANK_TOL` times `reference` (or the largest, if larger)
/// dropped: a caller that projected `m` passes its size before, so that
/// what the projection left as rounding is not taken for a direction.
/// `None` when the SVD fails. On this thread ([`thin_svd`]: on faer's pool
/// the directions, and the fits kept off them, followed the thread count).
fn orthonormal(m: MatRef<'_, f64>, reference: f64) -> Result<Option<Mat<f64>>> {
    if m.ncols() == 0 || m.nrows() == 0 {
        return Ok(Some(Mat::zeros(m.nrows(), 0)));
    }
    let Some((u, s)) = thin_svd(m)? else {
        return Ok(None);
    };
    let top = s.iter().copied().fold(reference, f64::max);
    let keep: Vec<usize> = (0..s.len())
        .filter(|&k| top > 0.0 && s[k] > RANK_TOL * top)
        .collect();
    Ok(Some(Mat::from_fn(m.nrows(), keep.len(), |i, c| {
        u[(i, keep[c])]
    })))
}

impl Pinned {
    /// The directions in the scaled variables `e = d / scale0` of a fit's
    /// first step: orthonormal, with the exempt ones projected out. `None`
    /// when the sizes do not match `scale0`, an SVD fails or nothing is left
    /// to keep off ([`crate::Error::OutOfMemory`] when an SVD's scratch space
    /// cannot be had).
    pub fn basis(&self, scale0: &[f64]) -> Result<Option<PinnedBasis>> {
        let nf = scale0.len();
        if self.dirs.nrows() != nf
            || self.exempt.nrows() != nf
            || self.weight == 0.0
            || scale0.iter().any(|s| !(s.is_finite() && *s > 0.0))
        {
            return Ok(None);
        }
        let scaled = |m: &Mat<f64>| Mat::from_fn(nf, m.ncols(), |i, c| m[(i, c)] / scale0[i]);
        let Some(g) = orthonormal(scaled(&self.exempt).as_ref(), 0.0)? else {
            return Ok(None);
        };
        let mut w = scaled(&self.dirs);
        let before = w.norm_l2();
        if g.ncols() > 0 {
            let gw = product(g.transpose(), w.as_ref());
            w -= product(g.as_ref(), gw.as_ref());
        }
        let Some(v) = orthonormal(w.as_ref(), before)? else {
            return Ok(None);
        };
        if v.ncols() == 0 {
            return Ok(None);
        }
        Ok(Some(PinnedBasis {
            u: Mat::from_fn(nf, v.ncols(), |i, c| v[(i, c)] / scale0[i]),
            weight: self.weight,
        }))
    }
}

impl PinnedBasis {
    /// The added curvature in the scaled variables `e = d / scale` of a
    /// step: `weight (S U)(S U)^T`, the same quadratic in the unscaled step
    /// at every scale.
    pub fn scaled_curvature(&self, scale: &[f64]) -> Result<Mat<f64>> {
        let root = self.weight.sqrt();
        let su = Mat::from_fn(self.u.nrows(), self.u.ncols(), |i, c| {
            self.u[(i, c)] * scale[i] * root
        });
        let nf = su.nrows();
        let mut out = try_zeros(nf, nf, "the curvature along the pinned directions")?;
        // A product of two matrices: the same bits on any number of threads.
        let par = par_for((nf * nf * su.ncols()) as f64);
        matmul(out.as_mut(), Accum::Replace, &su, su.transpose(), 1.0, par);
        Ok(out)
    }

    /// Adds the curvature's gradient at the unscaled step `d`,
    /// `weight U (U^T d)`, to `out`.
    pub fn add_gradient(&self, d: &[f64], out: &mut [f64]) {
        for c in 0..self.u.ncols() {
            let col = self.u.col(c);
            let dot: f64 = (0..d.len()).map(|i| col[i] * d[i]).sum();
            let f = self.weight * dot;
            out.iter_mut()
                .enumerate()
                .for_each(|(i, o)| *o += f * col[i]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic, irregular matrix.
    fn filled(rows: usize, cols: usize, seed: f64) -> Mat<f64> {
        Mat::from_fn(rows, cols, |i, j| {
            ((i * i * 3 + j * 5 + i * j * 11) as f64 * 0.37 + seed).sin()
        })
    }

    #[test]
    fn basis_is_orthonormal_in_the_first_metric_and_leaves_the_exempt_free() {
        let nf = 8;
        let exempt = filled(nf, 2, 0.1);
        // Two kept-off directions plus one inside the exempt span.
        let dirs = Mat::from_fn(nf, 3, |i, j| match j {
            0 | 1 => filled(nf, 2, 1.3)[(i, j)],
            _ => exempt[(i, 0)] - 2.0 * exempt[(i, 1)],
        });
        let scale0: Vec<f64> = (0..nf).map(|i| 0.5 + 0.25 * i as f64).collect();
        let pinned = Pinned {
            dirs,
            exempt: exempt.clone(),
            weight: 2.0,
        };
        let basis = pinned
            .basis(&scale0)
            .unwrap()
            .expect("two directions are left");
        assert_eq!(basis.u.ncols(), 2);
        let v = Mat::from_fn(nf, 2, |i, c| basis.u[(i, c)] * scale0[i]);
        let gram = v.transpose() * &v;
        for a in 0..2 {
            for b in 0..2 {
                let want = if a == b { 1.0 } else { 0.0 };
                assert!((gram[(a, b)] - want).abs() < 1e-12);
            }
        }
        // Orthogonal to the exempt directions in the scaled variables.
        let scaled_exempt = Mat::from_fn(nf, 2, |i, c| exempt[(i, c)] / scale0[i]);
        let cross = v.transpose() * &scaled_exempt;
        for a in 0..2 {
            for b in 0..2 {
                assert!(cross[(a, b)].abs() < 1e-12);
            }
        }
    }

    #[test]
    fn gradient_is_the_curvature_at_every_scale() {
        let nf = 6;
        let pinned = Pinned {
            dirs: filled(nf, 3, 0.7),
            exempt: filled(nf, 1, 2.1),
            weight: 1.5,
        };
        let scale0: Vec<f64> = (0..nf).map(|i| 1.0 + 0.1 * i as f64).collect();
        let basis = pinned.basis(&scale0).unwrap().expect("directions are left");
        let scale: Vec<f64> = (0..nf).map(|i| 0.3 + 0.2 * i as f64).collect();
        let curvature = basis.scaled_curvature(&scale).unwrap();
        let d: Vec<f64> = (0..nf).map(|i| (i as f64 * 1.7).cos()).collect();
        // Unscaled curvature S^-1 C S^-1 times d, against add_gradient.
        let mut grad = vec![0.0; nf];
        basis.add_gradient(&d, &mut grad);
        for i in 0..nf {
            let want: f64 = (0..nf)
                .map(|j| curvature[(i, j)] / (scale[i] * scale[j]) * d[j])
                .sum();
            assert!((grad[i] - want).abs() < 1e-12 * (1.0 + want.abs()));
        }
    }

    #[test]
    fn nothing_to_keep_off_inside_the_exempt_span_or_at_zero_weight() {
        let nf = 5;
        let exempt = filled(nf, 2, 0.4);
        let inside = Mat::from_fn(nf, 1, |i, _| 3.0 * exempt[(i, 0)] + exempt[(i, 1)]);
        let scale0 = vec![1.0; nf];
        let within = Pinned {
            dirs: inside,
            exempt: exempt.clone(),
            weight: 1.0,
        };
        assert!(within.basis(&scale0).unwrap().is_none());
        let unweighted = Pinned {
            dirs: filled(nf, 2, 3.0),
            exempt,
            weight: 0.0,
        };
        assert!(unweighted.basis(&scale0).unwrap().is_none());
        assert!(Pinned {
            weight: 1.0,
            ..unweighted.clone()
        }
        .basis(&[1.0, f64::NAN, 1.0, 1.0, 1.0])
        .unwrap()
        .is_none());
    }
    #[test]
    fn one_direction_by_hand_at_a_new_scale() {
        // dirs = d (one column), no exempt, scale0 = s0: V = (d/s0)/||d/s0||
        // and u = V/s0, so weight (S u)(S u)^T has entries
        // weight s_i s_j d_i d_j / (s0_i^2 s0_j^2 ||d/s0||^2) (the sign of
        // the SVD's column cancels).
        let d = [1.0, -2.0, 0.5];
        let s0 = [2.0, 0.5, 1.0];
        let weight = 3.0;
        let pinned = Pinned {
            dirs: Mat::from_fn(3, 1, |i, _| d[i]),
            exempt: Mat::zeros(3, 0),
            weight,
        };
        let basis = pinned.basis(&s0).unwrap().expect("one direction");
        assert_eq!(basis.u.ncols(), 1);
        let n2: f64 = (0..3).map(|i| (d[i] / s0[i]).powi(2)).sum();
        let s = [0.3, 1.5, 0.8];
        let c = basis.scaled_curvature(&s).unwrap();
        for i in 0..3 {
            for j in 0..3 {
                let want =
                    weight * s[i] * s[j] * d[i] * d[j] / (s0[i] * s0[i] * s0[j] * s0[j] * n2);
                assert!((c[(i, j)] - want).abs() <= 1e-14 * want.abs(), "{i} {j}");
            }
        }
        // The gradient at a step x: weight u (u . x), u = d / (s0^2 ||d/s0||).
        let x = [0.7, 0.2, -1.1];
        let u: Vec<f64> = (0..3).map(|i| d[i] / (s0[i] * s0[i] * n2.sqrt())).collect();
        let dot: f64 = (0..3).map(|i| u[i] * x[i]).sum();
        let mut grad = vec![1.0, -1.0, 2.0];
        basis.add_gradient(&x, &mut grad);
        for i in 0..3 {
            let want = [1.0, -1.0, 2.0][i] + weight * u[i] * dot;
            assert!(
                (grad[i] - want).abs() <= 1e-14 * want.abs().max(1.0),
                "{grad:?}"
            );
        }
    }

    #[test]
    fn each_refusal_of_a_basis_alone() {
        let nf = 4;
        let good = Pinned {
            dirs: filled(nf, 2, 0.9),
            exempt: filled(nf, 1, 1.7),
            weight: 1.0,
        };
        let scale0 = vec![1.0; nf];
        assert!(good.basis(&scale0).unwrap().is_some());
        let short_dirs = Pinned {
            dirs: filled(nf - 1, 2, 0.9),
            ..good.clone()
        };
        assert!(short_dirs.basis(&scale0).unwrap().is_none());
        let short_exempt = Pinned {
            exempt: filled(nf + 1, 1, 1.7),
            ..good.clone()
        };
        assert!(short_exempt.basis(&scale0).unwrap().is_none());
        for bad in [0.0, -1.0, f64::INFINITY, f64::NAN] {
            let mut s = scale0.clone();
            s[2] = bad;
            assert!(good.basis(&s).unwrap().is_none(), "{bad}");
        }
    }

    #[test]
    fn repeated_directions_count_once() {
        // Two equal columns and a third that is their double: rank one,
        // the rounding of the SVD is not a direction.
        let nf = 5;
        let one = filled(nf, 1, 0.3);
        let pinned = Pinned {
            dirs: Mat::from_fn(nf, 3, |i, c| one[(i, 0)] * [1.0, 1.0, 2.0][c]),
            exempt: Mat::zeros(nf, 0),
            weight: 1.0,
        };
        let scale0: Vec<f64> = (0..nf).map(|i| 1.0 + i as f64).collect();
        assert_eq!(pinned.basis(&scale0).unwrap().unwrap().u.ncols(), 1);
        // A matrix of zeros has no direction, an empty one none either.
        assert_eq!(
            orthonormal(Mat::<f64>::zeros(3, 2).as_ref(), 0.0)
                .unwrap()
                .unwrap()
                .ncols(),
            0
        );
        let empty = orthonormal(Mat::<f64>::zeros(3, 0).as_ref(), 1.0)
            .unwrap()
            .unwrap();
        assert_eq!((empty.nrows(), empty.ncols()), (3, 0));
        let no_rows = orthonormal(Mat::<f64>::zeros(0, 2).as_ref(), 1.0)
            .unwrap()
            .unwrap();
        assert_eq!((no_rows.nrows(), no_rows.ncols()), (0, 0));
        // A second direction at eps/2 of the largest singular value is
        // dropped below RANK_TOL and kept above it, at any magnitude.
        for size in [1.0, 1e3] {
            for (eps, kept) in [(1e-10, 1), (1e-8, 2)] {
                let m = Mat::from_fn(3, 2, |i, c| match (i, c) {
                    (0, _) => size,
                    (1, 1) => size * eps,
                    _ => 0.0,
                });
                let got = orthonormal(m.as_ref(), 0.0).unwrap().unwrap().ncols();
                assert_eq!(got, kept, "size {size}, eps {eps}");
            }
        }
        // Full rank: every column kept, orthonormal.
        let full = orthonormal(filled(4, 3, 0.2).as_ref(), 0.0)
            .unwrap()
            .unwrap();
        assert_eq!(full.ncols(), 3);
        let gram = full.transpose() * &full;
        for a in 0..3 {
            for b in 0..3 {
                let want = if a == b { 1.0 } else { 0.0 };
                assert!((gram[(a, b)] - want).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn the_basis_is_the_same_to_the_last_bit_on_any_number_of_threads() {
        // Sizes at which the SVD on faer's pool gave other bits on two
        // threads than on one (so did the pinned fits of the positioning
        // stage built on it).
        let nf = 1200;
        let pinned = Pinned {
            dirs: filled(nf, 40, 0.7),
            exempt: filled(nf, 4, 0.1),
            weight: 2.0,
        };
        let scale0: Vec<f64> = (0..nf).map(|i| 1.0 + (i % 7) as f64).collect();
        let on = |threads: usize| {
            crate::testing::on_threads(threads, || {
                pinned.basis(&scale0).unwrap().expect("directions are left")
            })
        };
        let one = on(1);
        assert_eq!(one.u.ncols(), 40);
        for threads in [2, 4] {
            let other = on(threads);
            let differ = (0..40)
                .flat_map(|c| (0..nf).map(move |i| (i, c)))
                .filter(|&(i, c)| one.u[(i, c)].to_bits() != other.u[(i, c)].to_bits())
                .count();
            assert_eq!(differ, 0, "{differ} entries differ on {threads} threads");
        }
    }
}
