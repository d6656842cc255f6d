//! Small dense helpers on faer, single-threaded: the matrices of one step
//! are a few hundred wide, where thread start-up costs more than it saves.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::{cholesky_in_place, cholesky_in_place_scratch};
use faer::linalg::triangular_solve::{
    solve_lower_triangular_in_place, solve_upper_triangular_in_place,
};
use faer::{Mat, MatMut, Par};

/// Lower Cholesky factor `L` of a symmetric positive definite matrix
/// (`A = L L^T`), or `None` when `A` is not numerically positive definite.
pub fn cholesky(mut a: Mat<f64>) -> Option<Mat<f64>> {
    let n = a.nrows();
    let mut mem = MemBuffer::new(cholesky_in_place_scratch::<f64>(
        n,
        Par::Seq,
        Default::default(),
    ));
    let stack = MemStack::new(&mut mem);
    cholesky_in_place(
        a.as_mut(),
        Default::default(),
        Par::Seq,
        stack,
        Default::default(),
    )
    .ok()?;
    for j in 0..n {
        for i in 0..j {
            a[(i, j)] = 0.0;
        }
    }
    Some(a)
}

/// Solve `L L^T x = b` in place.
pub fn cholesky_solve(l: &Mat<f64>, mut b: MatMut<'_, f64>) {
    solve_lower_triangular_in_place(l.as_ref(), b.as_mut(), Par::Seq);
    solve_upper_triangular_in_place(l.transpose(), b.as_mut(), Par::Seq);
}

/// Solve `L x = b` in place.
pub fn lower_solve(l: &Mat<f64>, b: MatMut<'_, f64>) {
    solve_lower_triangular_in_place(l.as_ref(), b, Par::Seq);
}

/// Solve `L^T x = b` in place.
pub fn lower_transpose_solve(l: &Mat<f64>, b: MatMut<'_, f64>) {
    solve_upper_triangular_in_place(l.transpose(), b, Par::Seq);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cholesky_solves_a_known_system() {
        let a = Mat::from_fn(3, 3, |i, j| if i == j { 4.0 } else { 1.0 });
        let l = cholesky(a.clone()).unwrap();
        let back = &l * l.transpose();
        for i in 0..3 {
            for j in 0..3 {
                assert!((back[(i, j)] - a[(i, j)]).abs() < 1e-14);
            }
        }
        let mut x = Mat::from_fn(3, 1, |i, _| i as f64 + 1.0);
        cholesky_solve(&l, x.as_mut());
        let ax = &a * &x;
        for i in 0..3 {
            assert!((ax[(i, 0)] - (i as f64 + 1.0)).abs() < 1e-13);
        }
        let indefinite = Mat::from_fn(2, 2, |i, j| if i == j { 1.0 } else { 2.0 });
        assert!(cholesky(indefinite).is_none());
    }
}
