//! The Levenberg-Marquardt step through every point's factor
//! (`point_factors.rs`) on a real problem of the size where it is taken:
//! the same step as the dense factorisation of `J^T J + mu D`, the rank
//! the similarity transformations leave, and the same fit on any number
//! of threads.

use faer::Mat;
use lpvid::fit::lm::{lm_step, marquardt_diagonal, LmSystem};
use lpvid::l21::cone_groups;
use lpvid::socp::{ConeProblem, ConeSolver, ConeStep, Pinned, PinnedBasis};
use lpvid::testing::{damped_rotations, on_threads, relative_gap, Lcg};
use lpvid::{
    frequency_response, levenberg_marquardt, FreeSet, FrfData, L21Settings, LmSettings, Matrix,
    ModelAt, Problem, Shape, Silent,
};
use num_complex::Complex64 as C64;

const N: usize = 16;
const POINTS: usize = 9;
const LINES: usize = 12;

fn points() -> Vec<f64> {
    (0..POINTS)
        .map(|k| -1.0 + 2.0 * k as f64 / (POINTS - 1) as f64)
        .collect()
}

/// `p, p^2, p^3` at every point.
fn basis() -> Vec<f64> {
    points()
        .iter()
        .flat_map(|&p| [p, p * p, p * p * p])
        .collect()
}

/// A stable discrete-time model of order 16 with 2 outputs and 2 inputs,
/// every coefficient nonzero, and its frequency lines.
fn model() -> (Shape, Vec<f64>, Vec<C64>) {
    let shape = Shape::new(N, 2, 2, 3).unwrap();
    let mut rng = Lcg(3);
    let mut theta: Vec<f64> = (0..shape.len()).map(|_| 0.3 * rng.next_f64()).collect();
    // A(0): eight damped rotations; A(1..3) small beside them.
    let a0 = damped_rotations(N, |k| (0.6 + 0.03 * k as f64, 0.2 + 0.35 * k as f64));
    theta[shape.block(Matrix::A, 0)].copy_from_slice(&a0);
    for i in 1..4 {
        for v in &mut theta[shape.block(Matrix::A, i)] {
            *v *= 0.02;
        }
    }
    let z = (0..LINES)
        .map(|k| C64::from_polar(1.0, 0.05 + 3.0 * k as f64 / (LINES - 1) as f64))
        .collect();
    (shape, theta, z)
}

/// The model's data with noise, and a start near the model.
fn problem() -> (Problem, Vec<f64>) {
    let (shape, theta, z) = model();
    let mut g = frequency_response(&ModelAt::new(shape, &theta, &basis(), POINTS), &z).unwrap();
    let mut rng = Lcg(5);
    for v in g.iter_mut() {
        *v += 0.01 * C64::new(rng.next_f64(), rng.next_f64());
    }
    let sigma = vec![0.01; g.len()];
    let data = FrfData::new(POINTS, 2, 2, z, g, &sigma).unwrap();
    let start = theta
        .iter()
        .map(|t| t * (1.0 + 0.05 * rng.next_f64()))
        .collect();
    (Problem::new(shape, data, &basis()).unwrap(), start)
}

#[test]
fn a_big_problems_step_goes_through_its_points_factors_and_is_the_dense_step() {
    let (p, start) = problem();
    let all = FreeSet::all(start.len());
    // D fixed, and a scattered few of the other parameters.
    let mask: Vec<bool> = (0..start.len())
        .map(|u| u % 11 != 4 && !p.shape().block(Matrix::D, 0).contains(&u))
        .collect();
    for free in [all, FreeSet::from_mask(&mask)] {
        let gn = p.gauss_newton(&start, &free).unwrap();
        let factors = gn.factors.as_ref().expect("1296 parameters: factored");
        // 68 = n (l + r) + l r: what the similarity transformations leave.
        assert_eq!(factors.ranks(), vec![68; POINTS]);
        let diag = marquardt_diagonal(&gn);
        let system = LmSystem::new(&gn, &diag).unwrap();
        assert!(matches!(system, LmSystem::Factored(_)));
        for mu in [1e-4, 1e-2, 1.0] {
            let dense = lm_step(&gn, &diag, mu).unwrap().unwrap();
            let factored = system.step(&gn, &diag, mu).unwrap().unwrap();
            let err = relative_gap(&factored, &dense);
            assert!(err < 1e-7, "{} free, mu {mu}: {err:e}", free.len());
        }
    }
}

#[test]
fn a_small_problem_keeps_the_dense_step() {
    let (p, start) = problem();
    // The constant coefficients alone: 324 free parameters.
    let mask: Vec<bool> = (0..start.len())
        .map(|u| {
            Matrix::ALL
                .iter()
                .any(|&x| p.shape().block(x, 0).contains(&u))
        })
        .collect();
    let gn = p.gauss_newton(&start, &FreeSet::from_mask(&mask)).unwrap();
    assert_eq!(gn.dim(), 324);
    assert!(gn.factors.is_none());
}

