//! Unit tests of the problem's units of work (`super`). Its evaluations are
//! tested against finite differences and a full Jacobian in
//! `tests/core_derivatives.rs`.

use super::*;
use crate::eval::point_factors::pivoted_factor;
use crate::testing::{damped_rotations, Lcg};

/// A task holds whole batches of [`LANES`] lines, as many as fit in
/// [`TASK_COLUMNS`] real residuals, and one batch where even one does not fit.
#[test]
fn a_task_is_the_most_whole_batches_of_lines_that_fit_its_residuals() {
    for (l, r) in [(1, 1), (2, 1), (1, 3), (4, 4), (8, 8), (16, 16), (20, 3)] {
        let shape = Shape::new(4, r, l, 1).unwrap();
        let lines = lines_per_task(&shape);
        let per_line = 2 * l * r;
        assert_eq!(lines % LANES, 0, "{l} x {r}: {lines} lines");
        if per_line * LANES <= TASK_COLUMNS {
            assert!(lines * per_line <= TASK_COLUMNS, "{l} x {r}: {lines} lines");
            assert!(
                (lines + LANES) * per_line > TASK_COLUMNS,
                "{l} x {r}: {lines} lines"
            );
        } else {
            assert_eq!(lines, LANES, "{l} x {r}");
        }
    }
}

/// The unfolding of the Gram sums and the Hessenberg forms go to the pool
/// at n = 16 2x2 on nine points, and stay on this thread at the gantry's
/// size (order 6, 2 outputs, 1 input, five points): as their notes say.
#[test]
fn the_points_go_to_the_pool_at_n16_and_stay_here_at_the_gantrys_size() {
    let lti = |n: usize, l: usize, r: usize| Shape::new(n, r, l, 1).unwrap().lti_len();
    assert_eq!(lti(16, 2, 2), 324);
    assert_eq!(lti(6, 2, 1), 56);
    assert!(unfold_spreads(9, lti(16, 2, 2)));
    assert!(!unfold_spreads(5, lti(6, 2, 1)));
    assert!(forms_spread(16, 9));
    assert!(!forms_spread(6, 5));
}

/// The bound the route's cost is priced with is the rank of a point's Gram
/// matrix, `n (l + r) + l r`: what the `n^2` similarity transformations
/// leave of the LTI parameters. Found by the pivoted factorisation of a
/// generic model's Gram matrix at one point, with lines enough to see it.
/// (Far from a tie: the unit-diagonal Gram matrices' eigenvalues kept are
/// 4.6e-3 and above, those dropped 2e-15 and below, the tolerance 1e-12.)
#[test]
fn a_points_gram_matrix_has_the_rank_its_bound_prices() {
    let mut rng = Lcg(11);
    for (n, l, r) in [(4, 2, 1), (4, 1, 3), (2, 2, 2), (6, 1, 1), (8, 3, 2)] {
        let shape = Shape::new(n, r, l, 0).unwrap();
        let mut theta: Vec<f64> = (0..shape.len()).map(|_| rng.next_f64()).collect();
        // A: damped rotations spread over the band (poles near the origin
        // would leave directions the lines see only below the rank's
        // tolerance).
        let a = damped_rotations(n, |k| (0.7, 0.4 + 2.2 * k as f64 / (n / 2) as f64));
        theta[shape.block(Matrix::A, 0)].copy_from_slice(&a);
        let lines = 40;
        let z: Vec<C64> = (0..lines)
            .map(|k| C64::from_polar(1.0, 0.1 + 0.075 * k as f64))
            .collect();
        let g = vec![C64::new(0.0, 0.0); lines * l * r];
        let data = FrfData::new(1, l, r, z, g, &vec![1.0; lines * l * r]).unwrap();
        let problem = Problem::new(shape, data, &[]).unwrap();
        let gn = problem
            .gauss_newton(&theta, &FreeSet::all(problem.shape.len()))
            .unwrap();
        let lti = problem.shape.lti_len();
        let (_, _, rank) = pivoted_factor(&gn.gram, lti).unwrap();
        assert_eq!(rank, n * (l + r) + l * r, "n {n}, {l} x {r}");
        assert_eq!(problem.rank_bound(), rank, "n {n}, {l} x {r}");
    }
}
