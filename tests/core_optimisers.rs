//! The optimisers of the core on problems whose answer is known:
//! Levenberg-Marquardt (`lm.rs`) on an exact nonlinear fit and on a linear
//! least-squares problem solved independently, the cone step (`socp.rs`)
//! against the closed-form group soft-thresholding, and Algorithm 1
//! (`l21.rs`) on data from a model with known zero groups.

use lpvid::l21::cone_groups;
use lpvid::socp::{ConeGroup, ConeProblem, ConeSolver, WarmSteps};
use lpvid::testing::Lcg;
use lpvid::{
    fit_l21, frequency_response, levenberg_marquardt, Error, FreeSet, FrfData, GaussNewton,
    L21Settings, LmSettings, Matrix, ModelAt, Problem, Shape, Silent,
};
use nalgebra::{DMatrix, DVector};
use num_complex::Complex64 as C64;

const POINTS: [f64; 5] = [-1.0, -0.5, 0.0, 0.5, 1.0];
const LINES: usize = 30;
const SIGMA: f64 = 0.01;

/// A discrete-time model with n = 2, r = 1, l = 1 and the basis (p, p^2)
/// on [-1, 1]: A(0), A(1), B(0), C(0), C(1) and D(0) are non-zero; the
/// groups A(2), B(1), B(2), C(2), D(1) and D(2) are zero.
fn true_model() -> (Shape, Vec<f64>) {
    let shape = Shape::new(2, 1, 1, 2).unwrap();
    let mut theta = vec![0.0; shape.len()];
    let mut set = |x: Matrix, i: usize, values: &[f64]| {
        theta[shape.block(x, i)].copy_from_slice(values);
    };
    // Column-major: A(0) = [[0.6, 0.3], [-0.3, 0.6]].
    set(Matrix::A, 0, &[0.6, -0.3, 0.3, 0.6]);
    set(Matrix::A, 1, &[0.1, 0.0, 0.0, -0.1]);
    set(Matrix::B, 0, &[1.0, 0.5]);
    set(Matrix::C, 0, &[1.0, -0.4]);
    set(Matrix::C, 1, &[0.2, 0.3]);
    set(Matrix::D, 0, &[0.1]);
    (shape, theta)
}

fn basis() -> Vec<f64> {
    POINTS.iter().flat_map(|&p| [p, p * p]).collect()
}

fn z() -> Vec<C64> {
    (0..LINES)
        .map(|k| C64::from_polar(1.0, 0.05 + 3.0 * k as f64 / (LINES - 1) as f64))
        .collect()
}

/// The problem with the true model's FRF as data, plus `noise` times a
/// deterministic complex perturbation (in units of sigma).
fn problem(noise: f64) -> (Problem, Vec<f64>) {
    let (shape, theta) = true_model();
    let basis = basis();
    let model = ModelAt::new(shape, &theta, &basis, POINTS.len());
    let mut g = frequency_response(&model, &z()).unwrap();
    let mut rng = Lcg(5);
    for v in g.iter_mut() {
        *v += noise * SIGMA * C64::new(rng.next_f64(), rng.next_f64());
    }
    let sigma = vec![SIGMA; g.len()];
    let data = FrfData::new(POINTS.len(), 1, 1, z(), g, &sigma).unwrap();
    (Problem::new(shape, data, &basis).unwrap(), theta)
}

fn perturbed(theta: &[f64], size: f64, seed: u64) -> Vec<f64> {
    let mut rng = Lcg(seed);
    theta.iter().map(|t| t + size * rng.next_f64()).collect()
}

fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).fold(0.0, |m, (x, y)| m.max((x - y).abs()))
}

// ------------------------------------------------------------ Levenberg-Marquardt

