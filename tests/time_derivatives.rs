//! The time-record cost: its analytic gradient and Gauss-Newton matrix
//! against central finite differences of the residual (discrete and
//! continuous time, several inputs and outputs, initial states zero, given
//! and estimated), and its errors.

use lpvid::testing::{time_model as model, time_records as records};
use lpvid::{FreeSet, InitialState, Matrix, Objective, Record, Shape, TimeProblem};

/// Solve `a x = b` (small, dense, column-major `k x k`) by Gauss-Jordan.
fn solve(k: usize, a: &[f64], b: &[f64], cols: usize) -> Vec<f64> {
    let mut m = a.to_vec();
    let mut x = b.to_vec();
    for c in 0..k {
        let p = (c..k)
            .max_by(|&i, &j| m[i + c * k].abs().total_cmp(&m[j + c * k].abs()))
            .unwrap();
        for j in 0..k {
            m.swap(c + j * k, p + j * k);
        }
        for j in 0..cols {
            x.swap(c + j * k, p + j * k);
        }
        let d = m[c + c * k];
        for i in 0..k {
            if i != c {
                let f = m[i + c * k] / d;
                for j in 0..k {
                    m[i + j * k] -= f * m[c + j * k];
                }
                for j in 0..cols {
                    x[i + j * k] -= f * x[c + j * k];
                }
            }
        }
    }
    for i in 0..k {
        for j in 0..cols {
            x[i + j * k] /= m[i + i * k];
        }
    }
    x
}

/// Central differences of the residual with respect to the free entries of
/// theta (at the initial states `x0`, `records x n`) and, when `wrt_x0`,
/// to the initial states (appended columns).
fn jacobian(
    make: &dyn Fn(InitialState) -> TimeProblem,
    theta: &[f64],
    free: &FreeSet,
    x0: &[f64],
    wrt_x0: bool,
) -> Vec<Vec<f64>> {
    let h = 1e-6;
    let base = make(InitialState::Given(x0.to_vec()));
    let mut cols = Vec::new();
    for &i in free.indices() {
        let step = h * theta[i].abs().max(1.0);
        let (mut up, mut down) = (theta.to_vec(), theta.to_vec());
        up[i] += step;
        down[i] -= step;
        let (a, b) = (base.residual(&up).unwrap(), base.residual(&down).unwrap());
        cols.push(
            a.iter()
                .zip(&b)
                .map(|(p, q)| (p - q) / (2.0 * step))
                .collect(),
        );
    }
    if wrt_x0 {
        for k in 0..x0.len() {
            let (mut up, mut down) = (x0.to_vec(), x0.to_vec());
            up[k] += h;
            down[k] -= h;
            let a = make(InitialState::Given(up)).residual(theta).unwrap();
            let b = make(InitialState::Given(down)).residual(theta).unwrap();
            cols.push(a.iter().zip(&b).map(|(p, q)| (p - q) / (2.0 * h)).collect());
        }
    }
    cols
}

fn check_with(
    shape: Shape,
    hold: Option<f64>,
    initial: InitialState,
    skip: usize,
    is_free: &dyn Fn(usize) -> bool,
) {
    let theta = model(&shape, hold.is_none(), 5 + shape.n as u64);
    let recs = records(&shape, &[70, 45], 17);
    let make =
        |init: InitialState| TimeProblem::new(shape, recs.clone(), init, hold, skip).unwrap();
    let problem = make(initial.clone());
    let mask: Vec<bool> = (0..shape.len()).map(is_free).collect();
    let free = FreeSet::from_mask(&mask);
    let gn = problem.gauss_newton(&theta, &free).unwrap();
    let v = problem.cost(&theta).unwrap();
    assert!((gn.vnls - v).abs() <= 1e-12 * v, "{} vs {v}", gn.vnls);
    assert_eq!(
        Objective::response(&problem, &theta).unwrap(),
        problem.residual(&theta).unwrap()
    );
    assert_eq!(
        problem.residual(&theta).unwrap().len(),
        problem.n_residuals()
    );
    // The gradient against central differences of the cost (for estimated
    // initial states: of the least cost over them).
    let scale = gn.gradient.iter().fold(1.0f64, |a, g| a.max(g.abs()));
    for (k, &i) in free.indices().iter().enumerate() {
        let step = 1e-6 * theta[i].abs().max(1.0);
        let (mut up, mut down) = (theta.clone(), theta.clone());
        up[i] += step;
        down[i] -= step;
        let fd = (problem.cost(&up).unwrap() - problem.cost(&down).unwrap()) / (2.0 * step);
        assert!(
            (fd - gn.gradient[k]).abs() <= 2e-6 * scale,
            "gradient {k}: {} vs {fd}",
            gn.gradient[k]
        );
    }
    // J^T J from the explicit Jacobian; with estimated initial states, the
    // Jacobian at the estimate over theta and x0, then the Schur complement.
    let x0 = problem.initial_states(&theta).unwrap();
    let estimated = initial == InitialState::Estimate;
    match &initial {
        InitialState::Given(v) => assert_eq!(&x0, v),
        InitialState::Zero => assert!(x0.iter().all(|&v| v == 0.0)),
        InitialState::Estimate => {}
    }
    let cols = jacobian(&make, &theta, &free, &x0, estimated);
    let k = cols.len();
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(p, q)| p * q).sum::<f64>();
    let full: Vec<f64> = (0..k * k)
        .map(|e| dot(&cols[e % k], &cols[e / k]))
        .collect();
    let nf = free.len();
    let want: Vec<f64> = if estimated {
        let nx = k - nf;
        let gxx: Vec<f64> = (0..nx * nx)
            .map(|e| full[nf + e % nx + (nf + e / nx) * k])
            .collect();
        let gxt: Vec<f64> = (0..nx * nf)
            .map(|e| full[nf + e % nx + (e / nx) * k])
            .collect();
        let sol = solve(nx, &gxx, &gxt, nf);
        (0..nf * nf)
            .map(|e| {
                let (a, b) = (e % nf, e / nf);
                full[a + b * k]
                    - (0..nx)
                        .map(|c| full[a + (nf + c) * k] * sol[c + b * nx])
                        .sum::<f64>()
            })
            .collect()
    } else {
        full
    };
    let big = want.iter().fold(1.0f64, |a, v| a.max(v.abs()));
    for (e, (g, w)) in gn.gram.iter().zip(&want).enumerate() {
        assert!(
            (g - w).abs() <= 2e-6 * big,
            "gram ({}, {}): {g} vs {w}",
            e % nf,
            e / nf
        );
    }
}

