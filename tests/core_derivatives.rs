//! The analytic gradient and Gauss-Newton matrix of the core against central
//! finite differences of the residual, on small random problems.

use lpvid::testing::Lcg;
use lpvid::{FreeSet, FrfData, Matrix, ModelAt, Objective, Problem, Shape};
use num_complex::Complex64 as C64;

fn problem(n: usize, r: usize, l: usize, nb: usize, discrete: bool) -> (Problem, Vec<f64>) {
    problem_of(
        n,
        r,
        l,
        nb,
        discrete,
        &[-1.0, -1.0 / 3.0, 1.0 / 3.0, 1.0],
        13,
    )
}

/// [`problem`] at the scheduling points `s` (the basis `s, s^2, ...`), with
/// `lines` frequency lines.
fn problem_of(
    n: usize,
    r: usize,
    l: usize,
    nb: usize,
    discrete: bool,
    s: &[f64],
    lines: usize,
) -> (Problem, Vec<f64>) {
    let shape = Shape::new(n, r, l, nb).unwrap();
    let mut rng = Lcg(42 + n as u64);
    let mut theta: Vec<f64> = (0..shape.len()).map(|_| 0.3 * rng.next_f64()).collect();
    let a0 = shape.block(Matrix::A, 0);
    for k in 0..n {
        theta[a0.start + k * (n + 1)] += if discrete { 0.2 } else { -1.5 };
    }
    let n_points = s.len();
    let z: Vec<C64> = (0..lines)
        .map(|k| {
            let w = 0.1 + 0.2 * k as f64;
            if discrete {
                C64::from_polar(1.0, w)
            } else {
                C64::new(0.0, 4.0 * w)
            }
        })
        .collect();
    let basis: Vec<f64> = s
        .iter()
        .flat_map(|&s| (1..=nb).map(move |i| s.powi(i as i32)))
        .collect();
    let len = n_points * lines * l * r;
    let g: Vec<C64> = (0..len)
        .map(|_| C64::new(rng.next_f64(), rng.next_f64()))
        .collect();
    let sigma: Vec<f64> = (0..len).map(|_| 0.5 + rng.next_f64()).collect();
    let data = FrfData::new(n_points, l, r, z, g, &sigma).unwrap();
    (Problem::new(shape, data, &basis).unwrap(), theta)
}

fn real_residual(p: &Problem, theta: &[f64]) -> Vec<f64> {
    let e = p.residual(theta).unwrap();
    e.iter()
        .map(|v| v.re)
        .chain(e.iter().map(|v| v.im))
        .collect()
}

fn check(n: usize, r: usize, l: usize, nb: usize, discrete: bool, mask: Option<Vec<bool>>) {
    let (p, theta) = problem(n, r, l, nb, discrete);
    let free = FreeSet::for_shape(p.shape(), mask.as_deref()).unwrap();
    let gn = p.gauss_newton(&theta, &free).unwrap();
    let r0 = real_residual(&p, &theta);
    let v0: f64 = r0.iter().map(|x| x * x).sum();
    assert!((gn.vnls - v0).abs() <= 1e-12 * v0);
    // The response of the l2,1 fit's settled test: the same residual, real
    // and imaginary parts interleaved.
    let resp = Objective::response(&p, &theta).unwrap();
    let e = p.residual(&theta).unwrap();
    assert_eq!(resp.len(), 2 * e.len());
    for (k, v) in e.iter().enumerate() {
        assert_eq!((resp[2 * k], resp[2 * k + 1]), (v.re, v.im));
    }
    // Explicit Jacobian by central differences, free columns only.
    let h = 1e-6;
    let cols: Vec<Vec<f64>> = free
        .indices()
        .iter()
        .map(|&i| {
            let (mut up, mut down) = (theta.clone(), theta.clone());
            up[i] += h;
            down[i] -= h;
            let (ru, rd) = (real_residual(&p, &up), real_residual(&p, &down));
            ru.iter()
                .zip(&rd)
                .map(|(a, b)| (a - b) / (2.0 * h))
                .collect()
        })
        .collect();
    let m = free.len();
    let gmax = gn.gradient.iter().fold(0.0f64, |a, b| a.max(b.abs()));
    let hmax = gn.gram.iter().fold(0.0f64, |a, b| a.max(b.abs()));
    for a in 0..m {
        let g_fd: f64 = 2.0 * cols[a].iter().zip(&r0).map(|(j, r)| j * r).sum::<f64>();
        assert!(
            (gn.gradient[a] - g_fd).abs() <= 1e-6 * gmax,
            "gradient {a}: {} vs {g_fd}",
            gn.gradient[a]
        );
        for b in 0..m {
            let h_fd: f64 = cols[a].iter().zip(&cols[b]).map(|(x, y)| x * y).sum();
            let got = gn.gram[a + b * m];
            assert!(
                (got - h_fd).abs() <= 1e-6 * hmax,
                "J^T J ({a}, {b}): {got} vs {h_fd}"
            );
            assert_eq!(got, gn.gram[b + a * m]);
        }
    }
}