#[test]
fn lm_reaches_the_true_frf_from_a_nearby_start() {
    let (p, truth) = problem(0.0);
    let shape = *p.shape();
    let start = perturbed(&truth, 0.04, 1);
    let v0 = p.cost(&start).unwrap();
    assert!(v0 > 1.0, "the start is not a fit: V_NLS = {v0}");
    // Free: every parameter, or only the constant parts and the true
    // groups A(1), C(1) (the zero groups fixed at zero).
    let in_structure =
        |x: Matrix, i: usize| i == 0 || (i == 1 && matches!(x, Matrix::A | Matrix::C));
    let mut structure = vec![true; truth.len()];
    for g in shape.groups() {
        if !in_structure(g.matrix, g.basis) {
            structure[g.range].iter_mut().for_each(|m| *m = false);
        }
    }
    for (mask, max_steps) in [(vec![true; truth.len()], 300), (structure, 10)] {
        let free = FreeSet::for_shape(&shape, Some(&mask)).unwrap();
        let theta0: Vec<f64> = (0..truth.len())
            .map(|i| if mask[i] { start[i] } else { truth[i] })
            .collect();
        // With the zero groups free the fit crosses a flat valley (they
        // trade against each other and the similarity transform) and
        // needs about 150 steps; with the true structure it converges
        // quadratically.
        let settings = LmSettings {
            max_iter: 300,
            ..LmSettings::default()
        };
        let fit = levenberg_marquardt(&p, &theta0, &free, &settings, &mut Silent).unwrap();
        assert!(fit.stop.converged(), "{:?}", fit.stop);
        assert!(
            fit.history.len() <= max_steps,
            "{} steps",
            fit.history.len()
        );
        // Exact data: V_NLS goes to (numerical) zero and the FRF is the
        // true one, though theta is only determined up to a similarity
        // transform.
        assert!(fit.vnls < 1e-16, "V_NLS = {}", fit.vnls);
        let e = p.residual(&fit.theta).unwrap();
        assert!(e.iter().all(|v| v.norm() * SIGMA < 1e-9));
        assert_eq!(fit.vnls, p.cost(&fit.theta).unwrap());
        // Accepted steps only ever lower V_NLS; fixed parameters never move.
        let accepted: Vec<f64> = fit
            .history
            .iter()
            .filter(|it| it.accepted)
            .map(|it| it.vnls)
            .collect();
        assert!(!accepted.is_empty());
        assert!(accepted.windows(2).all(|w| w[1] < w[0]));
        assert!((0..truth.len()).all(|i| mask[i] || fit.theta[i] == truth[i]));
    }
}

#[test]
fn lm_finds_the_minimiser_of_a_linear_least_squares_problem() {
    // Only D(0), D(1), D(2) free, from zero, with noisy data: the residual
    // is linear in them, G = G_rest + psi^T d, and the minimiser solves the
    // normal equations of Re(e) (d is real: the imaginary part is fixed).
    let (p, truth) = problem(3.0);
    let shape = *p.shape();
    let d_at = shape.block(Matrix::D, 0).start;
    let mut start = truth.clone();
    start[d_at..].iter_mut().for_each(|v| *v = 0.0);
    let mask: Vec<bool> = (0..shape.len()).map(|i| i >= d_at).collect();
    let free = FreeSet::for_shape(&shape, Some(&mask)).unwrap();
    // Independent solution: rows psi(q) = [1, p, p^2] per (point, line).
    let e0 = p.residual(&start).unwrap();
    let rows: Vec<[f64; 3]> = POINTS
        .iter()
        .flat_map(|&q| std::iter::repeat_n([1.0, q, q * q], LINES))
        .collect();
    let psi = DMatrix::from_fn(rows.len(), 3, |i, j| rows[i][j] / SIGMA);
    let rhs = DVector::from_iterator(e0.len(), e0.iter().map(|v| -v.re));
    let d = (psi.transpose() * &psi)
        .lu()
        .solve(&(psi.transpose() * rhs))
        .unwrap();
    let mut want = start.clone();
    want[d_at..].copy_from_slice(d.as_slice());
    let v_min = p.cost(&want).unwrap();
    let fit = levenberg_marquardt(&p, &start, &free, &LmSettings::default(), &mut Silent).unwrap();
    assert!(fit.stop.converged(), "{:?}", fit.stop);
    assert!(
        max_abs_diff(&fit.theta, &want) < 1e-9,
        "{:?}",
        &fit.theta[d_at..]
    );
    assert!((fit.vnls - v_min).abs() <= 1e-10 * v_min);
    // The noise is there: the minimum is well above zero.
    assert!(v_min > 0.1 * p.n_residuals() as f64);
    // Fixed parameters never move.
    assert_eq!(fit.theta[..d_at], start[..d_at]);
}