/// `check_with` with every `fixed_every`-th parameter (from the second) fixed.
fn check(shape: Shape, hold: Option<f64>, initial: InitialState, skip: usize, fixed_every: usize) {
    check_with(shape, hold, initial, skip, &|i| {
        fixed_every == 0 || i % fixed_every != 1
    });
}

#[test]
fn discrete_time_mimo_with_zero_and_given_initial_states() {
    check(
        Shape::new(3, 2, 2, 2).unwrap(),
        None,
        InitialState::Zero,
        0,
        0,
    );
    let given = InitialState::Given(vec![0.3, -0.2, 0.5, 0.1, 0.0, -0.4]);
    check(Shape::new(3, 2, 2, 2).unwrap(), None, given, 5, 7);
}

#[test]
fn discrete_time_with_estimated_initial_states() {
    check(
        Shape::new(3, 2, 2, 2).unwrap(),
        None,
        InitialState::Estimate,
        0,
        0,
    );
    check(
        Shape::new(2, 1, 3, 3).unwrap(),
        None,
        InitialState::Estimate,
        4,
        5,
    );
}

#[test]
fn continuous_time_through_the_zero_order_hold() {
    // dt = 0.05: no squaring in the exponential; dt = 0.6: several.
    check(
        Shape::new(3, 2, 2, 2).unwrap(),
        Some(0.05),
        InitialState::Zero,
        0,
        0,
    );
    check(
        Shape::new(3, 2, 2, 2).unwrap(),
        Some(0.6),
        InitialState::Estimate,
        3,
        0,
    );
    check(
        Shape::new(2, 1, 2, 1).unwrap(),
        Some(0.3),
        InitialState::Estimate,
        0,
        4,
    );
}

#[test]
fn a_diverging_model_is_an_error_naming_the_record_and_sample() {
    let shape = Shape::new(2, 1, 1, 1).unwrap();
    let mut theta = model(&shape, true, 3);
    let a0 = shape.block(Matrix::A, 0);
    theta[a0.start] = 3.0;
    let problem = TimeProblem::new(
        shape,
        records(&shape, &[50, 900], 4),
        InitialState::Estimate,
        None,
        0,
    )
    .unwrap();
    let free = FreeSet::all(shape.len());
    for err in [
        problem.cost(&theta).unwrap_err(),
        problem.gauss_newton(&theta, &free).unwrap_err(),
    ] {
        let text = err.to_string();
        assert!(
            text.starts_with("model: diverges along time record 1"),
            "{text}"
        );
        assert!(text.contains(" sample "), "{text}");
    }
}

#[test]
fn bad_records_and_settings_are_named() {
    let shape = Shape::new(2, 1, 1, 1).unwrap();
    let name = |e: lpvid::Error| match e {
        lpvid::Error::InvalidArgument { name, .. } => name,
        other => panic!("{other:?}"),
    };
    let rec = |u: usize, psi: usize, y: usize, s: f64| {
        Record::new(
            &shape,
            vec![0.0; u],
            vec![0.0; psi],
            vec![0.0; y],
            &vec![s; y],
        )
    };
    assert_eq!(name(rec(0, 0, 0, 1.0).unwrap_err()), "u");
    assert_eq!(name(rec(4, 3, 4, 1.0).unwrap_err()), "psi");
    assert_eq!(name(rec(4, 4, 3, 1.0).unwrap_err()), "y");
    assert_eq!(name(rec(4, 4, 4, 0.0).unwrap_err()), "sigma");
    let ok = rec(4, 4, 4, 1.0).unwrap();
    let make = |init, hold, skip| TimeProblem::new(shape, vec![ok.clone()], init, hold, skip);
    assert_eq!(name(make(InitialState::Zero, None, 4).unwrap_err()), "skip");
    assert_eq!(
        name(make(InitialState::Zero, Some(0.0), 0).unwrap_err()),
        "dt"
    );
    assert_eq!(
        name(make(InitialState::Given(vec![0.0]), None, 0).unwrap_err()),
        "x0"
    );
    assert_eq!(make(InitialState::Zero, None, 3).unwrap().n_residuals(), 1);
}

#[test]
fn only_output_or_only_state_parameters_free() {
    let shape = Shape::new(3, 2, 2, 2).unwrap();
    let c0 = shape.block(Matrix::C, 0).start;
    let output_only = |i: usize| i >= c0;
    let state_only = |i: usize| i < c0;
    for hold in [None, Some(0.2)] {
        check_with(shape, hold, InitialState::Zero, 2, &output_only);
        check_with(shape, hold, InitialState::Estimate, 2, &output_only);
        check_with(shape, hold, InitialState::Estimate, 0, &state_only);
    }
}
