//! Tests of [`crate::base::gram_product`].

use super::*;
use faer::Mat;

/// A deterministic, irregular row-major `rows x stride` matrix.
fn filled(rows: usize, stride: usize, seed: f64) -> Vec<f64> {
    (0..rows * stride)
        .map(|i| ((i * i % 97) as f64 * 0.731 + seed).sin() * (1.0 + (i % 7) as f64))
        .collect()
}

fn start(m: usize, p: usize) -> Mat<f64> {
    Mat::from_fn(m, p, |i, j| ((i * 3 + j * 5) as f64 * 0.17).cos())
}

/// Every entry's bits, column by column.
fn bits(x: &Mat<f64>) -> Vec<u64> {
    (0..x.ncols())
        .flat_map(|j| (0..x.nrows()).map(move |i| x[(i, j)].to_bits()))
        .collect()
}

/// `c += v u^T` over `samples` by `kernel`, with a scratch of NaNs: a
/// kernel that read its scratch before writing it would show.
fn add_product(
    kernel: Kernel,
    c: MatMut<'_, f64>,
    v: &[f64],
    u: &[f64],
    stride: usize,
    samples: Samples,
) {
    let mut scratch = vec![f64::NAN; scratch_len(c.ncols(), samples.total())];
    gram_product_with(kernel, c, Accum::Add, v, u, stride, samples, &mut scratch);
}

#[test]
fn every_kernel_gives_the_plain_loops_bits() {
    // Sizes off every block size, the samples fewer than the stride.
    // Samples left over past whole fours (37, 9) and fewer than the next
    // four (6): the packing's registers take fours only.
    for (m, p, stride, k) in [
        (1, 1, 1, 1),
        (17, 13, 40, 37),
        (35, 26, 9, 9),
        (9, 7, 8, 6),
        (8, 6, 5, 0),
    ] {
        let (v, u) = (filled(m, stride, 0.3), filled(p, stride, 1.9));
        let mut want = start(m, p);
        plain(want.as_mut(), true, &v, &u, stride, Samples::first(k));
        for kernel in [Kernel::Plain, Kernel::Avx2, Kernel::Avx512] {
            let mut got = start(m, p);
            add_product(kernel, got.as_mut(), &v, &u, stride, Samples::first(k));
            assert_eq!(bits(&got), bits(&want), "{kernel:?} {m} x {p}, k {k}");
        }
    }
}

/// A kernel the processor runs is never refused (its products would go on
/// the plain loop: the same bits, at a fraction of the speed), and one it
/// does not run is never taken (an illegal instruction).
#[test]
fn the_kernels_available_are_those_the_processor_runs() {
    assert!(Kernel::Plain.available());
    #[cfg(target_arch = "x86_64")]
    {
        let avx2 = std::arch::is_x86_feature_detected!("avx2")
            && std::arch::is_x86_feature_detected!("fma");
        let avx512 = avx2 && std::arch::is_x86_feature_detected!("avx512f");
        assert_eq!(Kernel::Avx2.available(), avx2);
        assert_eq!(Kernel::Avx512.available(), avx512);
    }
    #[cfg(not(target_arch = "x86_64"))]
    assert!(!Kernel::Avx2.available() && !Kernel::Avx512.available());
}

/// Only a `C` whose columns are contiguous is written in place, block by
/// block: a transposed one (its rows contiguous) gets its sums through the
/// block buffer, the same bits in their places.
#[test]
fn a_transposed_c_gets_the_same_bits_in_their_places() {
    let (m, p, stride, k) = (37, 29, 40, 40);
    let (v, u) = (filled(m, stride, 0.3), filled(p, stride, 1.9));
    for kernel in [Kernel::Plain, Kernel::Avx2, Kernel::Avx512] {
        let mut want = start(m, p);
        let product =
            |c: MatMut<'_, f64>| add_product(kernel, c, &v, &u, stride, Samples::first(k));
        product(want.as_mut());
        let mut rows = start(m, p).transpose().to_owned();
        product(rows.as_mut().transpose_mut());
        assert_eq!(
            bits(&rows.transpose().to_owned()),
            bits(&want),
            "{kernel:?}"
        );
    }
}