#[test]
fn derivatives_discrete_mimo() {
    check(3, 2, 2, 2, true, None);
}

#[test]
fn derivatives_continuous_simo() {
    check(4, 1, 3, 1, false, None);
}

#[test]
fn derivatives_lti() {
    check(2, 1, 1, 0, true, None);
}

#[test]
fn derivatives_with_fixed_parameters() {
    let shape = Shape::new(3, 2, 2, 2).unwrap();
    let mut mask = vec![true; shape.len()];
    // all of D fixed
    mask[shape.block(Matrix::D, 0).start..]
        .iter_mut()
        .for_each(|m| *m = false);
    mask[shape.block(Matrix::A, 2).start + 4] = false;
    check(3, 2, 2, 2, true, Some(mask));
}

#[test]
fn derivatives_with_gaps_of_every_width_in_a_block() {
    // Entries 1, 3 and 4 of A(0) fixed: the free ones run 0 | 2 | 5 6 7 8,
    // the second run one entry past a gap of one and the third past a gap
    // of two (runs of consecutive parameters are read from the points'
    // Gram matrices whole; a gap inside one would read the wrong entries).
    let shape = Shape::new(3, 2, 2, 2).unwrap();
    let mut mask = vec![true; shape.len()];
    for k in [1, 3, 4] {
        mask[shape.block(Matrix::A, 0).start + k] = false;
    }
    check(3, 2, 2, 2, true, Some(mask));
}

#[test]
fn singular_model_is_an_error_not_a_panic() {
    let shape = Shape::new(1, 1, 1, 0).unwrap();
    let z = vec![C64::new(0.5, 0.0), C64::new(0.0, 1.0)];
    let data = FrfData::new(1, 1, 1, z, vec![C64::new(1.0, 0.0); 2], &[1.0, 1.0]).unwrap();
    let p = Problem::new(shape, data, &[]).unwrap();
    let theta = vec![0.5, 1.0, 1.0, 0.0];
    let err = p.cost(&theta).unwrap_err();
    assert_eq!(err, lpvid::Error::Singular { point: 0, line: 0 });
    assert!(p.gauss_newton(&theta, &FreeSet::all(4)).is_err());
    // The pole on the third line of a batch of four (and on no other):
    // the error names that line, from the residuals and the Gram pieces.
    let z = vec![
        C64::new(0.0, 0.9),
        C64::new(0.0, -0.9),
        C64::new(0.5, 0.0),
        C64::new(0.8, 0.0),
    ];
    let data = FrfData::new(1, 1, 1, z, vec![C64::new(1.0, 0.0); 4], &[1.0; 4]).unwrap();
    let p = Problem::new(shape, data, &[]).unwrap();
    let at_third = lpvid::Error::Singular { point: 0, line: 2 };
    assert_eq!(p.cost(&theta).unwrap_err(), at_third);
    let err = p.gauss_newton(&theta, &FreeSet::all(4)).unwrap_err();
    assert_eq!(err, at_third);
}

/// `J^T J` and `J^T r` (all parameters free) against the same sums over the
/// rows of the explicit complex Jacobian of `sensitivity::lti_jacobian`, to
/// rounding: the Gram matrix comes from the Kronecker structure of the rows
/// (`lpvid::eval::kron_gram`), grouped by outputs when `l <= r` and by inputs
/// otherwise, over batches of lines that do not fill the last one.
fn check_against_rows(n: usize, r: usize, l: usize, nb: usize, discrete: bool) {
    let (p, theta) = problem(n, r, l, nb, discrete);
    check_rows_of(&p, &theta);
}