#[test]
fn a_start_whose_vnls_is_not_finite_is_refused() {
    let (p, truth) = problem(0.0);
    let shape = *p.shape();
    let mut huge = truth.clone();
    // |G| ~ 1e200 / sigma: finite residuals, V_NLS overflows.
    for x in [Matrix::B, Matrix::C] {
        huge[shape.block(x, 0)].iter_mut().for_each(|v| *v *= 1e100);
    }
    assert!(p.residual(&huge).unwrap().iter().all(|v| v.is_finite()));
    assert!(!p.cost(&huge).unwrap().is_finite());
    let free = FreeSet::all(truth.len());
    let is_model_error = |r: lpvid::Result<lpvid::Fit>| match r {
        Err(Error::InvalidArgument { name, message }) => {
            name == "model" && message.starts_with("V_NLS at the start is not finite")
        }
        _ => false,
    };
    let lm = levenberg_marquardt(&p, &huge, &free, &LmSettings::default(), &mut Silent);
    assert!(is_model_error(lm));
    for gamma in [0.0, 0.1] {
        let settings = L21Settings {
            gamma,
            ..L21Settings::default()
        };
        let l21 = fit_l21(&p, &huge, &free, &[1.0, 1.0], &settings, None, &mut Silent);
        assert!(is_model_error(l21));
    }
}

// --------------------------------------------------------------------- cone step

/// The minimiser of `(a/2) ||v - c||^2 + lambda ||v||`: group soft-thresholding.
fn soft_threshold(c: &[f64], a: f64, lambda: f64) -> Vec<f64> {
    let norm = c.iter().map(|x| x * x).sum::<f64>().sqrt();
    let keep = (1.0 - lambda / (a * norm)).max(0.0);
    c.iter().map(|x| keep * x).collect()
}

/// The pieces of a cone step whose reduced quadratic is `a_g I` on every
/// group: the free parameters are three groups (positions 0-1, 2-4, 5) and
/// two ungrouped ones (6, 7), coupled to the groups through `coupling`.
struct ConeCase {
    gn: GaussNewton,
    diag: Vec<f64>,
    theta: Vec<f64>,
    groups: Vec<ConeGroup>,
    q: DVector<f64>,
    w: DMatrix<f64>,
}

const CASE_GROUPS: [&[usize]; 3] = [&[0, 1], &[2, 3, 4], &[5]];
const CASE_A: [f64; 3] = [1.5, 0.8, 2.0];
const CASE_M: f64 = 10.0;
const CASE_GAMMA: f64 = 0.3;
const CASE_PHI: [f64; 3] = [1.0, 4.0, 0.5];
const CASE_VARPHI: [f64; 3] = [1.0, 0.5, 3.0];

fn cone_setup(coupling: f64, mu: f64, seed: u64) -> ConeCase {
    let mut rng = Lcg(seed);
    let (nk, nu) = (6, 2);
    let nf = nk + nu;
    // P = (2/M)(H + mu D) with P_UU = I, P_GU = W, P_GG = diag(a_g) + W W^T:
    // the Schur complement onto the groups is diag(a_g).
    let w = DMatrix::from_fn(nk, nu, |_, _| coupling * rng.next_f64());
    let mut p = DMatrix::zeros(nf, nf);
    let mut a_of = vec![0.0; nk];
    for (g, at) in CASE_GROUPS.iter().enumerate() {
        for &i in *at {
            a_of[i] = CASE_A[g];
        }
    }
    let p_gg = DMatrix::from_diagonal(&DVector::from_vec(a_of)) + &w * w.transpose();
    p.view_mut((0, 0), (nk, nk)).copy_from(&p_gg);
    p.view_mut((0, nk), (nk, nu)).copy_from(&w);
    p.view_mut((nk, 0), (nu, nk)).copy_from(&w.transpose());
    p.view_mut((nk, nk), (nu, nu)).fill_with_identity();
    // H = (M/2) P - mu D with the Marquardt diagonal D = 1 (any D works
    // that keeps H's structure; the step sees only H + mu D).
    let diag = vec![1.0; nf];
    let gram = &p * (CASE_M / 2.0) - DMatrix::identity(nf, nf) * mu;
    let q = DVector::from_fn(nf, |_, _| rng.next_f64());
    let gn = GaussNewton {
        vnls: 1.0,
        gradient: (&q * CASE_M).as_slice().to_vec(),
        gram: gram.as_slice().to_vec(),
        factors: None,
    };
    let theta: Vec<f64> = (0..nf).map(|_| rng.next_f64()).collect();
    let groups: Vec<ConeGroup> = CASE_GROUPS
        .iter()
        .enumerate()
        .map(|(g, at)| ConeGroup {
            entries: at.iter().map(|&i| (i, Some(i))).collect(),
            phi: CASE_PHI[g],
            varphi: CASE_VARPHI[g],
        })
        .collect();
    ConeCase {
        gn,
        diag,
        theta,
        groups,
        q,
        w,
    }
}