#[test]
fn the_plain_loop_is_the_product_and_fuses_each_step() {
    // Against faer's product to rounding, on sizes off the blocks.
    let (m, p, stride, k) = (23, 19, 50, 47);
    let (v, u) = (filled(m, stride, 0.7), filled(p, stride, 2.3));
    let mut got = start(m, p);
    gram_product(
        got.as_mut(),
        Accum::Add,
        &v,
        &u,
        stride,
        k,
        &mut vec![0.0; scratch_len(p, k)],
    );
    let vm = Mat::from_fn(m, k, |i, s| v[i * stride + s]);
    let um = Mat::from_fn(p, k, |j, s| u[j * stride + s]);
    let want = start(m, p) + &vm * um.transpose();
    for j in 0..p {
        for i in 0..m {
            let scale: f64 = (0..k).map(|s| (vm[(i, s)] * um[(j, s)]).abs()).sum();
            assert!((got[(i, j)] - want[(i, j)]).abs() <= 1e-14 * (scale + 1.0));
        }
    }
    // One entry whose products cancel: -y + x x with y the rounded
    // square, fused, is the rounding error of x x (0 unfused).
    let x = 0.1f64;
    let (v1, u1) = (vec![-1.0, x], vec![x * x, x]);
    let mut c = Mat::<f64>::zeros(1, 1);
    gram_product_with(
        Kernel::best(),
        c.as_mut(),
        Accum::Add,
        &v1,
        &u1,
        2,
        Samples::first(2),
        &mut vec![0.0; scratch_len(1, 2)],
    );
    assert_eq!(c[(0, 0)], x.mul_add(x, -(x * x)));
    assert_ne!(c[(0, 0)], 0.0);
}

/// A product never reads a sample past the stride: the runs' end is where
/// the check looks, and a product whose runs end past it is refused.
#[test]
fn runs_of_samples_end_after_their_last_sample_and_not_past_the_stride() {
    let runs = |first, count| Samples {
        first,
        step: 12,
        len: 4,
        count,
    };
    assert_eq!(runs(3, 8).end(), 3 + 7 * 12 + 4);
    assert_eq!(runs(3, 1).end(), 7);
    assert_eq!(runs(3, 0).end(), 0);
    assert_eq!(Samples::first(5).end(), 5);
    let past = |samples: Samples, stride: usize| {
        let (v, u) = (filled(17, stride, 0.3), filled(13, stride, 1.9));
        let mut c = start(17, 13);
        std::panic::catch_unwind(move || {
            add_product(Kernel::Plain, c.as_mut(), &v, &u, stride, samples)
        })
        .is_err()
    };
    assert!(!past(runs(3, 8), 91));
    assert!(past(runs(3, 8), 90));
    assert!(!past(runs(200, 0), 91));
}

#[test]
fn a_product_over_runs_of_samples_leaves_out_only_their_zero_products() {
    // U's rows zero off every third run of four samples (as a rank-one
    // side's entries are off its own output): the product over that
    // run alone has the whole product's bits on every kernel; over
    // other runs, or with a run's zero sample filled in, it does not.
    let (m, p, stride) = (37, 29, 96);
    let runs = |first| Samples {
        first,
        step: 12,
        len: 4,
        count: 8,
    };
    let v = filled(m, stride, 0.4);
    let mut u = filled(p, stride, 1.1);
    for row in u.chunks_mut(stride) {
        for (s, x) in row.iter_mut().enumerate() {
            if !runs(4).iter().any(|t| t == s) {
                *x = if s % 2 == 0 { 0.0 } else { -0.0 };
            }
        }
    }
    let mut whole = start(m, p);
    plain(whole.as_mut(), true, &v, &u, stride, Samples::first(stride));
    for kernel in [Kernel::Plain, Kernel::Avx2, Kernel::Avx512] {
        let product = |u: &[f64], samples: Samples| {
            let mut got = start(m, p);
            add_product(kernel, got.as_mut(), &v, u, stride, samples);
            bits(&got)
        };
        assert_eq!(product(&u, runs(4)), bits(&whole), "{kernel:?}");
        assert_ne!(product(&u, runs(0)), bits(&whole), "{kernel:?}");
        let mut one_more = u.clone();
        one_more[2] = 0.5;
        let mut want = start(m, p);
        plain(
            want.as_mut(),
            true,
            &v,
            &one_more,
            stride,
            Samples::first(stride),
        );
        assert_ne!(product(&one_more, runs(4)), bits(&want), "{kernel:?}");
    }
}

