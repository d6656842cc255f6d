//! Unit tests of the problem's units of work (`super`). Its evaluations are
//! tested against finite differences and a full Jacobian in
//! `tests/core_derivatives.rs`.

use super::*;

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
