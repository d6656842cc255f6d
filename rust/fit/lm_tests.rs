//! Unit tests of the Levenberg-Marquardt pieces and loop (`super`).

use super::*;
use crate::error::Error;
use crate::eval::objective::GaussNewton;
use crate::eval::point_factors::tests::pieces;
use crate::testing::relative_gap;

fn refused(settings: LmSettings) -> (&'static str, String) {
    match settings.validate() {
        Err(Error::InvalidArgument { name, message }) => (name, message),
        other => panic!("expected InvalidArgument, got {other:?}"),
    }
}

#[test]
fn settings_refuse_what_no_fit_can_use_and_name_it() {
    assert!(LmSettings::default().validate().is_ok());
    let edge = LmSettings {
        xtol: 0.0,
        ftol: 0.0,
        gtol: 0.0,
        lambda0: f64::MIN_POSITIVE,
        ..LmSettings::default()
    };
    assert!(edge.validate().is_ok());
    for bad in [-1e-300, f64::NAN, f64::INFINITY] {
        for name in ["xtol", "ftol", "gtol"] {
            let mut s = LmSettings::default();
            match name {
                "xtol" => s.xtol = bad,
                "ftol" => s.ftol = bad,
                _ => s.gtol = bad,
            }
            let (got, message) = refused(s);
            assert_eq!(got, name);
            assert_eq!(message, format!("expected a finite number >= 0, got {bad}"));
        }
    }
    for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        let s = LmSettings {
            lambda0: bad,
            ..LmSettings::default()
        };
        let (got, message) = refused(s);
        assert_eq!(got, "lambda0");
        assert_eq!(message, format!("expected a finite number > 0, got {bad}"));
    }
}

fn gauss_newton(gram: Vec<f64>) -> GaussNewton {
    let m = (gram.len() as f64).sqrt() as usize;
    GaussNewton {
        vnls: 1.0,
        gradient: vec![0.0; m],
        gram,
        factors: None,
    }
}

#[test]
fn marquardt_diagonal_is_the_gram_diagonal_floored_at_1e_12_of_its_largest() {
    // Off-diagonal entries distinct from the diagonal, so that reading the
    // wrong entry shows; the third diagonal entry lies below the floor.
    let gram = vec![
        4.0, 0.5, 0.25, //
        0.5, 2.0, 0.125, //
        0.25, 0.125, 1e-20,
    ];
    assert_eq!(
        marquardt_diagonal(&gauss_newton(gram)),
        vec![4.0, 2.0, 4e-12]
    );
    // A Gram matrix of zeros (no parameter has influence) still damps.
    let zero = marquardt_diagonal(&gauss_newton(vec![0.0; 4]));
    assert_eq!(zero, vec![1e-312, 1e-312]);
}

#[test]
fn predicted_decrease_is_the_gauss_newton_model_of_the_step() {
    // g = [1, -2, 0.5], symmetric J^T J, d chosen by hand: summed row by
    // row here, column by column in the code.
    let gram = vec![
        3.0, 0.5, -1.0, //
        0.5, 2.0, 0.25, //
        -1.0, 0.25, 4.0,
    ];
    let gn = GaussNewton {
        vnls: 10.0,
        gradient: vec![1.0, -2.0, 0.5],
        gram: gram.clone(),
        factors: None,
    };
    let d = [0.1, 0.3, -0.2];
    let gd: f64 = gn.gradient.iter().zip(&d).map(|(g, x)| g * x).sum();
    let mut quad = 0.0;
    for i in 0..3 {
        for j in 0..3 {
            quad += d[i] * gram[i * 3 + j] * d[j];
        }
    }
    let want = -(gd + quad);
    let got = predicted_decrease(&gn, &d);
    assert!((got - want).abs() <= 1e-15 * want.abs(), "{got} vs {want}");
}

#[test]
fn a_failed_machine_ends_the_fit_and_a_model_that_cannot_be_evaluated_is_a_rejected_step() {
    let oom = Error::OutOfMemory {
        bytes: 8,
        what: "a test",
    };
    assert!(matches!(trial_point::<f64>(Err(oom.clone())), Err(e) if e == oom));
    let singular = Error::Singular { point: 0, line: 1 };
    assert!(matches!(trial_point::<f64>(Err(singular)), Ok(None)));
}

/// Rosenbrock's function as least squares, `r = [10 (y - x^2), 1 - x]`.
struct Rosenbrock(crate::base::layout::Shape);

