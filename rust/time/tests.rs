//! The Gauss-Newton pieces of continuous-time records with the hold's
//! derivative computed by [`super::hold`] against those computed the way
//! it was before ([`super::hold_reference`]: one Van Loan exponential per
//! row on `[[A, B], [0, 0]] dt`, no balancing).

use super::{InitialState, TimeProblem};
use crate::base::layout::{FreeSet, Matrix, Shape};
use crate::eval::objective::GaussNewton;
use crate::testing::{time_model, time_records};

/// `|new - old| <= 1e-10 max |old|`, entry by entry.
fn close(what: &str, new: &[f64], old: &[f64]) {
    let scale = old.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    assert!(scale > 0.0, "{what}: all zero");
    for (k, (p, q)) in new.iter().zip(old).enumerate() {
        assert!(
            (p - q).abs() <= 1e-10 * scale,
            "{what}[{k}]: {p} vs {q} (scale {scale})"
        );
    }
}

#[test]
fn gauss_newton_pieces_agree_with_the_per_row_derivative() {
    // (shape, dt, initial state, skip, every how many parameters one is
    // fixed, scale of B): no squaring, several, a large input term.
    let cases = [
        (Shape::new(3, 2, 2, 2), 0.05, InitialState::Zero, 0, 0, 1.0),
        (
            Shape::new(3, 2, 2, 2),
            0.6,
            InitialState::Estimate,
            3,
            0,
            1.0,
        ),
        (
            Shape::new(2, 1, 2, 1),
            0.3,
            InitialState::Estimate,
            0,
            4,
            1.0,
        ),
        (Shape::new(4, 3, 1, 2), 0.2, InitialState::Zero, 2, 5, 30.0),
        (
            Shape::new(6, 1, 2, 4),
            0.1,
            InitialState::Estimate,
            0,
            0,
            8.0,
        ),
    ];
    for (case, (shape, dt, initial, skip, every, b_scale)) in cases.into_iter().enumerate() {
        let shape = shape.unwrap();
        let mut theta = time_model(&shape, false, 3 + case as u64);
        for i in 0..=shape.nb {
            theta[shape.block(Matrix::B, i)]
                .iter_mut()
                .for_each(|v| *v *= b_scale);
        }
        let records = time_records(&shape, &[60, 35], 11 + case as u64);
        let mut problem = TimeProblem::new(shape, records, initial, Some(dt), skip).unwrap();
        let mask: Vec<bool> = (0..shape.len())
            .map(|i| every == 0 || i % every != 1)
            .collect();
        let free = FreeSet::from_mask(&mask);
        let GaussNewton {
            vnls,
            gradient,
            gram,
            ..
        } = problem.gauss_newton_timed(&theta, &free).unwrap().0;
        problem.reference = true;
        let old = problem.gauss_newton_timed(&theta, &free).unwrap().0;
        let what = |piece: &str| format!("case {case}: {piece}");
        close(&what("V"), &[vnls], &[old.vnls]);
        close(&what("gradient"), &gradient, &old.gradient);
        close(&what("J^T J"), &gram, &old.gram);
    }
}

#[test]
fn the_cost_is_the_vnls_of_the_gauss_newton_pieces_to_the_last_bit() {
    // The fits judge a doubtful step by its cost alone and take the
    // pieces' V_NLS once it is taken: the two must agree bit for bit.
    for (case, (discrete, initial, skip)) in [
        (true, InitialState::Zero, 0),
        (true, InitialState::Estimate, 4),
        (false, InitialState::Estimate, 0),
        (false, InitialState::Zero, 7),
    ]
    .into_iter()
    .enumerate()
    {
        let shape = Shape::new(3, 2, 2, 2).unwrap();
        let theta = time_model(&shape, discrete, 21 + case as u64);
        let records = time_records(&shape, &[50, 33, 41], 5 + case as u64);
        let hold = (!discrete).then_some(0.2);
        let problem = TimeProblem::new(shape, records, initial, hold, skip).unwrap();
        let mask: Vec<bool> = (0..shape.len()).map(|i| i % 3 != 2).collect();
        let gn = problem
            .gauss_newton_timed(&theta, &FreeSet::from_mask(&mask))
            .unwrap()
            .0;
        let cost = problem.cost(&theta).unwrap();
        assert_eq!(cost.to_bits(), gn.vnls.to_bits(), "case {case}");
        let flat: f64 = problem
            .residual(&theta)
            .unwrap()
            .iter()
            .map(|v| v * v)
            .sum();
        assert!((flat - cost).abs() <= 1e-12 * cost, "case {case}");
    }
}
