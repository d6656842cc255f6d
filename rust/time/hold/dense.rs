//! Small dense kernels of the hold: row-major matrices with a row stride
//! `w` padded to a multiple of 4 (products four columns at a time), an
//! LU factorisation with partial pivoting and its solve, norms.

// Small matrix kernels index several arrays at once; an index reads best.
#![allow(clippy::needless_range_loop)]

/// `a b + c`, fused where the build targets a processor with FMA (the
/// default build does; elsewhere `mul_add` is a slow library call).
#[inline(always)]
pub(super) fn fma(a: f64, b: f64, c: f64) -> f64 {
    if cfg!(target_feature = "fma") {
        a.mul_add(b, c)
    } else {
        a * b + c
    }
}

/// `out = coef src` (`+=` when `add`): the row vector `coef` times the
/// matrix whose row `k` starts at `src[k * stride]`; `out.len()` is a
/// multiple of 4 and at most `stride`.
#[inline(always)]
pub(super) fn row_times(coef: &[f64], src: &[f64], stride: usize, out: &mut [f64], add: bool) {
    for (o, chunk) in out.chunks_exact_mut(4).enumerate() {
        let mut acc = [0.0; 4];
        if add {
            acc.copy_from_slice(chunk);
        }
        for (k, &c) in coef.iter().enumerate() {
            let v = &src[k * stride + 4 * o..k * stride + 4 * o + 4];
            for i in 0..4 {
                acc[i] = fma(c, v[i], acc[i]);
            }
        }
        chunk.copy_from_slice(&acc);
    }
}

/// `out = x y` for `k x k` matrices stored with row stride `w`.
#[inline(always)]
pub(super) fn mul(k: usize, w: usize, x: &[f64], y: &[f64], out: &mut [f64]) {
    for i in 0..k {
        row_times(
            &x[i * w..i * w + k],
            y,
            w,
            &mut out[i * w..(i + 1) * w],
            false,
        );
    }
}

/// `out = x^T` for a `k x k` matrix stored with row stride `w`.
#[inline(always)]
pub(super) fn transpose(k: usize, w: usize, x: &[f64], out: &mut [f64]) {
    for i in 0..k {
        for j in 0..k {
            out[j * w + i] = x[i * w + j];
        }
    }
}

/// LU factorisation with partial pivoting in place (`k x k`, row stride
/// `w`); false when singular.
#[inline(always)]
pub(super) fn lu_factor(k: usize, w: usize, a: &mut [f64], piv: &mut [usize]) -> bool {
    for c in 0..k {
        let p = (c..k)
            .max_by(|&i, &j| a[i * w + c].abs().total_cmp(&a[j * w + c].abs()))
            .unwrap_or(c);
        piv[c] = p;
        let pivot = a[p * w + c];
        if !(pivot.abs() > 0.0 && pivot.is_finite()) {
            return false;
        }
        if p != c {
            for j in 0..k {
                a.swap(c * w + j, p * w + j);
            }
        }
        for i in c + 1..k {
            let f = a[i * w + c] / pivot;
            a[i * w + c] = f;
            for j in c + 1..k {
                a[i * w + j] -= f * a[c * w + j];
            }
        }
    }
    true
}

/// Solve `A X = B` in place for the first `rows` rows of an LU factored
/// by [`lu_factor`] (row stride `w`): all of it, or the leading block's
/// solve when the factored matrix is `[[D11, D12], [0, I]]` (rows were
/// then only swapped within the leading block) and the right-hand side
/// is zero below row `rows`. The right-hand side has `width` columns (row
/// stride `width`). The factorisation swaps whole rows (`P A = L U`), so
/// all swaps come first.
#[inline(always)]
pub(super) fn lu_solve(
    rows: usize,
    w: usize,
    lu: &[f64],
    piv: &[usize],
    b: &mut [f64],
    width: usize,
) {
    for c in 0..rows {
        if piv[c] != c {
            for j in 0..width {
                b.swap(c * width + j, piv[c] * width + j);
            }
        }
    }
    for c in 0..rows {
        let (done, rest) = b.split_at_mut((c + 1) * width);
        let pivot_row = &done[c * width..];
        for (i, row) in rest[..(rows - c - 1) * width]
            .chunks_exact_mut(width)
            .enumerate()
        {
            let f = lu[(c + 1 + i) * w + c];
            if f != 0.0 {
                row.iter_mut()
                    .zip(pivot_row)
                    .for_each(|(x, &y)| *x = fma(-f, y, *x));
            }
        }
    }
    for c in (0..rows).rev() {
        let (head, tail) = b.split_at_mut((c + 1) * width);
        let row = &mut head[c * width..];
        for i in c + 1..rows {
            let f = lu[c * w + i];
            row.iter_mut()
                .zip(&tail[(i - c - 1) * width..(i - c) * width])
                .for_each(|(x, &y)| *x = fma(-f, y, *x));
        }
        let d = lu[c * w + c];
        row.iter_mut().for_each(|x| *x /= d);
    }
}

/// The sum of `|x|` over the first `cols` entries of `rows` rows (row stride `w`),
/// column by column (`by_rows` false) or row by row, largest.
pub(super) fn norm(rows: usize, cols: usize, w: usize, x: &[f64], by_rows: bool) -> f64 {
    let (outer, inner) = if by_rows { (rows, cols) } else { (cols, rows) };
    (0..outer)
        .map(|o| {
            (0..inner)
                .map(|i| {
                    let (r, c) = if by_rows { (o, i) } else { (i, o) };
                    x[r * w + c].abs()
                })
                .sum::<f64>()
        })
        .fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_lu_solve_follows_row_swaps_after_the_first_column() {
        // Column 0 pivots in place, column 1 swaps rows 1 and 2.
        let (k, w) = (3, 4);
        let a = [4.0, 1.0, 2.0, 2.0, 0.5, 7.0, 1.0, 3.0, 1.0];
        let mut lu = vec![0.0; k * w];
        for i in 0..k {
            lu[i * w..i * w + k].copy_from_slice(&a[i * k..(i + 1) * k]);
        }
        let mut piv = [0; 3];
        assert!(lu_factor(k, w, &mut lu, &mut piv));
        assert_eq!(piv, [0, 2, 2]);
        let want = [1.0, -2.0, 0.5, 3.0, 0.25, -1.0];
        let mut rhs: Vec<f64> = (0..k * 2)
            .map(|e| (0..k).map(|j| a[e / 2 * k + j] * want[j * 2 + e % 2]).sum())
            .collect();
        lu_solve(k, w, &lu, &piv, &mut rhs, 2);
        for (g, w) in rhs.iter().zip(&want) {
            assert!((g - w).abs() <= 1e-14, "{g} vs {w}");
        }
    }
}