fn check_rows_of(p: &Problem, theta: &[f64]) {
    let shape = *p.shape();
    let free = FreeSet::for_shape(&shape, None).unwrap();
    let gn = p.gauss_newton(theta, &free).unwrap();
    let data = p.data();
    let n_points = data.n_points();
    let basis: Vec<f64> = (0..n_points).flat_map(|q| p.psi(q)[1..].to_vec()).collect();
    let model = ModelAt::new(shape, theta, &basis, n_points);
    let jac = lpvid::eval::sensitivity::lti_jacobian(&model, data.z()).unwrap();
    let e = p.residual(theta).unwrap();
    let lti = shape.lti_len();
    let rows = e.len();
    // Map every entry of theta to (basis index, LTI index).
    let mut map = vec![(0, 0); shape.len()];
    for x in Matrix::ALL {
        for i in 0..shape.n_coef() {
            for (k, u) in shape.block(x, i).enumerate() {
                map[u] = (i, shape.lti_offset(x) + k);
            }
        }
    }
    let lines = data.n_lines();
    let lr = shape.l * shape.r;
    let mut want = vec![0.0; shape.len() * shape.len()];
    let mut grad = vec![0.0; shape.len()];
    for row in 0..rows {
        let q = row / (lines * lr);
        let w = data.weight()[row];
        let jrow = &jac[row * lti..(row + 1) * lti];
        for (u, &(i, pu)) in map.iter().enumerate() {
            let ju = jrow[pu] * w * p.psi(q)[i];
            grad[u] += 2.0 * (ju.conj() * e[row]).re;
            for (v, &(k, pv)) in map.iter().enumerate() {
                let jv = jrow[pv] * w * p.psi(q)[k];
                want[u + v * shape.len()] += (ju.conj() * jv).re;
            }
        }
    }
    let hmax = want.iter().fold(0.0f64, |a, b| a.max(b.abs()));
    for (k, (got, w)) in gn.gram.iter().zip(&want).enumerate() {
        assert!(
            (got - w).abs() <= 1e-12 * hmax,
            "J^T J entry {k}: {got} vs {w}"
        );
    }
    let gmax = grad.iter().fold(0.0f64, |a, b| a.max(b.abs()));
    for (k, (got, w)) in gn.gradient.iter().zip(&grad).enumerate() {
        assert!(
            (got - w).abs() <= 1e-12 * gmax,
            "gradient {k}: {got} vs {w}"
        );
    }
}

/// Basis functions zero at every point (all points at s = 0): the sums of
/// their pairs have no term, and their blocks of `J^T J` are exactly zero.
#[test]
fn gram_of_basis_functions_zero_at_every_point_is_zero() {
    let (p, theta) = problem_of(2, 1, 2, 2, true, &[0.0, 0.0], 13);
    check_rows_of(&p, &theta);
    let shape = *p.shape();
    let gn = p.gauss_newton(&theta, &FreeSet::all(shape.len())).unwrap();
    let m = shape.len();
    let constant: Vec<usize> = Matrix::ALL
        .iter()
        .flat_map(|&x| shape.block(x, 0))
        .collect();
    let mut nonzero = 0;
    for v in 0..m {
        for u in 0..m {
            let entry = gn.gram[u + v * m];
            if constant.contains(&u) && constant.contains(&v) {
                nonzero += usize::from(entry != 0.0);
            } else {
                assert_eq!(entry, 0.0, "({u}, {v})");
            }
        }
    }
    assert!(nonzero > 0);
}

#[test]
fn gram_matches_the_rows_of_the_jacobian_more_inputs_than_outputs() {
    check_against_rows(3, 3, 2, 2, true);
}

#[test]
fn gram_matches_the_rows_of_the_jacobian_more_outputs_than_inputs() {
    check_against_rows(4, 1, 3, 1, false);
}

#[test]
fn gram_matches_the_rows_of_the_jacobian_square() {
    check_against_rows(3, 2, 2, 2, false);
}

/// Sizes whose Gram products run on the core's kernels (more than
/// `FAER_ENTRIES` entries) in parts: the entries of `Theta`'s last rows
/// over their own output's (or input's) samples alone.
#[test]
fn gram_matches_the_rows_of_the_jacobian_in_parts_by_outputs_and_by_inputs() {
    check_against_rows(6, 3, 2, 1, false);
    check_against_rows(6, 2, 3, 1, true);
    check_against_rows(5, 3, 3, 1, false);
}

/// Several tasks a point (56 lines a task at 3 x 3): the buffers of a
/// summed part go to a later task, whose first products write over them.
#[test]
fn gram_matches_the_rows_of_the_jacobian_over_several_tasks_a_point() {
    let (p, theta) = problem_of(5, 3, 3, 1, false, &[-0.5, 0.5], 200);
    check_rows_of(&p, &theta);
}

/// Several blocks of samples a task (SISO: 512 lines a task, 256 samples a
/// block): the block's products are flushed into the sums in the middle of
/// a task, and the next block's samples go into the same buffers.
#[test]
fn gram_matches_the_rows_of_the_jacobian_over_several_blocks_a_task() {
    let (p, theta) = problem_of(4, 1, 1, 1, true, &[-0.5, 0.5], 600);
    check_rows_of(&p, &theta);
}

