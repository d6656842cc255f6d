//! Small dense helpers on faer. Single-threaded where the matrices are a
//! few hundred wide (thread start-up costs more than it saves); kernels of
//! more work ([`par_for`]: the Levenberg-Marquardt step and the cone step's
//! Schur complement at n = 16 and more) use the whole thread pool.
//!
//! No result may depend on the number of threads (the machine's cores, a
//! Dask worker's): every faer call here names its parallelism. faer's own
//! operators (`&a * &b`) and decompositions (`Mat::thin_svd`, ...) run on
//! its global parallelism, every thread of the pool unless told otherwise,
//! and some of them cut their sums by the number of threads: measured
//! (faer 0.21.9, pools of one, two and four threads) a 3000 x 100 matrix
//! times a vector and the thin SVD of a 1000 x 40 matrix differ in the last
//! bits, and so did the pinned l2,1 fits of the positioning stage, whose
//! kept-off directions were made orthonormal by that SVD. Products of two
//! matrices (`gemm`) and the Cholesky factorisation gave the same bits on
//! any number of threads up to 6480 x 200 and 2916 wide, and run on the
//! pool where [`par_for`] says so; the matrix-vector products and the
//! decompositions run on this thread ([`product`], [`thin_svd`],
//! [`symmetric_eigen`]). The Python module also
//! sets faer's global parallelism to one thread when it loads, so that no
//! faer call left to it can bring the thread count back.

use crate::error::Result;
use crate::memory::out_of_memory_for;
use faer::diag::Diag;
use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::evd::{self_adjoint_evd, self_adjoint_evd_scratch, ComputeEigenvectors};
use faer::linalg::matmul::matmul;
use faer::linalg::svd::{svd, svd_scratch, ComputeSvdVectors};
use faer::linalg::triangular_solve::{
    solve_lower_triangular_in_place, solve_upper_triangular_in_place,
};
use faer::{Accum, Mat, MatMut, MatRef, Par};

/// Work (in flops) from which a dense kernel here uses every thread of the
/// pool. Measured on two cores: the Cholesky factorisation 1.4x at 900-1700
/// wide (the LM step at n = 16 2x2 is 1620 wide), 1.5x at 2900, no gain at
/// 600; the Schur complement of a cone step (`W^T W`, 324 x 1296 at n = 16)
/// 1.6x, at n = 24 2.2x. The results are the same to the last bit.
const PARALLEL_FLOPS: f64 = 1.5e8;

/// The parallelism for a kernel of `flops` floating-point operations (on
/// one thread when this thread keeps its loops, [`super::spread::kept_here`]).
pub fn par_for(flops: f64) -> Par {
    if flops >= PARALLEL_FLOPS && !super::spread::kept_here() {
        Par::rayon(0)
    } else {
        Par::Seq
    }
}

/// The scratch space `req` of a faer kernel ([`crate::Error::OutOfMemory`],
/// naming `what`, when it cannot be had).
pub(super) fn scratch(req: StackReq, what: &'static str) -> Result<MemBuffer> {
    MemBuffer::try_new(req).map_err(|_| out_of_memory_for(req.size_bytes(), what))
}

/// Lower Cholesky factor `L` of a symmetric positive definite matrix
/// (`A = L L^T`), or `None` when `A` is not numerically positive definite
/// ([`crate::Error::OutOfMemory`] when the factorisation's scratch space
/// cannot be had).
/// `L` is the lower triangle of the result; the strict upper triangle is
/// left as the factorisation leaves it (the triangular solves below read
/// the lower triangle only; clearing the other half cost a pass over the
/// matrix, 1.3 million writes at n = 16 2x2).
pub fn cholesky(mut a: Mat<f64>) -> Result<Option<Mat<f64>>> {
    Ok(factor_lower(a.as_mut())?.then_some(a))
}

