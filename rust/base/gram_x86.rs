//! The x86 kernels of [`super`] (a submodule in its own file): the
//! register blocks of AVX-512F and of AVX2 with FMA, and the AVX2 transpose
//! that packs four rows at a time.

use super::{MR_256, MR_512, NR_256, NR_512};
use std::arch::x86_64::*;

/// A kernel on one register width: `out[jj * ld + ii] += sum_s
/// vp[s * mr + ii] up[s * nr + jj]` (`=` with `add` false), each sum
/// from zero with one fused multiply-add per sample in order, `mr` rows
/// as two registers of `half` doubles.
macro_rules! block_kernel {
    ($(#[$doc:meta])* $name:ident, $feature:literal, $mr:ident, $nr:ident, $half:literal,
     $zero:ident, $load:ident, $store:ident, $splat:ident, $fma:ident, $add:ident) => {
        $(#[$doc])*
        #[target_feature(enable = $feature)]
        pub unsafe fn $name(
            vp: &[f64],
            up: &[f64],
            k: usize,
            out: *mut f64,
            ld: usize,
            add: bool,
        ) {
            debug_assert!(vp.len() >= $mr * k && up.len() >= $nr * k);
            let mut acc = [[$zero(); 2]; $nr];
            let (a, b) = (vp.as_ptr(), up.as_ptr());
            for s in 0..k {
                let a0 = $load(a.add(s * $mr));
                let a1 = $load(a.add(s * $mr + $half));
                for (jj, pair) in acc.iter_mut().enumerate() {
                    let bj = $splat(*b.add(s * $nr + jj));
                    pair[0] = $fma(a0, bj, pair[0]);
                    pair[1] = $fma(a1, bj, pair[1]);
                }
            }
            for (jj, pair) in acc.iter().enumerate() {
                let col = out.add(jj * ld);
                let top = col.add($half);
                if add {
                    $store(col, $add($load(col), pair[0]));
                    $store(top, $add($load(top), pair[1]));
                } else {
                    $store(col, pair[0]);
                    $store(top, pair[1]);
                }
            }
        }
    };
}

/// Four rows of `x` (`stride` apart, from the first) into columns
/// `q..q + 4` of a `width`-wide panel, samples `0..k` (`k` a multiple
/// of four): `panel[s * width + q + i] = x[i * stride + s]`.
///
/// # Safety
/// The processor must run AVX2; `x` holds `3 stride + k` values and
/// `panel` `k width`, `q + 4 <= width`.
#[target_feature(enable = "avx2")]
pub unsafe fn transpose4(
    panel: &mut [f64],
    x: &[f64],
    stride: usize,
    k: usize,
    q: usize,
    width: usize,
) {
    assert!(k.is_multiple_of(4) && q + 4 <= width && panel.len() >= k * width);
    assert!(k == 0 || x.len() >= 3 * stride + k);
    let (src, dst) = (x.as_ptr(), panel.as_mut_ptr());
    for s in (0..k).step_by(4) {
        let r0 = _mm256_loadu_pd(src.add(s));
        let r1 = _mm256_loadu_pd(src.add(stride + s));
        let r2 = _mm256_loadu_pd(src.add(2 * stride + s));
        let r3 = _mm256_loadu_pd(src.add(3 * stride + s));
        let (t0, t1) = (_mm256_unpacklo_pd(r0, r1), _mm256_unpackhi_pd(r0, r1));
        let (t2, t3) = (_mm256_unpacklo_pd(r2, r3), _mm256_unpackhi_pd(r2, r3));
        let at = dst.add(s * width + q);
        _mm256_storeu_pd(at, _mm256_permute2f128_pd(t0, t2, 0x20));
        _mm256_storeu_pd(at.add(width), _mm256_permute2f128_pd(t1, t3, 0x20));
        _mm256_storeu_pd(at.add(2 * width), _mm256_permute2f128_pd(t0, t2, 0x31));
        _mm256_storeu_pd(at.add(3 * width), _mm256_permute2f128_pd(t1, t3, 0x31));
    }
}

block_kernel!(
    /// The kernel in 16 x 12 blocks.
    ///
    /// # Safety
    /// The processor must run AVX-512F; `vp` holds `16 k` and `up` `12 k`
    /// values, and `out` is a `16 x 12` block with columns `ld` apart.
    block_512, "avx512f", MR_512, NR_512, 8,
    _mm512_setzero_pd, _mm512_loadu_pd, _mm512_storeu_pd, _mm512_set1_pd, _mm512_fmadd_pd,
    _mm512_add_pd
);

block_kernel!(
    /// The kernel in 8 x 6 blocks.
    ///
    /// # Safety
    /// The processor must run AVX2 and FMA; `vp` holds `8 k` and `up` `6 k`
    /// values, and `out` is an `8 x 6` block with columns `ld` apart.
    block_256, "avx2,fma", MR_256, NR_256, 4,
    _mm256_setzero_pd, _mm256_loadu_pd, _mm256_storeu_pd, _mm256_set1_pd, _mm256_fmadd_pd,
    _mm256_add_pd
);