impl ConeCase {
    fn cone(&self) -> ConeProblem<'_> {
        ConeProblem {
            gn: &self.gn,
            diag: &self.diag,
            theta: &self.theta,
            groups: &self.groups,
            gamma: CASE_GAMMA,
            n_residuals: CASE_M,
            pinned: None,
            newton: true,
        }
    }
}

/// The step of [`cone_setup`], its closed form and the number of groups
/// that the closed form removes (`theta_g + d_g = 0`).
fn cone_case(coupling: f64, mu: f64, seed: u64) -> (Vec<f64>, Vec<f64>, usize) {
    let case = cone_setup(coupling, mu, seed);
    let (nk, nu) = (6, 2);
    let nf = nk + nu;
    let (q, w, theta) = (&case.q, &case.w, &case.theta);
    let step = case
        .cone()
        .solve(mu, &mut ConeSolver::new(1e-10))
        .expect("memory")
        .step
        .expect("solved");
    // Closed form: eliminate the ungrouped part, d_U = -(q_U + W^T d_G);
    // the reduced linear term is q_G - W q_U, and per group
    // v_g = theta_g + d_g = soft_threshold(theta_g - q~_g / a_g).
    let q_g = q.rows(0, nk) - w * q.rows(nk, nu);
    let mut want = vec![0.0; nf];
    let mut removed = 0;
    for (g, at) in CASE_GROUPS.iter().enumerate() {
        let c: Vec<f64> = at.iter().map(|&i| theta[i] - q_g[i] / CASE_A[g]).collect();
        let lambda = CASE_GAMMA * CASE_PHI[g] * CASE_VARPHI[g];
        let v = soft_threshold(&c, CASE_A[g], lambda);
        removed += usize::from(v.iter().all(|&x| x == 0.0));
        for (&i, v) in at.iter().zip(v) {
            want[i] = v - theta[i];
        }
    }
    let d_g = DVector::from_column_slice(&want[..nk]);
    let d_u = -(q.rows(nk, nu) + w.transpose() * d_g);
    want[nk..].copy_from_slice(d_u.as_slice());
    (step, want, removed)
}

/// A rejected step's successor, started from it, is the step solved anew
/// to the solve's tolerance; after `forget` (a new point) a step starts
/// from zero again, the same to the last bit.
#[test]
fn warm_steps_are_those_solved_anew() {
    let (a, b) = (cone_setup(0.7, 0.0, 3), cone_setup(0.7, 0.0, 4));
    let fresh = |case: &ConeCase, mu: f64| {
        let solved = case.cone().solve(mu, &mut ConeSolver::new(1e-10)).unwrap();
        solved.step.expect("solved")
    };
    let (mu, next) = (0.25, 1.0);
    let mut steps = WarmSteps::new(1e-10);
    let first = steps.solve(&a.cone(), mu).unwrap();
    assert_eq!(first.step.unwrap(), fresh(&a, mu));
    // The rejection's step, from the first.
    let second = steps.solve(&a.cone(), next).unwrap().step.unwrap();
    assert!(max_abs_diff(&second, &fresh(&a, next)) < 1e-9);
    // The point changes: the step at the new point, from zero.
    steps.forget();
    let moved = steps.solve(&b.cone(), next).unwrap();
    assert_eq!(moved.step.unwrap(), fresh(&b, next));
    assert!(max_abs_diff(&fresh(&a, next), &fresh(&b, next)) > 1e-3);
}

#[test]
fn cone_step_is_group_soft_thresholding() {
    let (mut removed, mut cases) = (0, 0);
    for seed in 0..6 {
        for (coupling, mu) in [(0.0, 0.0), (0.7, 0.0), (0.7, 0.25)] {
            let (step, want, r) = cone_case(coupling, mu, seed);
            assert!(
                max_abs_diff(&step, &want) < 1e-8,
                "seed {seed}, coupling {coupling}, mu {mu}: {step:?} vs {want:?}"
            );
            removed += r;
            cases += 3;
        }
    }
    // The cases cover both sides of the threshold.
    assert!(
        removed > 0 && removed < cases,
        "{removed} of {cases} groups removed"
    );
}

