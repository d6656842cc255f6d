//! The initial states: their least-squares estimate and their exact
//! elimination from the Gauss-Newton matrix.
//!
//! The outputs are linear in `x(0)`, so for fixed `theta` the best initial
//! state solves `min ||r0 + Jx x0||^2` (`r0` the residual from rest, `Jx`
//! the weighted free response). With `G = J^T J` over `[theta, x0]`, the
//! reduced problem in `theta` alone has the gradient `g_t - G_tx G_xx^+ g_x`
//! and the Gauss-Newton matrix `G_tt - G_tx G_xx^+ G_xt` (the Schur
//! complement; Kaufman's form of variable projection). Directions of `x0`
//! that the record cannot see (eigenvalues of `G_xx` below `1e-12` of the
//! largest) are left at zero.

use super::sensitivity::Normal;
use crate::base::dense::symmetric_eigen;
use crate::error::{Error, Result};
use crate::memory::try_vec;
use faer::Mat;

/// Eigenvalues below this fraction of the largest count as zero.
const RELATIVE_RANK: f64 = 1e-12;

/// `W` with `W W^T = G^+` for a symmetric positive semi-definite `g`
/// (`k x k` column-major): `U diag(1 / sqrt(lambda))` over the eigenvalues kept.
fn pinv_root(g: &[f64], k: usize) -> Result<Mat<f64>> {
    let m = Mat::from_fn(k, k, |i, j| g[i + j * k]);
    let Some((u, s)) = symmetric_eigen(m.as_ref())? else {
        return Err(Error::Numerical(
            "eigenvalues of the initial-state Gram matrix: the iteration did not converge".into(),
        ));
    };
    let largest = s.iter().copied().fold(0.0f64, f64::max);
    let kept: Vec<usize> = (0..k)
        .filter(|&i| s[i] > RELATIVE_RANK * largest && s[i] > 0.0)
        .collect();
    Ok(Mat::from_fn(k, kept.len(), |i, j| {
        u[(i, kept[j])] / s[kept[j]].sqrt()
    }))
}

/// The minimum-norm least-squares initial state from the Gram matrix and
/// `J^T r0` of the initial-state columns: `x0 = -G^+ J^T r0`.
pub(crate) fn estimate(normal: &Normal) -> Result<Vec<f64>> {
    let k = normal.k;
    let w = pinv_root(&normal.gram, k)?;
    // W^T b, then -W (W^T b).
    let wb: Vec<f64> = (0..w.ncols())
        .map(|j| (0..k).map(|i| w[(i, j)] * normal.jtr[i]).sum())
        .collect();
    Ok((0..k)
        .map(|i| -(0..w.ncols()).map(|j| w[(i, j)] * wb[j]).sum::<f64>())
        .collect())
}

/// Eliminate the columns at positions `initial` (engine order) from
/// `normal`: the Schur complement of their block. Returns `J^T r` and
/// `J^T J` over the other columns, in their order.
pub(crate) fn eliminate(normal: &Normal, initial: &[usize]) -> Result<(Vec<f64>, Vec<f64>)> {
    let k = normal.k;
    let kept: Vec<usize> = (0..k).filter(|q| !initial.contains(q)).collect();
    let (p, nx) = (kept.len(), initial.len());
    let g = |i: usize, j: usize| normal.gram[i + j * k];
    let gxx: Vec<f64> = (0..nx * nx)
        .map(|e| g(initial[e % nx], initial[e / nx]))
        .collect();
    let w = pinv_root(&gxx, nx)?;
    // V = G_tx W (p x rank); reduced G = G_tt - V V^T, g = g_t - V W^T g_x.
    let rank = w.ncols();
    let v = Mat::from_fn(p, rank, |a, j| {
        (0..nx)
            .map(|b| g(kept[a], initial[b]) * w[(b, j)])
            .sum::<f64>()
    });
    let wg: Vec<f64> = (0..rank)
        .map(|j| (0..nx).map(|b| w[(b, j)] * normal.jtr[initial[b]]).sum())
        .collect();
    let jtr = (0..p)
        .map(|a| normal.jtr[kept[a]] - (0..rank).map(|j| v[(a, j)] * wg[j]).sum::<f64>())
        .collect();
    let mut gram = try_vec(p * p, 0.0, "the Gauss-Newton matrix of a time record")?;
    for b in 0..p {
        for a in b..p {
            let vv: f64 = (0..rank).map(|j| v[(a, j)] * v[(b, j)]).sum();
            let x = g(kept[a], kept[b]) - vv;
            gram[a + b * p] = x;
            gram[b + a * p] = x;
        }
    }
    Ok((jtr, gram))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn schur_complement_of_a_known_matrix() {
        // G = [[4, 1, 2], [1, 3, 0], [2, 0, 2]], eliminate the last column.
        let g = vec![4.0, 1.0, 2.0, 1.0, 3.0, 0.0, 2.0, 0.0, 2.0];
        let normal = Normal {
            k: 3,
            gram: g,
            jtr: vec![1.0, 2.0, 4.0],
        };
        let (b, h) = eliminate(&normal, &[2]).unwrap();
        // G_tt - G_tx G_xt / 2 = [[4 - 2, 1], [1, 3]]; g_t - G_tx 4 / 2.
        let want_h = [2.0, 1.0, 1.0, 3.0];
        for (x, y) in h.iter().zip(want_h) {
            assert!((x - y).abs() < 1e-13, "{x} vs {y}");
        }
        assert!((b[0] - (1.0 - 4.0)).abs() < 1e-13 && (b[1] - 2.0).abs() < 1e-13);
        // The estimate of the last column alone: -4 / 2.
        let x = estimate(&Normal {
            k: 1,
            gram: vec![2.0],
            jtr: vec![4.0],
        })
        .unwrap();
        assert!((x[0] + 2.0).abs() < 1e-14);
    }

    #[test]
    fn unseen_directions_are_left_out() {
        // The second initial state does not show in the outputs.
        let normal = Normal {
            k: 2,
            gram: vec![2.0, 0.0, 0.0, 0.0],
            jtr: vec![4.0, 0.0],
        };
        let x = estimate(&normal).unwrap();
        assert!((x[0] + 2.0).abs() < 1e-14 && x[1].abs() < 1e-14);
    }
}
