//! Unit tests of Newton's method on the cone step (`super`): its minimiser
//! against the optimality conditions (written out with nalgebra) and
//! against Clarabel on the same cone program, and each way it gives up.

use super::*;
use crate::socp::program::{Cone, ConeSolver, Csc, Program};
use crate::testing::Lcg;
use nalgebra::{DMatrix, DVector};

/// The minimiser and the iterations, when Newton's method found it.
fn solved(out: Newton) -> Option<(Vec<f64>, u32)> {
    match out {
        Newton::Solved { x, iterations } => Some((x, iterations)),
        _ => None,
    }
}

/// A group over `x[start..start + len]` with `fixed` fixed entries of its own.
struct Spec {
    start: usize,
    len: usize,
    fixed: Vec<f64>,
    weight: f64,
}

/// A random program: `P = B B^T / k + 0.1 I` (well conditioned enough for
/// a solution determined to 1e-7), `q`, and groups with random `alpha`, `beta`.
fn random(
    n: usize,
    specs: &[Spec],
    seed: u64,
) -> (Mat<f64>, Vec<f64>, Vec<NewtonGroup>, Vec<Vec<f64>>) {
    let mut rng = Lcg(seed);
    let b = DMatrix::from_fn(n, n + 3, |_, _| rng.next_f64());
    let p = &b * b.transpose() / (n as f64) + DMatrix::identity(n, n) * 0.1;
    // A small gradient: the minimum moves each group by less than its size.
    let q: Vec<f64> = (0..n).map(|_| 0.1 * rng.next_f64()).collect();
    let mut fixed = Vec::new();
    let groups = specs
        .iter()
        .map(|s| {
            fixed.push(s.fixed.clone());
            NewtonGroup {
                start: s.start,
                alpha: (0..s.len).map(|_| 1.0 + rng.next_f64()).collect(),
                // Sizes of 1 and more: the minima stay away from the kinks.
                beta: (0..s.len).map(|_| 1.0 + rng.next_f64()).collect(),
                fixed_squares: s.fixed.iter().map(|v| v * v).sum(),
                weight: s.weight,
            }
        })
        .collect();
    (Mat::from_fn(n, n, |i, j| p[(i, j)]), q, groups, fixed)
}

fn specs(weight: f64) -> Vec<Spec> {
    vec![
        Spec {
            start: 0,
            len: 4,
            fixed: vec![],
            weight,
        },
        Spec {
            start: 4,
            len: 5,
            fixed: vec![0.7, -0.2],
            weight: 0.5 * weight,
        },
        Spec {
            start: 9,
            len: 3,
            fixed: vec![],
            weight: 2.0 * weight,
        },
    ]
}

/// `f` and its gradient, written out with nalgebra.
fn value_and_gradient(
    p: &Mat<f64>,
    q: &[f64],
    groups: &[NewtonGroup],
    x: &[f64],
) -> (f64, DVector<f64>) {
    let n = q.len();
    let pm = DMatrix::from_fn(n, n, |i, j| p[(i, j)]);
    let xv = DVector::from_column_slice(x);
    let qv = DVector::from_column_slice(q);
    let mut grad = &pm * &xv + &qv;
    let mut f = 0.5 * xv.dot(&(&pm * &xv)) + qv.dot(&xv);
    for g in groups {
        let z: Vec<f64> = (0..g.alpha.len())
            .map(|a| g.beta[a] + g.alpha[a] * x[g.start + a])
            .collect();
        let norm = (z.iter().map(|v| v * v).sum::<f64>() + g.fixed_squares).sqrt();
        f += g.weight * norm;
        for (a, za) in z.iter().enumerate() {
            grad[g.start + a] += g.weight * g.alpha[a] * za / norm;
        }
    }
    (f, grad)
}