#[test]
fn the_response_of_a_sum_is_that_of_its_parts_one_after_the_other() {
    let (a, theta) = problem(2, 1, 2, 1, true);
    let (b, _) = problem(2, 1, 2, 1, false);
    let sum = lpvid::eval::sum::Sum::new(vec![&a, &b]).unwrap();
    let mut want = Objective::response(&a, &theta).unwrap();
    want.extend(Objective::response(&b, &theta).unwrap());
    let got = sum.response(&theta).unwrap();
    assert_eq!(got, want);
    let v: f64 = got.iter().map(|x| x * x).sum();
    let cost = sum.cost(&theta).unwrap();
    assert!((v - cost).abs() <= 1e-12 * cost);
}

#[test]
fn the_cost_is_the_vnls_of_the_gauss_newton_pieces_to_the_last_bit() {
    // The fits judge a doubtful step by its cost alone and take the
    // pieces' V_NLS once it is taken: the two must agree bit for bit.
    for (n, r, l, nb, discrete) in [(3, 2, 2, 2, true), (4, 1, 3, 1, false), (2, 3, 1, 0, true)] {
        let (p, theta) = problem(n, r, l, nb, discrete);
        let (other, _) = problem(n, r, l, nb, !discrete);
        let mask: Vec<bool> = (0..theta.len()).map(|i| i % 4 != 1).collect();
        let free = FreeSet::from_mask(&mask);
        let gn = p.gauss_newton(&theta, &free).unwrap();
        assert_eq!(p.cost(&theta).unwrap().to_bits(), gn.vnls.to_bits());
        let sum = lpvid::eval::sum::Sum::new(vec![&p, &other]).unwrap();
        let total = Objective::gauss_newton(&sum, &theta, &free).unwrap();
        assert_eq!(sum.cost(&theta).unwrap().to_bits(), total.vnls.to_bits());
    }
}

#[test]
fn a_problem_evaluated_again_gives_the_bits_of_a_fresh_one() {
    // A problem keeps its evaluations' workspaces for the next one
    // (`lpvid::eval::workspace`): whatever it evaluated before, a singular
    // model stopped partway through a task included, every piece must come
    // out as from a copy that never evaluated anything.
    let shape = Shape::new(2, 1, 2, 1).unwrap();
    let lines = 1300; // several tasks a point, the last one part full
    let at = 900; // z = 1 exactly on this line, e^{i w} on the others
    let z: Vec<C64> = (0..lines)
        .map(|k| match k {
            k if k == at => C64::new(1.0, 0.0),
            k => C64::from_polar(1.0, 0.01 + 0.002 * k as f64),
        })
        .collect();
    let mut rng = Lcg(9);
    let len = 3 * lines * 2;
    let g: Vec<C64> = (0..len)
        .map(|_| C64::new(rng.next_f64(), rng.next_f64()))
        .collect();
    let sigma: Vec<f64> = (0..len).map(|_| 0.5 + rng.next_f64()).collect();
    let data = FrfData::new(3, 2, 1, z, g, &sigma).unwrap();
    let p = Problem::new(shape, data, &[-1.0, 0.0, 1.0]).unwrap();
    let fresh = p.clone();
    let mut theta: Vec<f64> = (0..shape.len()).map(|_| 0.3 * rng.next_f64()).collect();
    // A(psi) upper triangular: A_0 = [0.5 0.1; 0 0.3], A_1 = [a 0; 0 -0.2].
    let (a0, a1) = (
        shape.block(Matrix::A, 0).start,
        shape.block(Matrix::A, 1).start,
    );
    let a = |theta: &mut Vec<f64>, corner: f64| {
        theta[a0..a0 + 4].copy_from_slice(&[0.5, 0.0, 0.1, 0.3]);
        theta[a1..a1 + 4].copy_from_slice(&[corner, 0.0, 0.0, -0.2]);
    };
    a(&mut theta, 0.45);
    let bits = |p: &Problem, theta: &[f64]| {
        let gn = p.gauss_newton(theta, &FreeSet::all(theta.len())).unwrap();
        let mut out = vec![gn.vnls.to_bits()];
        out.extend(gn.gradient.iter().chain(&gn.gram).map(|x| x.to_bits()));
        out
    };
    let want = bits(&fresh, &theta);
    let mut other = theta.clone();
    other.iter_mut().for_each(|x| *x *= 0.9);
    assert_ne!(bits(&p, &other), want);
    assert_eq!(bits(&p, &theta), want);
    // At the last point (psi = 1) a pole at z = 1, on line 900: the task
    // that holds it has summed some of its lines when it stops.
    let mut singular = theta.clone();
    a(&mut singular, 0.5);
    let err = p.gauss_newton(&singular, &FreeSet::all(theta.len()));
    assert_eq!(
        err.unwrap_err(),
        lpvid::Error::Singular { point: 2, line: at }
    );
    assert_eq!(bits(&p, &theta), want);
    assert_eq!(bits(&p, &theta), want);
}
