//! Tests of [`crate::base::cholesky`].

use super::*;
use crate::testing::{on_threads, spd_matrix as spd};
use faer::Mat;

/// faer's own factorisation, on this thread.
fn faers(a: &Mat<f64>) -> (Mat<f64>, bool) {
    let mut l = a.clone();
    let ok = factor(l.as_mut(), None, Par::Seq).expect("scratch");
    (l, ok)
}

fn assert_same_lower(got: &Mat<f64>, want: &Mat<f64>, what: &str) {
    let n = want.nrows();
    for j in 0..n {
        for i in j..n {
            assert_eq!(
                got[(i, j)].to_bits(),
                want[(i, j)].to_bits(),
                "{what}: ({i}, {j}) of {n}: {} against faer's {}",
                got[(i, j)],
                want[(i, j)]
            );
        }
    }
}

#[test]
fn every_kernel_gives_faers_factor_to_the_last_bit() {
    // Sizes at and around faer's unblocked limit (64), its block (128), the
    // update's diagonal blocks (16) and FAER_ENTRIES, several blocks with a
    // short last one, and rectangles wider than COLUMNS (at 1100 the first
    // update's is 486 wide).
    for n in [1, 16, 17, 64, 65, 100, 128, 129, 257, 300, 531, 1100] {
        let a = spd(n, 0.37 * n as f64);
        let (want, ok) = faers(&a);
        assert!(ok, "{n}");
        for kernel in [Kernel::Plain, Kernel::Avx2, Kernel::Avx512] {
            let mut got = a.clone();
            assert!(factor(got.as_mut(), Some(kernel), Par::Seq).expect("scratch"));
            assert_same_lower(&got, &want, &format!("{kernel:?}"));
        }
    }
}

#[test]
fn on_a_pool_the_factor_is_the_same() {
    // Large enough that the update's halves run side by side.
    for n in [300, 700] {
        let a = spd(n, 1.1);
        let (want, _) = faers(&a);
        for kernel in [Kernel::Avx2, Kernel::Avx512] {
            let mut got = a.clone();
            let ok = on_threads(3, || factor(got.as_mut(), Some(kernel), Par::rayon(0)));
            assert!(ok.expect("scratch"));
            assert_same_lower(&got, &want, &format!("{kernel:?} on 3 threads"));
        }
    }
}

#[test]
fn the_factor_is_the_matrix_and_a_pivot_below_zero_is_said() {
    let n = 257;
    let a = spd(n, 2.0);
    let mut l = a.clone();
    assert!(factor(l.as_mut(), Some(Kernel::best()), Par::Seq).expect("scratch"));
    // L L^T against A, relative to A's largest entry.
    let lower = Mat::from_fn(n, n, |i, j| if i >= j { l[(i, j)] } else { 0.0 });
    let mut back = Mat::zeros(n, n);
    matmul(
        back.as_mut(),
        Accum::Replace,
        lower.as_ref(),
        lower.transpose(),
        1.0,
        Par::Seq,
    );
    let scale = (0..n).map(|i| a[(i, i)]).fold(0.0f64, f64::max);
    for j in 0..n {
        for i in 0..n {
            assert!(
                (back[(i, j)] - a[(i, j)]).abs() <= 1e-12 * scale,
                "({i}, {j})"
            );
        }
    }
    // Not positive definite past the first block: both say so.
    let mut bad = a.clone();
    bad[(200, 200)] = -bad[(200, 200)];
    let (_, ok) = faers(&bad);
    assert!(!ok);
    for kernel in [Kernel::Plain, Kernel::Avx512] {
        let mut got = bad.clone();
        assert!(!factor(got.as_mut(), Some(kernel), Par::Seq).expect("scratch"));
    }
}

#[test]
fn factor_lower_is_faers_on_this_route() {
    // Whatever route this processor (or LPVID_KERNEL) takes.
    let a = spd(531, 0.9);
    let (want, _) = faers(&a);
    let mut got = a.clone();
    assert!(crate::base::dense::factor_lower(got.as_mut()).expect("scratch"));
    assert_same_lower(&got, &want, &format!("{:?}", kernel_for_updates()));
}