#[test]
fn the_minimiser_meets_the_optimality_conditions() {
    for (seed, weight) in [(1, 0.02), (2, 0.05), (3, 0.1)] {
        // x[12] is in no group: only the quadratic holds it.
        let (p, q, groups, _) = random(13, &specs(weight), seed);
        for (tol, bound) in [(1e-8, 1e-8), (1e-12, 1e-11)] {
            let out = newton(&mut p.clone(), &q, &groups, tol, None, None, None).unwrap();
            let (x, iterations) = solved(out).expect("Newton's method converges");
            let (_, grad) = value_and_gradient(&p, &q, &groups, &x);
            let worst = grad.amax();
            assert!(
                worst < bound,
                "seed {seed}, tol {tol}: gradient {worst:.2e}"
            );
            assert!(iterations <= 12, "seed {seed}: {iterations} iterations");
        }
    }
}

#[test]
fn the_quadratic_is_given_back_as_it_came_and_a_second_call_gives_the_same() {
    let (mut p, q, groups, _) = random(13, &specs(0.05), 8);
    let before = p.clone();
    let first = solved(newton(&mut p, &q, &groups, 1e-8, None, None, None).unwrap()).unwrap();
    for j in 0..13 {
        for i in 0..13 {
            assert_eq!(p[(i, j)].to_bits(), before[(i, j)].to_bits(), "({i}, {j})");
        }
    }
    let second = solved(newton(&mut p, &q, &groups, 1e-8, None, None, None).unwrap()).unwrap();
    assert_eq!(first.1, second.1);
    assert!(first
        .0
        .iter()
        .zip(&second.0)
        .all(|(a, b)| a.to_bits() == b.to_bits()));
}

#[test]
fn a_looser_tolerance_stops_earlier_at_an_answer_near_the_tight_one() {
    let (p, q, groups, _) = random(13, &specs(0.05), 2);
    let (tight, slow) =
        solved(newton(&mut p.clone(), &q, &groups, 1e-14, None, None, None).unwrap()).unwrap();
    let (loose, fast) =
        solved(newton(&mut p.clone(), &q, &groups, 1e-2, None, None, None).unwrap()).unwrap();
    assert!(fast < slow, "{fast} vs {slow} iterations");
    // One full step after a decrement of 1e-2: within about the decrement's square root.
    let diff = loose
        .iter()
        .zip(&tight)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(diff > 0.0 && diff < 0.1, "{diff}");
}

/// The same problem as Clarabel's program over `[x; t]`, each cone
/// `(t_g, z_g)` with its fixed entries as constant rows.
fn as_program(p: &Mat<f64>, q: &[f64], groups: &[NewtonGroup], fixed: &[Vec<f64>]) -> Program {
    let n = q.len();
    let mut pc = Csc::new();
    for c in 0..n {
        pc.push((0..=c).map(|i| (i, p[(i, c)])));
    }
    groups.iter().for_each(|_| pc.push([]));
    // Rows: per group t, its free entries, its fixed entries.
    let mut b = Vec::new();
    let mut cones = Vec::new();
    let mut x_rows = vec![None; n];
    let mut t_rows = Vec::new();
    for (g, fx) in groups.iter().zip(fixed) {
        t_rows.push(b.len());
        b.push(0.0);
        for a in 0..g.alpha.len() {
            x_rows[g.start + a] = Some((b.len(), -g.alpha[a]));
            b.push(g.beta[a]);
        }
        b.extend(fx);
        cones.push(Cone::Soc(1 + g.alpha.len() + fx.len()));
    }
    let mut a = Csc::new();
    for row in &x_rows {
        a.push(row.iter().copied());
    }
    for &row in &t_rows {
        a.push([(row, -1.0)]);
    }
    let mut qq = q.to_vec();
    qq.extend(groups.iter().map(|g| g.weight));
    Program {
        p: pc,
        q: qq,
        a,
        b,
        cones,
    }
}

/// Clarabel's minimiser of the same program, to its gap of 1e-10.
fn clarabels(p: &Mat<f64>, q: &[f64], groups: &[NewtonGroup], fixed: &[Vec<f64>]) -> Vec<f64> {
    let reference = ConeSolver::new(1e-10)
        .run(&as_program(p, q, groups, fixed))
        .unwrap()
        .unwrap();
    reference.x[..q.len()].to_vec()
}