impl Objective for Rosenbrock {
    fn shape(&self) -> &crate::base::layout::Shape {
        &self.0
    }
    fn n_residuals(&self) -> usize {
        2
    }
    fn cost(&self, theta: &[f64]) -> Result<f64> {
        Ok(self.response(theta)?.iter().map(|v| v * v).sum())
    }
    fn gauss_newton(&self, theta: &[f64], free: &FreeSet) -> Result<GaussNewton> {
        assert_eq!(free.len(), 2);
        let r = self.response(theta)?;
        let jac = [[-20.0 * theta[0], 10.0], [-1.0, 0.0]];
        let mut gradient = vec![0.0; 2];
        let mut gram = vec![0.0; 4];
        for a in 0..2 {
            for k in 0..2 {
                gradient[a] += 2.0 * jac[k][a] * r[k];
                for b in 0..2 {
                    gram[a + 2 * b] += jac[k][a] * jac[k][b];
                }
            }
        }
        Ok(GaussNewton {
            vnls: r.iter().map(|v| v * v).sum(),
            gradient,
            gram,
            factors: None,
        })
    }
    fn response(&self, theta: &[f64]) -> Result<Vec<f64>> {
        Ok(vec![
            10.0 * (theta[1] - theta[0] * theta[0]),
            1.0 - theta[0],
        ])
    }
}

/// The fit from (-1.2, 1) and the cost there.
fn rosenbrock(settings: &LmSettings) -> (Fit, f64) {
    let problem = Rosenbrock(crate::base::layout::Shape::new(1, 1, 1, 1).expect("a valid shape"));
    let start = [-1.2, 1.0];
    let v0 = problem.cost(&start).expect("finite");
    let fit = levenberg_marquardt(
        &problem,
        &start,
        &FreeSet::all(2),
        settings,
        &mut crate::fit::Silent,
    )
    .expect("the fit runs");
    (fit, v0)
}

#[test]
fn lm_takes_only_steps_that_lower_the_cost_and_damps_more_after_a_rejection() {
    // A small initial damping: the first steps overshoot along the valley.
    let settings = LmSettings {
        lambda0: 1e-4,
        max_iter: 500,
        ..LmSettings::default()
    };
    let (fit, mut v) = rosenbrock(&settings);
    let mut rejected = 0;
    for (k, it) in fit.history.iter().enumerate() {
        if it.accepted {
            assert!(it.vnls < v, "step {k}: {} after {v}", it.vnls);
        } else {
            rejected += 1;
            assert_eq!(it.vnls, v, "step {k} rejected yet moved");
            if let Some(next) = fit.history.get(k + 1) {
                assert!(next.lambda > it.lambda, "step {k}: damping not raised");
            }
        }
        v = it.vnls;
    }
    assert!(
        rejected > 0,
        "no step was rejected: the test proves nothing"
    );
    assert!((fit.theta[0] - 1.0).abs() < 1e-6 && (fit.theta[1] - 1.0).abs() < 1e-6);
}

#[test]
fn ftol_stops_at_the_first_accepted_step_that_gains_less_than_its_share() {
    let ftol = 0.3;
    let (fit, mut v) = rosenbrock(&LmSettings {
        ftol,
        ..LmSettings::default()
    });
    assert_eq!(fit.stop, Stop::CostChange);
    let last = fit.history.len() - 1;
    for (k, it) in fit.history.iter().enumerate() {
        if it.accepted {
            let small = v - it.vnls <= ftol * v;
            assert_eq!(small, k == last, "step {k}: V {v} -> {}", it.vnls);
        }
        v = it.vnls;
    }
    assert!(fit.history[last].accepted);
}

/// Rosenbrock's cost, with a model that cannot be evaluated anywhere
/// but at the start: every step is rejected.
struct Cliff(Rosenbrock);

impl Objective for Cliff {
    fn shape(&self) -> &crate::base::layout::Shape {
        self.0.shape()
    }
    fn n_residuals(&self) -> usize {
        2
    }
    fn cost(&self, theta: &[f64]) -> Result<f64> {
        self.0.cost(theta)
    }
    fn gauss_newton(&self, theta: &[f64], free: &FreeSet) -> Result<GaussNewton> {
        if theta != [-1.2, 1.0] {
            return Err(Error::Singular { point: 0, line: 0 });
        }
        self.0.gauss_newton(theta, free)
    }
    fn response(&self, theta: &[f64]) -> Result<Vec<f64>> {
        self.0.response(theta)
    }
}