// ------------------------------------------------------------------- Algorithm 1

/// Relative magnitudes (23) of every group at theta, as the fit uses them.
fn magnitudes(p: &Problem, theta: &[f64], settings: &L21Settings) -> Vec<f64> {
    let free = FreeSet::all(theta.len());
    cone_groups(p.shape(), &free, &[1.0, 1.0], theta, settings)
        .unwrap()
        .iter()
        .map(|g| g.varphi * g.norm_at(theta))
        .collect()
}

#[test]
fn fit_l21_drops_exactly_the_zero_groups() {
    let (p, truth) = problem(0.0);
    let shape = *p.shape();
    // Every group of the start is in use, the zero ones at about 1e-2.
    let start = perturbed(&truth, 0.04, 2);
    let free = FreeSet::all(truth.len());
    // Exact data: any gamma from 1e-5 to 0.1 finds the structure; 1 and
    // more remove true groups too.
    let settings = L21Settings {
        gamma: 1e-3,
        ..L21Settings::default()
    };
    assert!(magnitudes(&p, &start, &settings).iter().all(|&m| m > 1e-3));
    let fit = fit_l21(&p, &start, &free, &[1.0, 1.0], &settings, None, &mut Silent).unwrap();
    assert!(fit.stop.converged(), "{:?}", fit.stop);
    assert!(fit
        .history
        .iter()
        .all(|it| it.kind == lpvid::StepKind::Socp));
    let kept: Vec<(Matrix, usize)> = shape
        .groups()
        .iter()
        .zip(magnitudes(&p, &fit.theta, &settings))
        .filter(|(_, m)| *m > settings.threshold)
        .map(|(g, _)| (g.matrix, g.basis))
        .collect();
    assert_eq!(kept, vec![(Matrix::A, 1), (Matrix::C, 1)]);
    // The structure found is enough: with the dropped groups fixed at
    // zero, Levenberg-Marquardt fits the exact data.
    let mut theta = fit.theta.clone();
    let mut mask = vec![true; theta.len()];
    for g in shape.groups() {
        if !kept.contains(&(g.matrix, g.basis)) {
            theta[g.range.clone()].iter_mut().for_each(|v| *v = 0.0);
            mask[g.range].iter_mut().for_each(|m| *m = false);
        }
    }
    let free = FreeSet::for_shape(&shape, Some(&mask)).unwrap();
    let refit =
        levenberg_marquardt(&p, &theta, &free, &LmSettings::default(), &mut Silent).unwrap();
    assert!(refit.vnls < 1e-16, "V_NLS = {}", refit.vnls);
}

#[test]
fn fit_l21_takes_the_same_steps_on_one_thread_and_on_two() {
    // Rejected doubtful steps (the first of a reweighting, or one after a
    // rejection) whose successors start from them (`socp::WarmSteps`): the
    // same steps to the last bit whatever the pool.
    let (p, truth) = problem(1.0);
    let start = perturbed(&truth, 0.3, 7);
    let free = FreeSet::all(truth.len());
    // A small initial damping: the first step of a reweighting is bold.
    let settings = L21Settings {
        gamma: 1e-2,
        lambda0: 1e-3,
        ..L21Settings::default()
    };
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| fit_l21(&p, &start, &free, &[1.0, 1.0], &settings, None, &mut Silent))
            .unwrap()
    };
    let (one, two) = (run(1), run(2));
    // Rejected doubtful steps: their successors were started from them.
    let h = &one.history;
    let used = (0..h.len())
        .filter(|&i| {
            !h[i].accepted && (i == 0 || h[i - 1].outer != h[i].outer || !h[i - 1].accepted)
        })
        .count();
    assert!(
        used > 0,
        "no doubtful step was rejected: no successor was started from one"
    );
    assert_eq!(one.history.len(), two.history.len());
    for (a, b) in one.history.iter().zip(&two.history) {
        assert_eq!(
            (a.accepted, a.solver_iterations, a.objective.to_bits()),
            (b.accepted, b.solver_iterations, b.objective.to_bits())
        );
    }
    assert_eq!(one.theta, two.theta);
}