/// Newton's minimiser agrees with Clarabel's (its gap of 1e-10 bounds its
/// error by sqrt(2e-10 / 0.1)) and is no worse (to rounding).
fn assert_clarabels(p: &Mat<f64>, q: &[f64], groups: &[NewtonGroup], x: &[f64], x_ref: &[f64]) {
    let diff = x
        .iter()
        .zip(x_ref)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(diff < 5e-5, "{diff:.2e}");
    let (f, _) = value_and_gradient(p, q, groups, x);
    let (f_ref, _) = value_and_gradient(p, q, groups, x_ref);
    assert!(f <= f_ref + 1e-13 * f_ref.abs(), "{f} > {f_ref}");
}

#[test]
fn the_minimiser_is_clarabels_to_its_accuracy() {
    for (seed, weight) in [(4, 0.05), (5, 0.1)] {
        let (p, q, groups, fixed) = random(13, &specs(weight), seed);
        let (x, _) =
            solved(newton(&mut p.clone(), &q, &groups, 1e-8, None, None, None).unwrap()).unwrap();
        assert_clarabels(&p, &q, &groups, &x, &clarabels(&p, &q, &groups, &fixed));
    }
}

#[test]
fn a_minimum_at_a_kink_is_found_with_the_group_held_there() {
    // A weight far above the gradient the quadratic can oppose puts the
    // first group's minimum at z = 0 (its subgradient condition holds
    // there): Newton's method holds it at zero and converges on the rest.
    let mut s = specs(0.1);
    s[0].weight = 50.0;
    let (p, q, groups, fixed) = random(13, &s, 6);
    let out = newton(&mut p.clone(), &q, &groups, 1e-8, None, None, None).unwrap();
    let (x, iterations) = solved(out).expect("solved with the group held at zero");
    assert!(groups[0].norm(&x) < 1e-14);
    // Held once two cut steps were headed for its kink: 5 iterations
    // (without that, held only when it falls below COLLAPSE: 10).
    assert!(iterations <= 6, "{iterations}");
    let x_ref = clarabels(&p, &q, &groups, &fixed);
    assert!(groups[0].norm(&x_ref) < 1e-6);
    assert_clarabels(&p, &q, &groups, &x, &x_ref);
    // Its zero is optimal: the subgradient condition at Newton's point.
    let quad: Vec<f64> = (0..13)
        .map(|i| q[i] + (0..13).map(|j| p[(i, j)] * x[j]).sum::<f64>())
        .collect();
    assert!(groups[0].zero_is_optimal(&quad));
    // A group that cannot be held (a fixed entry off zero) is named instead.
    let mut stuck = groups.clone();
    stuck[0].fixed_squares = 1e-14;
    let named = newton(&mut p.clone(), &q, &stuck, 1e-8, None, None, None).unwrap();
    assert!(matches!(named, Newton::Kink { group: 0, .. }), "{named:?}");
}

#[test]
fn a_group_at_zero_whose_minimum_is_not_there_is_let_go() {
    // Group 2 starts at z = 0 (beta = 0), but with a small weight its
    // minimum is away from zero: held at the start, let go along its
    // steepest descent, and the minimiser is Clarabel's.
    let (p, q, mut groups, fixed) = random(13, &specs(0.1), 7);
    groups[2].beta.iter_mut().for_each(|b| *b = 0.0);
    groups[2].weight = 0.01;
    let x_ref = clarabels(&p, &q, &groups, &fixed);
    assert!(
        groups[2].norm(&x_ref) > 1e-3,
        "not a test: its minimum is at zero"
    );
    let out = newton(&mut p.clone(), &q, &groups, 1e-8, None, None, None).unwrap();
    let (x, iterations) = solved(out).expect("converges after letting go");
    assert_clarabels(&p, &q, &groups, &x, &x_ref);
    assert!(iterations <= 12, "{iterations}");
    // The same from a given start: the other groups at their minimum and
    // group 2 at zero (where a refuted check leaves them).
    let mut start = x_ref.clone();
    groups[2].hold(&mut start);
    let out = newton(&mut p.clone(), &q, &groups, 1e-8, Some(start), None, None).unwrap();
    let (warm, from_there) = solved(out).expect("converges from the start given");
    assert_clarabels(&p, &q, &groups, &warm, &x_ref);
    assert!(from_there <= iterations, "{from_there} > {iterations}");
}