#[test]
fn a_factored_fit_takes_the_same_steps_on_one_thread_and_on_two() {
    let (p, start) = problem();
    let free = FreeSet::all(start.len());
    let settings = LmSettings {
        max_iter: 6,
        lambda0: 1e-3,
        ..LmSettings::default()
    };
    let run = |threads| {
        on_threads(threads, || {
            levenberg_marquardt(&p, &start, &free, &settings, &mut Silent).unwrap()
        })
    };
    let (one, two) = (run(1), run(2));
    assert!(one.vnls < p.cost(&start).unwrap());
    assert_eq!(one.history.len(), two.history.len());
    for (a, b) in one.history.iter().zip(&two.history) {
        assert_eq!(
            (a.accepted, a.vnls.to_bits()),
            (b.accepted, b.vnls.to_bits())
        );
    }
    assert_eq!(one.theta, two.theta);
}

/// The factored and the dense route's cone steps from the start, damping
/// `mu`, at `gamma`, kept off `pinned`'s directions when given:
/// `(factored, dense)`.
fn cone_steps(gamma: f64, mus: &[f64], pinned: Option<&PinnedBasis>) -> Vec<(ConeStep, ConeStep)> {
    let (p, start) = problem();
    let free = FreeSet::all(start.len());
    let gn = p.gauss_newton(&start, &free).unwrap();
    assert!(gn.factors.is_some());
    let mut dense = gn.clone();
    dense.factors = None;
    let diag = marquardt_diagonal(&gn);
    let settings = L21Settings {
        gamma,
        ..L21Settings::default()
    };
    let groups = cone_groups(p.shape(), &free, &[1.0; 3], &start, &settings).unwrap();
    let cone = |gn, mu| {
        let problem = ConeProblem {
            gn,
            diag: &diag,
            theta: &start,
            groups: &groups,
            gamma,
            n_residuals: p.n_residuals() as f64,
            pinned,
            newton: true,
        };
        problem.solve(mu, &mut ConeSolver::new(1e-10)).unwrap()
    };
    mus.iter()
        .map(|&mu| (cone(&gn, mu), cone(&dense, mu)))
        .collect()
}

#[test]
fn a_big_problems_cone_step_through_its_points_factors_is_the_dense_step() {
    // A small gamma keeps the groups open (972 grouped parameters with
    // mu >= 1e-4: the factored Newton systems); a larger one takes some to
    // zero (the dense system of the rest).
    let mut zeroed = Vec::new();
    for gamma in [1e-3, 1.0] {
        let mus = [1e-8, 1e-4, 1e-2];
        for ((a, b), mu) in cone_steps(gamma, &mus, None).into_iter().zip(mus) {
            assert!(a.status.contains("Newton") && b.status.contains("Newton"));
            assert_eq!(a.iterations, b.iterations, "gamma {gamma} mu {mu}");
            assert_eq!(a.zeroed, b.zeroed, "gamma {gamma} mu {mu}");
            let (sa, sb) = (a.step.unwrap(), b.step.unwrap());
            let err = relative_gap(&sa, &sb);
            assert!(err < 1e-11, "gamma {gamma} mu {mu}: {err:e}");
            if gamma == 1e-3 {
                // The factored route ran: other last bits.
                assert_ne!(sa, sb);
            }
            zeroed.push(a.zeroed);
        }
    }
    assert_eq!(zeroed[1..3], [0, 0], "{zeroed:?}");
    assert!(zeroed[3..].iter().all(|&z| z > 0), "{zeroed:?}");
}

#[test]
fn a_cone_step_kept_off_directions_never_goes_through_the_points_factors() {
    // The pinned curvature is not of the factors' form: with it the
    // factors the evaluation brought are left alone, and the step is the
    // dense route's to the last bit (through the factors, Newton's
    // method would solve with a Hessian that lacks that curvature).
    let nf = model().0.len();
    let pinned = Pinned {
        dirs: Mat::from_fn(nf, 2, |i, k| ((i * (k + 3)) as f64 * 0.37).sin()),
        exempt: Mat::zeros(nf, 0),
        weight: 1.0,
    };
    let basis = pinned.basis(&vec![1.0; nf]).unwrap().unwrap();
    for (a, b) in cone_steps(1e-3, &[1e-4, 1e-2], Some(&basis)) {
        assert!(a.status.contains("Newton"), "{}", a.status);
        assert_eq!(a.iterations, b.iterations);
        assert_eq!(a.step.unwrap(), b.step.unwrap());
    }
}

#[test]
fn a_factored_cone_step_that_newton_gives_up_on_is_the_cone_solvers_on_the_whole_quadratic() {
    // gamma 1e-3, mu 1e-10: on the factored route Newton's method gives
    // up and Clarabel takes the program, whose quadratic needs the Schur
    // complement the factored route left to its products; its step is
    // the dense route's (solved by Newton's method) to the solvers'
    // tolerances. Without the complement it is 40 % off.
    let (a, b) = cone_steps(1e-3, &[1e-10], None).remove(0);
    assert!(
        !a.status.contains("Newton"),
        "{}: not the fallback",
        a.status
    );
    assert!(b.status.contains("Newton"), "{}", b.status);
    let err = relative_gap(&a.step.unwrap(), &b.step.unwrap());
    assert!(err < 1e-4, "{err:e}");
}