/// [`cholesky`] in place: `a` is overwritten, `L` in its lower triangle
/// (faer's factorisation also writes into the strict upper triangle).
/// False when `a` is not numerically positive definite. faer's
/// factorisation to the last bit, its updates on the AVX-512 kernel where
/// the route runs it ([`super::cholesky`]).
pub fn factor_lower(a: MatMut<'_, f64>) -> Result<bool> {
    let n = a.nrows();
    let par = par_for((n * n * n) as f64 / 3.0);
    super::cholesky::factor(a, super::cholesky::kernel_for_updates(), par)
}

/// `a b` on this thread (see the module's note: a product with one column
/// on faer's pool sums in another order on another number of threads).
pub fn product(a: MatRef<'_, f64>, b: MatRef<'_, f64>) -> Mat<f64> {
    let mut out = Mat::zeros(a.nrows(), b.ncols());
    matmul(out.as_mut(), Accum::Replace, a, b, 1.0, Par::Seq);
    out
}

/// The thin SVD `m = U S V^T` on this thread: `U` (`m.nrows() x k`, `k` the
/// smaller dimension) and the singular values, largest first; `None` when
/// the iteration does not converge ([`crate::Error::OutOfMemory`] when its
/// scratch space cannot be had). As faer's `Mat::thin_svd` on one thread.
pub fn thin_svd(m: MatRef<'_, f64>) -> Result<Option<(Mat<f64>, Vec<f64>)>> {
    let (rows, cols) = m.shape();
    let k = rows.min(cols);
    let mut u = Mat::zeros(rows, k);
    let mut v = Mat::zeros(cols, k);
    let mut s = Diag::zeros(k);
    let thin = ComputeSvdVectors::Thin;
    let req = svd_scratch::<f64>(rows, cols, thin, thin, Par::Seq, Default::default());
    let mut mem = scratch(req, "the scratch space of an SVD")?;
    let done = svd(
        m,
        s.as_mut(),
        Some(u.as_mut()),
        Some(v.as_mut()),
        Par::Seq,
        MemStack::new(&mut mem),
        Default::default(),
    );
    let values = s.column_vector();
    Ok(done.ok().map(|()| (u, (0..k).map(|i| values[i]).collect())))
}

/// The eigendecomposition `m = U diag(lambda) U^T` of a symmetric matrix
/// (its lower triangle is read) on this thread: `U` and the eigenvalues,
/// ascending; `None` when the iteration does not converge
/// ([`crate::Error::OutOfMemory`] when its scratch space cannot be had).
/// As faer's `Mat::self_adjoint_eigen(Side::Lower)` on one thread.
pub fn symmetric_eigen(m: MatRef<'_, f64>) -> Result<Option<(Mat<f64>, Vec<f64>)>> {
    let n = m.nrows();
    let mut u = Mat::zeros(n, n);
    let mut s = Diag::zeros(n);
    let yes = ComputeEigenvectors::Yes;
    let req = self_adjoint_evd_scratch::<f64>(n, yes, Par::Seq, Default::default());
    let mut mem = scratch(req, "the scratch space of an eigendecomposition")?;
    let done = self_adjoint_evd(
        m,
        s.as_mut(),
        Some(u.as_mut()),
        Par::Seq,
        MemStack::new(&mut mem),
        Default::default(),
    );
    let values = s.column_vector();
    Ok(done.ok().map(|()| (u, (0..n).map(|i| values[i]).collect())))
}

/// Solve `L L^T x = b` in place.
pub fn cholesky_solve(l: MatRef<'_, f64>, mut b: MatMut<'_, f64>) {
    solve_lower_triangular_in_place(l, b.as_mut(), Par::Seq);
    solve_upper_triangular_in_place(l.transpose(), b.as_mut(), Par::Seq);
}

/// Solve `L x = b` in place.
pub fn lower_solve(l: &Mat<f64>, b: MatMut<'_, f64>) {
    let par = par_for((l.nrows() * l.nrows() * b.ncols()) as f64);
    solve_lower_triangular_in_place(l.as_ref(), b, par);
}

