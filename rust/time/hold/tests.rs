//! The exponential and the derivative blocks of [`super::Hold`] against a
//! Taylor-series reference, and its errors.

use super::*;
use crate::testing::Lcg;

/// `out = a b` for `s x s` row-major matrices (plain loops).
fn product(s: usize, a: &[f64], b: &[f64]) -> Vec<f64> {
    (0..s * s)
        .map(|e| (0..s).map(|k| a[e / s * s + k] * b[k * s + e % s]).sum())
        .collect()
}

/// Reference exponential: Taylor series after scaling to norm 1/64,
/// then squaring (slow, simple, independent of the Padé code).
fn expm_taylor(s: usize, m: &[f64]) -> Vec<f64> {
    let norm: f64 = m.iter().map(|v| v.abs()).sum();
    let k = if norm > 1.0 / 64.0 {
        (norm * 64.0).log2().ceil() as i32
    } else {
        0
    };
    let x: Vec<f64> = m.iter().map(|v| v * 0.5f64.powi(k)).collect();
    let identity: Vec<f64> = (0..s * s)
        .map(|e| if e % (s + 1) == 0 { 1.0 } else { 0.0 })
        .collect();
    let (mut sum, mut term) = (identity.clone(), identity);
    for j in 1..25 {
        term = product(s, &term, &x);
        term.iter_mut().for_each(|t| *t /= j as f64);
        sum.iter_mut().zip(&term).for_each(|(a, t)| *a += t);
    }
    for _ in 0..k {
        sum = product(s, &sum, &sum);
    }
    sum
}

/// Random `A` (`n x n`, entries of size `sa`), `B` (`n x r`, size `sb`),
/// `x` and `u`.
fn system(n: usize, r: usize, sa: f64, sb: f64, seed: u64) -> [Vec<f64>; 4] {
    let mut rng = Lcg(seed);
    let mut draw =
        |len: usize, size: f64| -> Vec<f64> { (0..len).map(|_| size * rng.next_f64()).collect() };
    [draw(n * n, sa), draw(n * r, sb), draw(n, 1.0), draw(r, 1.0)]
}

/// Sizes, scales of `A` and `B`: no squaring, a few, many; a large
/// input term on a small `A` (balanced away); the gantry benchmark's
/// proportions.
const CASES: [(usize, usize, f64, f64); 7] = [
    (1, 1, 0.3, 0.3),
    (3, 2, 1.0, 1.0),
    (4, 1, 6.0, 6.0),
    (6, 2, 20.0, 20.0),
    (5, 3, 0.2, 50.0),
    (6, 1, 0.7, 4.0),
    (2, 2, 1e-3, 1.0),
];

#[test]
fn exponential_and_derivatives_match_a_taylor_reference() {
    for (case, &(n, r, sa, sb)) in CASES.iter().enumerate() {
        let s = n + r;
        let [a, b, x, u] = system(n, r, sa, sb, 7 + case as u64);
        let mut m = vec![0.0; s * s];
        for i in 0..n {
            m[i * s..i * s + n].copy_from_slice(&a[i * n..(i + 1) * n]);
            m[i * s + n..(i + 1) * s].copy_from_slice(&b[i * r..(i + 1) * r]);
        }
        let v: Vec<f64> = (0..n)
            .map(|i| (0..r).map(|k| b[i * r + k] * u[k]).sum())
            .collect();
        let mut hold = Hold::new(n).unwrap();
        let (mut ad, mut ad_alone) = (vec![0.0; n * n], vec![0.0; n * n]);
        hold.compute(&a, None, &mut ad_alone).unwrap();
        hold.compute(&a, Some((&v, &x)), &mut ad).unwrap();
        let mut forcing = vec![0.0; n * s * n];
        hold.forcing(1.0, &u, &mut forcing);
        let want = expm_taylor(n, &a);
        let big = want.iter().fold(1.0f64, |acc, w| acc.max(w.abs()));
        for ((p, q), w) in ad.iter().zip(&ad_alone).zip(&want) {
            assert!((p - w).abs() <= 1e-10 * big, "case {case}: exp {p} vs {w}");
            assert!((q - w).abs() <= 1e-10 * big, "case {case}: exp {q} vs {w}");
        }
        // L(M, E) z from the exponential of [[M, E], [0, M]], z = [x; u].
        let s2 = 2 * s;
        let mut want = Vec::new();
        for ia in 0..n {
            for ib in 0..s {
                let mut big_m = vec![0.0; s2 * s2];
                for i in 0..s {
                    for j in 0..s {
                        big_m[i * s2 + j] = m[i * s + j];
                        big_m[(s + i) * s2 + s + j] = m[i * s + j];
                    }
                }
                big_m[ia * s2 + s + ib] = 1.0;
                let ex = expm_taylor(s2, &big_m);
                want.extend((0..n).map(|c| {
                    (0..s)
                        .map(|k| ex[c * s2 + s + k] * if k < n { x[k] } else { u[k - n] })
                        .sum::<f64>()
                }));
            }
        }
        let big = want.iter().fold(1.0f64, |acc, w| acc.max(w.abs()));
        for (e, (got, w)) in forcing.iter().zip(&want).enumerate() {
            assert!(
                (got - w).abs() <= 1e-10 * big,
                "case {case}, a={} b={} c={}: {got} vs {w}",
                e / n / s,
                e / n % s,
                e % n
            );
        }
    }
}

#[test]
fn non_finite_matrices_are_an_error() {
    let mut hold = Hold::new(1).unwrap();
    let mut ad = [0.0];
    assert!(hold.compute(&[f64::NAN], None, &mut ad).is_err());
    let input = ([f64::INFINITY], [0.0]);
    assert!(hold
        .compute(&[0.5], Some((&input.0, &input.1)), &mut ad)
        .is_err());
}