#[test]
fn lm_gives_up_when_no_damping_helps_and_returns_the_start() {
    let shape = crate::base::layout::Shape::new(1, 1, 1, 1).expect("a valid shape");
    // No step-size or cost-change test to end it first.
    let settings = LmSettings {
        max_iter: 1000,
        xtol: 0.0,
        ftol: 0.0,
        ..LmSettings::default()
    };
    let start = [-1.2, 1.0];
    let fit = levenberg_marquardt(
        &Cliff(Rosenbrock(shape)),
        &start,
        &FreeSet::all(2),
        &settings,
        &mut crate::fit::Silent,
    )
    .expect("the fit runs");
    assert_eq!(fit.stop, Stop::Damping);
    assert!(fit.history.len() < 100, "{} steps", fit.history.len());
    assert!(fit.history.iter().all(|it| !it.accepted));
    assert_eq!(fit.theta, start);
}

#[test]
fn a_doubtful_step_is_judged_by_its_cost_alone_and_its_pieces_come_only_when_taken() {
    let problem = Rosenbrock(crate::base::layout::Shape::new(1, 1, 1, 1).expect("a valid shape"));
    let counted = crate::testing::Counted::new(&problem);
    let settings = LmSettings {
        lambda0: 1e-4,
        max_iter: 500,
        ..LmSettings::default()
    };
    let fit = levenberg_marquardt(
        &counted,
        &[-1.2, 1.0],
        &FreeSet::all(2),
        &settings,
        &mut crate::fit::Silent,
    )
    .expect("the fit runs");
    let h = &fit.history;
    // Doubtful: the first step and every step after a rejection.
    let doubtful = |k: usize| k == 0 || !h[k - 1].accepted;
    let rejected_doubtful = (0..h.len()).filter(|&k| doubtful(k) && !h[k].accepted);
    assert!(
        rejected_doubtful.count() > 0,
        "no doubtful step was rejected"
    );
    assert!(
        (0..h.len()).any(|k| !doubtful(k) && !h[k].accepted),
        "no other step was rejected"
    );
    assert_eq!(counted.calls(), crate::testing::expected_calls(h, doubtful));
}

// The factored step (`crate::eval::point_factors`) against the dense one.

#[test]
fn the_factored_step_is_the_dense_step_with_and_without_fixed_parameters() {
    let (points, lti, rank, n_coef) = (5, 30, 7, 3);
    let every: Vec<usize> = (0..n_coef * lti).collect();
    // Some parameters fixed: whole rows of one coefficient, scattered others.
    let some: Vec<usize> = every
        .iter()
        .copied()
        .filter(|u| u % 7 != 3 && *u / lti != 1)
        .collect();
    for free in [every, some] {
        let gn = pieces(points, lti, rank, n_coef, &free);
        let factors = gn.factors.as_ref().unwrap();
        assert_eq!(factors.ranks(), vec![rank; points]);
        let nf = free.len();
        let diag: Vec<f64> = (0..nf).map(|i| gn.gram[i + i * nf]).collect();
        let system = FactoredSystem::new(factors, &diag).unwrap();
        for mu in [1e-4, 1e-2, 1.0, 100.0] {
            let dense = lm_step(&gn, &diag, mu).unwrap().unwrap();
            let factored = system.step(factors, &diag, mu).unwrap().unwrap();
            let err = relative_gap(&factored, &dense);
            assert!(err < 1e-8, "nf {nf} mu {mu}: {err:e}");
        }
    }
}

#[test]
fn joined_factors_step_as_the_sum_of_their_points() {
    let (lti, n_coef) = (20, 2);
    let free: Vec<usize> = (0..n_coef * lti).collect();
    let a = pieces(3, lti, 5, n_coef, &free);
    let b = pieces(4, lti, 5, n_coef, &free);
    let nf = free.len();
    let gram: Vec<f64> = a.gram.iter().zip(&b.gram).map(|(x, y)| x + y).collect();
    let gradient: Vec<f64> = a
        .gradient
        .iter()
        .zip(&b.gradient)
        .map(|(x, y)| x + y)
        .collect();
    let joined = a
        .factors
        .clone()
        .unwrap()
        .join(b.factors.clone().unwrap())
        .unwrap();
    assert_eq!(joined.rank(), 35);
    let sum = GaussNewton {
        vnls: 2.0,
        gradient,
        gram,
        factors: Some(joined),
    };
    let diag: Vec<f64> = (0..nf).map(|i| sum.gram[i + i * nf]).collect();
    let factors = sum.factors.as_ref().unwrap();
    let system = FactoredSystem::new(factors, &diag).unwrap();
    let dense = lm_step(&sum, &diag, 1e-2).unwrap().unwrap();
    let factored = system.step(factors, &diag, 1e-2).unwrap().unwrap();
    assert!(relative_gap(&factored, &dense) < 1e-8);
    // Other free parameters: no join.
    let fewer: Vec<usize> = (1..n_coef * lti).collect();
    let c = pieces(2, lti, 5, n_coef, &fewer);
    assert!(a.factors.unwrap().join(c.factors.unwrap()).is_none());
}
