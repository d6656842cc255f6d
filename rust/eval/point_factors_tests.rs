//! Unit tests of the factored Levenberg-Marquardt step (`super`).

use super::*;
use crate::eval::objective::GaussNewton;
use crate::testing::Lcg;

/// `G G^T` (`lti x lti`, column-major) for `G` of `rank` random columns,
/// row `p` scaled by `10^(scale p)`, and a vector in its range.
fn low_rank(s: &mut Lcg, lti: usize, rank: usize, scale: f64) -> (Vec<f64>, Vec<f64>) {
    let rows: Vec<f64> = (0..lti)
        .map(|p| 10f64.powf(scale * p as f64 / lti as f64))
        .collect();
    let g: Vec<f64> = (0..lti * rank)
        .map(|k| s.next_f64() * rows[k % lti])
        .collect();
    let mut h = vec![0.0; lti * lti];
    for i in 0..lti {
        for j in 0..lti {
            h[i + j * lti] = (0..rank).map(|k| g[i + k * lti] * g[j + k * lti]).sum();
        }
    }
    let coef: Vec<f64> = (0..rank).map(|_| s.next_f64()).collect();
    let jtr = (0..lti)
        .map(|i| (0..rank).map(|k| g[i + k * lti] * coef[k]).sum())
        .collect();
    (h, jtr)
}

#[test]
fn the_pivoted_factor_finds_the_rank_of_a_badly_scaled_matrix_and_rebuilds_it() {
    let mut s = Lcg(7);
    for (lti, rank, scale) in [(40, 12, 0.0), (56, 20, 6.0), (30, 30, 3.0), (25, 1, 8.0)] {
        let (h, _) = low_rank(&mut s, lti, rank, scale);
        let (l, pivots, found) = pivoted_factor(&h, lti).unwrap();
        assert_eq!(found, rank, "lti {lti} rank {rank}");
        assert_eq!(l.len(), lti * found);
        let mut sorted = pivots.clone();
        sorted.sort_unstable();
        sorted.dedup();
        assert_eq!(sorted.len(), found, "pivots repeat");
        for i in 0..lti {
            for j in 0..lti {
                let llt: f64 = (0..found).map(|k| l[i + k * lti] * l[j + k * lti]).sum();
                let size = (h[i + i * lti] * h[j + j * lti]).sqrt();
                assert!((llt - h[i + j * lti]).abs() <= 1e-10 * size, "({i}, {j})");
            }
        }
        // Lower triangular in the pivots' order.
        for (k, &p) in pivots.iter().enumerate() {
            for m in k + 1..found {
                assert_eq!(l[p + m * lti], 0.0);
            }
        }
    }
}

#[test]
fn a_point_the_model_does_not_see_has_no_factor() {
    let lti = 6;
    let (l, pivots, rank) = pivoted_factor(&vec![0.0; lti * lti], lti).unwrap();
    assert_eq!((l.len(), pivots.len(), rank), (0, 0, 0));
}

/// The Gauss-Newton pieces of `points` random low-rank points over the
/// free parameters `free` of `n_coef` basis coefficients: dense, and with
/// the factors (also the pieces of `crate::fit::lm`'s tests, which check
/// the factored step against the dense one).
pub(crate) fn pieces(
    points: usize,
    lti: usize,
    rank: usize,
    n_coef: usize,
    free: &[usize],
) -> GaussNewton {
    let mut s = Lcg(11);
    let (mut grams, mut jtr, mut psi) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..points {
        let (h, g) = low_rank(&mut s, lti, rank, 2.0);
        grams.push(h);
        jtr.push(g);
        let mut row = vec![1.0];
        row.extend((1..n_coef).map(|_| s.next_f64()));
        psi.push(row);
    }
    let map: Vec<(usize, usize)> = free.iter().map(|&u| (u / lti, u % lti)).collect();
    let nf = map.len();
    let mut gram = vec![0.0; nf * nf];
    for (a, &(i, p)) in map.iter().enumerate() {
        for (b, &(j, t)) in map.iter().enumerate() {
            gram[a + b * nf] = (0..points)
                .map(|q| psi[q][i] * psi[q][j] * grams[q][p + t * lti])
                .sum();
        }
    }
    let gradient = map
        .iter()
        .map(|&(i, p)| 2.0 * (0..points).map(|q| psi[q][i] * jtr[q][p]).sum::<f64>())
        .collect();
    let factors = PointFactors::new(&grams, &jtr, psi, map, lti, rank).unwrap();
    GaussNewton {
        vnls: 1.0,
        gradient,
        gram,
        factors: Some(factors),
    }
}

#[test]
fn the_route_is_chosen_by_the_shape_alone() {
    // n = 16 2x2 at 9 points: 324 frozen parameters of rank at most 68.
    assert!(worth_it(324, 68, 9, 1620));
    // n = 32 4x4; its refit's 3600 free parameters would save less than half.
    assert!(worth_it(1296, 272, 9, 6480));
    assert!(!worth_it(1296, 272, 9, 3600));
    // The gantry (280 free) and the 9 x 9 grid (600): dense.
    assert!(!worth_it(56, 20, 5, 280));
    assert!(!worth_it(100, 36, 81, 600));
    // Many points of nearly full rank: dense however many parameters.
    assert!(!worth_it(324, 300, 9, 1620));
}

#[test]
fn the_factors_own_cost_and_the_fewest_parameters_count_in_the_route() {
    // Below FEWEST_FREE free parameters the dense step, however cheap the
    // factors; from it on, the shape decides.
    assert!(!worth_it(100, 10, 5, FEWEST_FREE - 1));
    assert!(worth_it(100, 10, 5, FEWEST_FREE));
    // Two points of rank at most 100, 2000 free parameters: half the dense
    // factorisation is 2000^3 / 6 = 1.33e9 flops; the reduced system
    // 3 * 100^2 lti + 200^3 / 3 and the points' factors 2 lti 100^2 / 2
    // flops, 4e4 lti + 2.7e6 in all: the factored step up to lti = 33266.
    // Without the factors' own cost the line would be at lti = 44355.
    assert!(worth_it(33_000, 100, 2, 2000));
    assert!(!worth_it(34_000, 100, 2, 2000));
    assert!(!worth_it(44_000, 100, 2, 2000));
}

#[test]
fn factors_join_only_over_the_same_shape_and_parameters() {
    let free: Vec<usize> = (0..24).collect();
    let factors = |points, rank, free: &[usize]| {
        pieces(points, 12, rank, 2, free)
            .factors
            .expect("the pieces' factors")
    };
    let joined = factors(2, 3, &free).join(factors(3, 3, &free));
    assert_eq!(joined.map(|f| f.ranks()), Some(vec![3; 5]));
    // Another bound on the ranks, or other free parameters: no one factor.
    assert!(factors(2, 3, &free).join(factors(2, 4, &free)).is_none());
    assert!(factors(2, 3, &free)
        .join(factors(2, 3, &free[..23]))
        .is_none());
    // Neither does another number of frozen parameters a point.
    let other = pieces(2, 8, 3, 3, &free).factors.expect("factors");
    assert!(factors(2, 3, &free).join(other).is_none());
}

#[test]
fn a_newton_system_goes_through_the_factors_only_where_they_cost_less() {
    let free: Vec<usize> = (0..24).collect();
    let f = pieces(3, 12, 3, 2, &free)
        .factors
        .expect("the pieces' factors");
    // The reduced system: 6 * 3^2 * 12 + 9^3 / 3 = 891 flops; half the
    // dense factorisation of n parameters n^3 / 6.
    assert!(!f.newton_worth_it(17));
    assert!(f.newton_worth_it(18));
}