#[test]
fn it_gives_up_on_a_quadratic_that_is_not_convex_and_on_nan() {
    let (p, q, groups, _) = random(13, &specs(0.1), 7);
    let negative = Mat::from_fn(13, 13, |i, j| if i == j { -1.0 } else { 0.0 });
    let indefinite = newton(&mut negative.clone(), &q, &groups, 1e-8, None, None, None).unwrap();
    assert!(
        matches!(indefinite, Newton::GaveUp { iterations: 1 }),
        "P = -I: {indefinite:?}"
    );
    // A non-finite q: no answer rather than NaN.
    let mut bad = q.clone();
    bad[3] = f64::NAN;
    let nan = newton(&mut p.clone(), &bad, &groups, 1e-8, None, None, None).unwrap();
    assert!(matches!(nan, Newton::GaveUp { .. }), "NaN in q");
}

#[test]
fn closest_is_the_smallest_norm_on_the_segment() {
    let g = NewtonGroup {
        start: 1,
        alpha: vec![1.0, 2.0],
        beta: vec![1.0, 0.0],
        fixed_squares: 0.0,
        weight: 1.0,
    };
    let x = [7.0, 0.0, 0.0];
    let close = |dx: [f64; 3]| g.closest(&x, &dx);
    // Through zero at t = 1/2.
    assert!(close([0.0, -2.0, 0.0]).abs() < 1e-15);
    // Short of zero: the end of the segment (t = 1).
    assert!((close([0.0, -0.5, 0.0]) - 0.5).abs() < 1e-15);
    // z(t) = (1 - 2t, t): nearest at t = 2/5, z = (0.2, 0.4).
    let mid = close([0.0, -2.0, 0.5]);
    assert!((mid - 0.2f64.sqrt()).abs() < 1e-15, "{mid}");
    // Moving away: the start (t = 0); no move: the start.
    assert!((close([0.0, 1.0, 0.0]) - 1.0).abs() < 1e-15);
    assert!((close([0.0; 3]) - 1.0).abs() < 1e-15);
    // The fixed entries count in the norm.
    let fixed = NewtonGroup {
        fixed_squares: 0.09,
        ..g.clone()
    };
    let mid = fixed.closest(&x, &[0.0, -2.0, 0.5]);
    assert!((mid - 0.29f64.sqrt()).abs() < 1e-15, "{mid}");
}

#[test]
fn the_line_search_tames_a_step_that_would_run_away() {
    // One entry, ||z|| = sqrt(1 + (5 + x)^2) with a faint quadratic: from
    // z = 5 the full Newton step is -z (1 + z^2) = -130 (Newton's method on
    // sqrt(1 + z^2) diverges from |z| > 1); backtracking brings it to the
    // minimum near z = 0, where the fixed entry keeps f smooth.
    let p = Mat::from_fn(1, 1, |_, _| 1e-3);
    let groups = [NewtonGroup {
        start: 0,
        alpha: vec![1.0],
        beta: vec![5.0],
        fixed_squares: 1.0,
        weight: 1.0,
    }];
    let (x, iterations) =
        solved(newton(&mut p.clone(), &[0.0], &groups, 1e-12, None, None, None).unwrap())
            .expect("converges with cut steps");
    let (_, grad) = value_and_gradient(&p, &[0.0], &groups, &x);
    assert!(grad.amax() < 1e-11, "{:.2e}", grad.amax());
    // The minimum: z / sqrt(1 + z^2) = -1e-3 x with z = 5 + x, near x = -5.
    assert!((x[0] + 5.0).abs() < 0.01, "{x:?}");
    assert!(iterations > 2, "{iterations}");
}

