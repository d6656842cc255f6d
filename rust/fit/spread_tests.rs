//! Every loop that runs on the pool or in order by its work
//! ([`crate::base::spread`]) gives the same bits both ways: the evaluation
//! of a problem (residual, V_NLS, gradient, `J^T J`), the frequency
//! responses with their sides, the stability margins, the pieces of a
//! Levenberg-Marquardt step and the points' factors of its reduced system.

use crate::base::data::FrfData;
use crate::base::layout::{FreeSet, Shape};
use crate::base::spread::forced;
use crate::eval::model::ModelAt;
use crate::eval::point_factors::tests::pieces;
use crate::eval::problem::Problem;
use crate::eval::response::frequency_response;
use crate::fit::lm::{lm_step, marquardt_diagonal, predicted_decrease};
use crate::fit::stable::FrozenRange;
use crate::testing::{on_threads, time_model, Lcg};
use num_complex::Complex64 as C64;

/// n = 5, 2 x 2, basis (p, p^2) at four points, 300 lines: three tasks a
/// point, twelve in all.
fn problem() -> (Problem, Vec<f64>, Vec<f64>) {
    let shape = Shape::new(5, 2, 2, 2).unwrap();
    let theta = time_model(&shape, true, 3);
    let points = [-1.0, -0.3, 0.4, 1.0];
    let psi: Vec<f64> = points.iter().flat_map(|&p| [p, p * p]).collect();
    let z: Vec<C64> = (0..300)
        .map(|k| C64::from_polar(1.0, 0.01 + 3.1 * k as f64 / 299.0))
        .collect();
    let model = ModelAt::new(shape, &theta, &psi, points.len());
    let mut g = frequency_response(&model, &z).unwrap();
    let mut rng = Lcg(7);
    g.iter_mut()
        .for_each(|v| *v += 0.05 * C64::new(rng.next_f64(), rng.next_f64()));
    let sigma = vec![0.05; g.len()];
    let data = FrfData::new(points.len(), 2, 2, z, g, &sigma).unwrap();
    let start: Vec<f64> = theta.iter().map(|t| t + 0.02 * rng.next_f64()).collect();
    (Problem::new(shape, data, &psi).unwrap(), start, psi)
}

/// Every number of one evaluation and step, computed with the loops on
/// the pool (three threads) or in order on this thread.
fn numbers(spread: bool) -> Vec<Vec<f64>> {
    let (problem, theta, psi) = problem();
    on_threads(3, || {
        forced(spread, || {
            let shape = *problem.shape();
            let free = FreeSet::for_shape(&shape, None).unwrap();
            let gn = problem.gauss_newton(&theta, &free).unwrap();
            let residual = problem.residual(&theta).unwrap();
            let z = problem.data().z().to_vec();
            let model = ModelAt::new(shape, &theta, &psi, 4);
            let response = frequency_response(&model, &z).unwrap();
            let diag = marquardt_diagonal(&gn);
            let step = lm_step(&gn, &diag, 1e-3).unwrap().unwrap();
            let decrease = predicted_decrease(&gn, &step);
            let grid: Vec<f64> = (0..41)
                .flat_map(|k| {
                    let p = -1.0 + k as f64 / 20.0;
                    [p, p * p]
                })
                .collect();
            let range = FrozenRange::new(2, &grid, 41, 4, true).unwrap();
            let margins = range.margins(&shape, &theta).unwrap();
            let (at, worst) = range.worst(&shape, &theta, -1.0).unwrap();
            let parts = |v: &[C64]| v.iter().flat_map(|c| [c.re, c.im]).collect::<Vec<_>>();
            // the points' factors (5 points, 40 frozen parameters of rank 12) and the
            // reduced system's Gram matrix
            let free: Vec<usize> = (0..120).filter(|k| k % 7 != 3).collect();
            let factored = pieces(5, 40, 12, 3, &free);
            let factors = factored.factors.expect("factors");
            let weights: Vec<f64> = (0..free.len()).map(|k| 1.0 + k as f64 / 9.0).collect();
            let reduced = factors.weighted_gram(&weights).unwrap();
            let reduced: Vec<f64> = (0..reduced.ncols())
                .flat_map(|j| (0..reduced.nrows()).map(move |i| (i, j)))
                .map(|(i, j)| reduced[(i, j)])
                .collect();
            let ranks: Vec<f64> = factors.ranks().iter().map(|&r| r as f64).collect();
            vec![
                vec![
                    gn.vnls,
                    problem.cost(&theta).unwrap(),
                    decrease,
                    at as f64,
                    worst,
                ],
                gn.gradient,
                gn.gram,
                parts(&residual),
                parts(&response),
                step,
                margins,
                factors.times(&vec![0.5; factors.rank()]),
                reduced,
                ranks,
            ]
        })
    })
}

#[test]
fn the_loops_give_the_same_bits_on_the_pool_and_in_order() {
    let (pool, here) = (numbers(true), numbers(false));
    for (k, (a, b)) in pool.iter().zip(&here).enumerate() {
        assert_eq!(a.len(), b.len(), "part {k}");
        for (i, (x, y)) in a.iter().zip(b).enumerate() {
            assert_eq!(x.to_bits(), y.to_bits(), "part {k}, entry {i}: {x} and {y}");
        }
    }
    // The problem is one a fit moves on: the step lowers the model's cost.
    assert!(pool[0][2] > 0.0);
}