/// Solve `L^T x = b` in place.
pub fn lower_transpose_solve(l: &Mat<f64>, b: MatMut<'_, f64>) {
    solve_upper_triangular_in_place(l.transpose(), b, Par::Seq);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::on_threads;

    /// The lower triangle of `a`.
    fn lower(a: &Mat<f64>) -> Mat<f64> {
        Mat::from_fn(
            a.nrows(),
            a.ncols(),
            |i, j| if i >= j { a[(i, j)] } else { 0.0 },
        )
    }

    #[test]
    fn cholesky_solves_a_known_system() {
        let a = Mat::from_fn(3, 3, |i, j| if i == j { 4.0 } else { 1.0 });
        let raw = cholesky(a.clone()).unwrap().unwrap();
        let l = lower(&raw);
        let back = &l * l.transpose();
        for i in 0..3 {
            for j in 0..3 {
                assert!((back[(i, j)] - a[(i, j)]).abs() < 1e-14);
            }
        }
        let mut x = Mat::from_fn(3, 1, |i, _| i as f64 + 1.0);
        cholesky_solve(raw.as_ref(), x.as_mut());
        let ax = &a * &x;
        for i in 0..3 {
            assert!((ax[(i, 0)] - (i as f64 + 1.0)).abs() < 1e-13);
        }
        let indefinite = Mat::from_fn(2, 2, |i, j| if i == j { 1.0 } else { 2.0 });
        assert!(cholesky(indefinite).unwrap().is_none());
    }

    /// The factorisation reads the lower triangle only (Newton's method
    /// on the cone step writes only that half of its Hessians): NaN above
    /// the diagonal gives the same factor, bit for bit, on one thread and
    /// (at 800 wide, above [`PARALLEL_FLOPS`]) on the pool.
    #[test]
    fn the_factorisation_reads_the_lower_triangle_only() {
        for n in [60, 800] {
            let mut rng = crate::testing::Lcg(9);
            let b = Mat::from_fn(n, n + 5, |_, _| rng.next_f64());
            let a = &b * b.transpose();
            let mut half = a.clone();
            for j in 0..n {
                for i in 0..j {
                    half[(i, j)] = f64::NAN;
                }
            }
            let whole = cholesky(a).unwrap().unwrap();
            let from_half = cholesky(half).unwrap().unwrap();
            for j in 0..n {
                for i in j..n {
                    let (x, y) = (whole[(i, j)], from_half[(i, j)]);
                    assert_eq!(x.to_bits(), y.to_bits(), "n {n} ({i}, {j})");
                }
            }
        }
    }

    #[test]
    fn the_solves_read_the_lower_triangle_only() {
        // Wide enough for faer's blocked solves, not only their small cases.
        let n = 300;
        let mut rng = crate::testing::Lcg(5);
        let b = Mat::from_fn(n, n + 10, |_, _| rng.next_f64());
        let raw = cholesky(&b * b.transpose()).unwrap().unwrap();
        let l = lower(&raw);
        let rhs = Mat::from_fn(n, 2, |_, _| rng.next_f64());
        let solved = |f: &Mat<f64>, which: usize| {
            let mut x = rhs.clone();
            match which {
                0 => cholesky_solve(f.as_ref(), x.as_mut()),
                1 => lower_solve(f, x.as_mut()),
                _ => lower_transpose_solve(f, x.as_mut()),
            }
            x
        };
        for which in 0..3 {
            let (x, y) = (solved(&raw, which), solved(&l, which));
            for j in 0..2 {
                for i in 0..n {
                    assert_eq!(x[(i, j)].to_bits(), y[(i, j)].to_bits(), "solve {which}");
                }
            }
        }
    }

    fn same_bits(a: &Mat<f64>, b: &Mat<f64>) -> bool {
        a.shape() == b.shape()
            && (0..a.ncols())
                .all(|j| (0..a.nrows()).all(|i| a[(i, j)].to_bits() == b[(i, j)].to_bits()))
    }

    #[test]
    fn products_and_svds_are_the_same_to_the_last_bit_on_any_number_of_threads() {
        // Sizes at which faer's operator and `Mat::thin_svd` on its pool
        // gave other bits on two threads than on one.
        let mut rng = crate::testing::Lcg(5);
        let a = Mat::from_fn(3000, 100, |_, _| rng.next_f64());
        let x = Mat::from_fn(100, 1, |_, _| rng.next_f64());
        let tall = Mat::from_fn(1000, 40, |_, _| rng.next_f64());
        let half = Mat::from_fn(400, 400, |_, _| rng.next_f64());
        let sym = &half + half.transpose();
        let run = || {
            let (u, s) = thin_svd(tall.as_ref()).unwrap().unwrap();
            let eig = symmetric_eigen(sym.as_ref()).unwrap().unwrap();
            (product(a.as_ref(), x.as_ref()), u, s, eig)
        };
        let (ax, u, s, (q, lambda)) = on_threads(1, run);
        for threads in [2, 4] {
            let (ax_t, u_t, s_t, (q_t, lambda_t)) = on_threads(threads, run);
            assert!(same_bits(&ax, &ax_t), "A x on {threads} threads");
            assert!(same_bits(&u, &u_t), "U on {threads} threads");
            assert_eq!(s, s_t, "singular values on {threads} threads");
            assert!(same_bits(&q, &q_t), "eigenvectors on {threads} threads");
            assert_eq!(lambda, lambda_t, "eigenvalues on {threads} threads");
        }
        // The eigendecomposition: ascending, Q diag(lambda) Q^T = M.
        assert!(lambda.windows(2).all(|w| w[0] <= w[1]));
        let ql = Mat::from_fn(400, 400, |i, k| q[(i, k)] * lambda[k]);
        let back = &ql * q.transpose();
        for j in 0..400 {
            for i in 0..400 {
                assert!((back[(i, j)] - sym[(i, j)]).abs() < 1e-11, "({i}, {j})");
            }
        }
        // And right: A x as a plain sum; U orthonormal, the singular values
        // falling, and the rows of U^T M (= S V^T) of norms S.
        for i in 0..3000 {
            let want: f64 = (0..100).map(|k| a[(i, k)] * x[(k, 0)]).sum();
            assert!((ax[(i, 0)] - want).abs() < 1e-12, "row {i}");
        }
        assert_eq!(u.shape(), (1000, 40));
        let utu = u.transpose() * &u;
        let utm = u.transpose() * &tall;
        for k in 0..40 {
            for l in 0..40 {
                let id = if k == l { 1.0 } else { 0.0 };
                assert!((utu[(k, l)] - id).abs() < 1e-12, "U^T U ({k}, {l})");
            }
            assert!(k == 0 || s[k] <= s[k - 1]);
            let row = (0..40).map(|j| utm[(k, j)].powi(2)).sum::<f64>().sqrt();
            assert!((row - s[k]).abs() < 1e-12 * s[0], "singular value {k}");
        }
    }

    #[test]
    fn a_wide_factor_is_the_same_to_the_last_bit_on_one_thread_and_two() {
        let n = 900;
        let mut rng = crate::testing::Lcg(3);
        let b = Mat::from_fn(n, n + 10, |_, _| rng.next_f64());
        let a = &b * b.transpose();
        let on = |threads: usize| on_threads(threads, || cholesky(a.clone()).unwrap().unwrap());
        let (one, two) = (on(1), on(2));
        let differ = (0..n)
            .flat_map(|j| (0..n).map(move |i| (i, j)))
            .filter(|&(i, j)| one[(i, j)].to_bits() != two[(i, j)].to_bits())
            .count();
        assert_eq!(differ, 0, "{differ} entries differ");
        let one = lower(&one);
        let back = &one * one.transpose();
        let err = (0..n)
            .flat_map(|j| (0..n).map(move |i| (i, j)))
            .map(|(i, j)| (back[(i, j)] - a[(i, j)]).abs())
            .fold(0.0f64, f64::max);
        assert!(err < 1e-9 * n as f64, "L L^T - A: {err}");
    }
}