#[test]
fn zero_is_optimal_up_to_the_checks_margin_of_1e_9() {
    // One entry, alpha = 2, weight 1: w = grad / 2.
    let g = NewtonGroup {
        start: 0,
        alpha: vec![2.0],
        beta: vec![0.0],
        fixed_squares: 0.0,
        weight: 1.0,
    };
    assert!(g.zero_is_optimal(&[2.0]));
    assert!(g.zero_is_optimal(&[-2.0 * (1.0 + 0.5e-9)]));
    assert!(!g.zero_is_optimal(&[2.0 * (1.0 + 2e-9)]));
    assert!(!g.zero_is_optimal(&[-3.0]));
}

#[test]
fn release_moves_a_group_to_the_minimum_of_f_on_its_steepest_ray() {
    // Group 2 at zero with a small weight (its zero is not optimal): the
    // release puts z_g on the ray -t w (t > 0) at the minimum of f along
    // it, the other entries untouched.
    let (p, q, mut groups, _) = random(13, &specs(0.1), 7);
    groups[2].weight = 0.01;
    let quadratic = Quadratic::of(&p, None).unwrap();
    let mut x = vec![0.0; 13];
    groups[2].hold(&mut x);
    let quad = quad_gradient(&quadratic, &q, &x);
    assert!(!groups[2].zero_is_optimal(&quad));
    let w = groups[2].w(&quad);
    let mut moved = x.clone();
    groups[2].release(&quadratic, &quad, &mut moved);
    let z: Vec<f64> = groups[2].z(&moved).collect();
    // z = -t w: parallel and opposite, the same t for every entry.
    let t = -z[0] / w[0];
    assert!(t > 0.0, "{t}");
    for (zk, wk) in z.iter().zip(&w) {
        assert!(
            (zk + t * wk).abs() <= 1e-12 * zk.abs().max(1e-300),
            "{zk} vs {}",
            -t * wk
        );
    }
    assert!(moved
        .iter()
        .zip(&x)
        .enumerate()
        .all(|(i, (a, b))| groups[2].range().contains(&i) || a == b));
    // The minimum of f on the ray: f at t (1 -/+ 1e-3) is no lower, and
    // lower than at zero.
    let f = |s: f64| {
        let y: Vec<f64> = x.iter().zip(&moved).map(|(a, b)| a + s * (b - a)).collect();
        value_and_gradient(&p, &q, &groups, &y).0
    };
    let here = f(1.0);
    assert!(here < f(0.0), "no lower than at zero");
    assert!(
        here <= f(0.999) && here <= f(1.001),
        "{} {} {}",
        f(0.999),
        here,
        f(1.001)
    );
}

#[test]
fn the_stopping_rule_is_relative_to_the_size_of_f() {
    // f scaled by 10 (|f| about 2.4 at the minimum) and by 1e7 (P, q and
    // the weights): the same iterations and the same minimiser, at a loose
    // tolerance and a tight one.
    let (p, q, groups, _) = random(13, &specs(0.05), 2);
    let scaled = |k: f64| {
        let groups: Vec<NewtonGroup> = groups
            .iter()
            .map(|g| NewtonGroup {
                weight: k * g.weight,
                ..g.clone()
            })
            .collect();
        let q: Vec<f64> = q.iter().map(|v| k * v).collect();
        (Mat::from_fn(13, 13, |i, j| k * p[(i, j)]), q, groups)
    };
    let (p_small, q_small, g_small) = scaled(10.0);
    let (p_big, q_big, g_big) = scaled(1e7);
    for tol in [1e-2, 1e-8] {
        let (x, its) = solved(
            newton(
                &mut p_small.clone(),
                &q_small,
                &g_small,
                tol,
                None,
                None,
                None,
            )
            .unwrap(),
        )
        .unwrap();
        let (f, _) = value_and_gradient(&p_small, &q_small, &g_small, &x);
        assert!(f.abs() > 1.0, "not a test of the relative rule: {f}");
        let (x_big, its_big) =
            solved(newton(&mut p_big.clone(), &q_big, &g_big, tol, None, None, None).unwrap())
                .unwrap();
        assert_eq!(its, its_big, "tol {tol}");
        let diff = x
            .iter()
            .zip(&x_big)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(diff < 1e-9, "tol {tol}: {diff:.2e}");
    }
}