#[test]
fn small_products_run_on_faer_and_larger_ones_on_the_kernels() {
    // At most FAER_ENTRIES entries: faer's bits (its dot-product
    // kernels sum in another order than the plain loop, so each side
    // of the line tells which ran); one more row or column: the loop's.
    let (stride, k) = (260, 256);
    for (m, p) in [(16, 16), (4, 64), (3, 85), (16, 17), (5, 52), (2, 129)] {
        let (v, u) = (filled(m, stride, 0.3), filled(p, stride, 1.9));
        let mut got = start(m, p);
        let mut scratch = vec![f64::NAN; scratch_len(p, k)];
        gram_product(got.as_mut(), Accum::Add, &v, &u, stride, k, &mut scratch);
        let mut loop_bits = start(m, p);
        plain(loop_bits.as_mut(), true, &v, &u, stride, Samples::first(k));
        let mut faer_bits = start(m, p);
        let vm = MatRef::from_row_major_slice(&v, m, stride).get(.., ..k);
        let um = MatRef::from_row_major_slice(&u, p, stride).get(.., ..k);
        matmul(
            faer_bits.as_mut(),
            Accum::Add,
            vm,
            um.transpose(),
            1.0,
            Par::Seq,
        );
        let want = if m * p <= FAER_ENTRIES {
            &faer_bits
        } else {
            &loop_bits
        };
        let other = if m * p <= FAER_ENTRIES {
            &loop_bits
        } else {
            &faer_bits
        };
        assert_eq!(bits(&got), bits(want), "{m} x {p}");
        if m * p <= FAER_ENTRIES {
            assert_ne!(bits(&got), bits(other), "{m} x {p}: the orders agree here");
        }
    }
}

#[test]
fn replacing_c_is_adding_to_zeros_whatever_c_held() {
    // On every kernel and on faer, sizes off the blocks (whole blocks in
    // place, the others through the block buffer), no sample at all too:
    // the sums written over a C of NaNs have the bits of the sums added to
    // a C of zeros.
    for (m, p, stride, k) in [
        (37, 29, 40, 36),
        (16, 12, 8, 8),
        (5, 40, 9, 9),
        (9, 31, 4, 0),
    ] {
        let (v, u) = (filled(m, stride, 0.2), filled(p, stride, 2.9));
        let mut scratch = vec![f64::NAN; scratch_len(p, k)];
        let samples = Samples::first(k);
        for kernel in [Kernel::Plain, Kernel::Avx2, Kernel::Avx512] {
            let mut want = Mat::<f64>::zeros(m, p);
            let (w, s) = (want.as_mut(), &mut scratch);
            gram_product_with(kernel, w, Accum::Add, &v, &u, stride, samples, s);
            let mut got = Mat::from_fn(m, p, |_, _| f64::NAN);
            let (g, s) = (got.as_mut(), &mut scratch);
            gram_product_with(kernel, g, Accum::Replace, &v, &u, stride, samples, s);
            assert_eq!(bits(&got), bits(&want), "{kernel:?} {m} x {p}, k {k}");
        }
        let mut want = Mat::<f64>::zeros(m, p);
        gram_product(want.as_mut(), Accum::Add, &v, &u, stride, k, &mut scratch);
        let mut got = Mat::from_fn(m, p, |_, _| f64::NAN);
        gram_product(
            got.as_mut(),
            Accum::Replace,
            &v,
            &u,
            stride,
            k,
            &mut scratch,
        );
        assert_eq!(bits(&got), bits(&want), "{m} x {p}, k {k}");
    }
}
