//! Unit tests of the cone step with several groups (`super`'s cases):
//! the active set, the elimination of the ungrouped parameters, the pinned
//! curvature and the failed steps.

use super::*;

// ----------------------------------------------------- several groups

/// Groups (0, 1), (2, 3, 4), (5) and two ungrouped parameters (6, 7).
pub(super) fn several(seed: u64, gamma: f64, theta_scale: f64) -> Case {
    let mut rng = Lcg(seed);
    let p = spd(8, 0.3, &mut rng);
    let q = DVector::from_fn(8, |_, _| rng.next_f64());
    let theta: Vec<f64> = (0..8).map(|_| theta_scale * rng.next_f64()).collect();
    let groups = vec![
        group(&[0, 1], 1.0, 1.0),
        group(&[2, 3, 4], 4.0, 0.5),
        group(&[5], 0.5, 3.0),
    ];
    case(p, q, 0.25, theta, groups, gamma, 10.0)
}

#[test]
fn every_group_at_zero_is_the_dense_solve_of_the_ungrouped_parameters() {
    // A large gamma: every group ends at zero, no cone program at all,
    // and the ungrouped parameters solve P_UU d_U = -(q_U + P_UG d_G).
    let c = several(3, 50.0, 1.0);
    let s = c.solve();
    assert_eq!((s.solves, s.zeroed, s.iterations), (0, 3, 0));
    let d = s.step.unwrap();
    for (x, t) in d.iter().zip(&c.theta).take(6) {
        assert!((x + t).abs() <= 1e-15 * t.abs());
    }
    let d_g = DVector::from_column_slice(&d[..6]);
    let rhs = -(c.q.rows(6, 2) + c.p.view((6, 0), (2, 6)) * d_g);
    let d_u =
        c.p.view((6, 6), (2, 2))
            .into_owned()
            .lu()
            .solve(&rhs)
            .unwrap();
    for k in 0..2 {
        assert!((d[6 + k] - d_u[k]).abs() < 1e-12 * (1.0 + d_u[k].abs()));
    }
    assert!(c.violation(&d, None, 1.0) < 1e-14);
}

#[test]
fn steps_with_open_groups_meet_the_optimality_conditions() {
    let mut zeroed = 0;
    for seed in 0..4 {
        for gamma in [0.02, 0.2, 1.0] {
            let c = several(seed, gamma, 1.0);
            let s = c.solve();
            let d = s.step.unwrap();
            assert_optimal(&c, &d, None, 1.0);
            // zeroed counts the groups at zero (to the rounding of the
            // scaling) and no other.
            let at_zero = c
                .groups
                .iter()
                .filter(|g| g.norm_after(&c.theta, &d) < 1e-14)
                .count();
            let open = c.groups.iter().map(|g| g.norm_after(&c.theta, &d));
            assert!(open.filter(|&n| n >= 1e-14).all(|n| n > 1e-6));
            assert_eq!(s.zeroed, at_zero);
            zeroed += at_zero;
        }
    }
    assert!(zeroed > 0 && zeroed < 36, "{zeroed} of 36 groups at zero");
}

/// `||G_g||` of group 0 at the step solved with it at zero (and the
/// others open), by nalgebra.
fn cone_gradient_norm_after_first_round(c: &Case) -> f64 {
    let cone = c.cone();
    let scale = cone.jacobi_scale(c.mu);
    let zero = [true, false, false];
    let mut solver = ConeSolver::new(1e-10);
    let r = cone
        .solve_with(c.mu, &zero, &scale, None, &mut solver, Method::Newton(None))
        .unwrap();
    let g = c.gradient(&r.step.unwrap(), None);
    g[0].hypot(g[1])
}

#[test]
fn a_resting_group_the_solution_needs_is_put_back() {
    // Group (0, 1) at zero, its gradient over its bound 0.05 (by less
    // than 1: the check scales the bound, it does not shift it).
    let mut c = several(5, 0.05, 1.0);
    c.theta[0] = 0.0;
    c.theta[1] = 0.0;
    c.q[0] = 0.4;
    c.gn.gradient[0] = 0.4 * c.m;
    let s = c.solve();
    assert_eq!(s.solves, 2, "{s:?}");
    let d = s.step.clone().unwrap();
    assert_optimal(&c, &d, None, 1.0);
    assert!(c.groups[0].norm_after(&c.theta, &d) > 0.01);
    let first = cone_gradient_norm_after_first_round(&c);
    assert!(first > 0.05 * (1.0 + 1e-9) && first < 1.05, "{first}");
    assert_eq!(s.zeroed, 0);
    // Iterations are the rounds' together: first with the group at zero
    // (Newton's method), then with it back, Newton's method again from the
    // first round's step, where it lets the group go from zero along its
    // steepest descent. From zero it does the same, in more iterations.
    let cone = c.cone();
    let scale = cone.jacobi_scale(c.mu);
    let solve = |zero: &[bool; 3], method| {
        let mut solver = ConeSolver::new(1e-10);
        cone.solve_with(c.mu, zero, &scale, None, &mut solver, method)
            .unwrap()
    };
    let first = solve(&[true, false, false], Method::Newton(None));
    assert!(
        first.solved && first.status == "Solved (Newton)",
        "{}",
        first.status
    );
    let from: Vec<f64> = first
        .step
        .as_ref()
        .unwrap()
        .iter()
        .zip(&scale)
        .map(|(d, s)| d / s)
        .collect();
    let warm = solve(&[false, false, false], Method::Newton(Some(from)));
    assert!(
        warm.solved && warm.status == "Solved (Newton)",
        "{}",
        warm.status
    );
    assert_eq!(s.status, "Solved (Newton)");
    assert_eq!(s.iterations, first.iterations + warm.iterations);
    assert_eq!(s.step.as_ref(), warm.step.as_ref());
    let cold = solve(&[false, false, false], Method::Newton(None));
    assert!(
        cold.solved && cold.status == "Solved (Newton)",
        "{}",
        cold.status
    );
    assert!(
        cold.iterations > warm.iterations,
        "{} <= {}",
        cold.iterations,
        warm.iterations
    );
    assert_optimal(&c, cold.step.as_ref().unwrap(), None, 1.0);
    let clarabel = solve(&[false, false, false], Method::Clarabel);
    assert!(
        clarabel.solved
            && clarabel.status.starts_with("Solved")
            && clarabel.status != "Solved (Newton)"
    );
    let gap = d
        .iter()
        .zip(clarabel.step.as_ref().unwrap())
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(gap < 1e-5, "{gap:.2e}");
}

#[test]
fn open_groups_and_ungrouped_parameters_are_group_soft_thresholding() {
    // P_UU = I, P_GU = W, P_GG = diag(a_g) + W W^T: the Schur complement
    // onto the groups is diag(a_g), so each group is soft-thresholded:
    // theta_g + d_g = max(0, 1 - lambda_g / (a_g ||c||)) c with
    // c = theta_g - (q_G - W q_U)_g / a_g, and d_U = -(q_U + W^T d_G).
    let a = [1.5, 0.8, 2.0];
    let at: [&[usize]; 3] = [&[0, 1], &[2, 3, 4], &[5]];
    let (phi, varphi, gamma) = ([1.0, 4.0, 0.5], [1.0, 0.5, 3.0], 0.3);
    let mut removed = 0;
    for seed in 0..4 {
        let mut rng = Lcg(seed + 11);
        let w = DMatrix::from_fn(6, 2, |_, _| 0.7 * rng.next_f64());
        let mut p = DMatrix::identity(8, 8);
        let mut a_of = DVector::zeros(6);
        for (g, at) in at.iter().enumerate() {
            at.iter().for_each(|&i| a_of[i] = a[g]);
        }
        let p_gg = DMatrix::from_diagonal(&a_of) + &w * w.transpose();
        p.view_mut((0, 0), (6, 6)).copy_from(&p_gg);
        p.view_mut((0, 6), (6, 2)).copy_from(&w);
        p.view_mut((6, 0), (2, 6)).copy_from(&w.transpose());
        let q = DVector::from_fn(8, |_, _| rng.next_f64());
        let theta: Vec<f64> = (0..8).map(|_| rng.next_f64()).collect();
        let groups = (0..3).map(|g| group(at[g], phi[g], varphi[g])).collect();
        let c = case(p, q.clone(), 0.5, theta.clone(), groups, gamma, 10.0);
        let d = c.solve().step.unwrap();
        let q_g = q.rows(0, 6) - &w * q.rows(6, 2);
        let mut want = vec![0.0; 8];
        for (g, at) in at.iter().enumerate() {
            let cg: Vec<f64> = at.iter().map(|&i| theta[i] - q_g[i] / a[g]).collect();
            let norm = cg.iter().map(|x| x * x).sum::<f64>().sqrt();
            let keep = (1.0 - gamma * phi[g] * varphi[g] / (a[g] * norm)).max(0.0);
            removed += usize::from(keep == 0.0);
            for (&i, x) in at.iter().zip(cg) {
                want[i] = keep * x - theta[i];
            }
        }
        let d_u = -(q.rows(6, 2) + w.transpose() * DVector::from_column_slice(&want[..6]));
        want[6..].copy_from_slice(d_u.as_slice());
        for (x, y) in d.iter().zip(&want) {
            assert!((x - y).abs() < 1e-7 * (1.0 + y.abs()), "{d:?} vs {want:?}");
        }
    }
    assert!(
        removed > 0 && removed < 12,
        "{removed} of 12 groups removed"
    );
}

#[test]
fn a_pinned_direction_adds_its_curvature_to_the_step() {
    // One kept-off direction u (unit at scale0 = 1), weight 3: the step
    // solves (27) with P + 3 u u^T.
    let mut c = several(7, 0.1, 1.0);
    let dir: Vec<f64> = (0..8).map(|i| (i as f64 * 0.9).sin()).collect();
    let norm = dir.iter().map(|x| x * x).sum::<f64>().sqrt();
    let u = DVector::from_iterator(8, dir.iter().map(|x| x / norm));
    let curvature = &u * u.transpose() * 3.0;
    let pinned = Pinned {
        dirs: Mat::from_fn(8, 1, |i, _| dir[i]),
        exempt: Mat::zeros(8, 0),
        weight: 3.0,
    };
    c.pinned = pinned.basis(&[1.0; 8]).unwrap();
    let d = c.solve().step.unwrap();
    assert_optimal(&c, &d, Some(&curvature), 1.0);
    // Without the curvature the conditions fail: the pin moved the step.
    assert!(c.violation(&d, None, 1.0) > 1e-3);
}

// ------------------------------------------------------------ failures

#[test]
fn a_zero_diagonal_or_an_indefinite_ungrouped_block_is_a_failed_step() {
    // No curvature at all on parameter 1 and no damping: no Jacobi scale.
    let mut p = DMatrix::identity(3, 3);
    p[(1, 1)] = 0.0;
    let flat = case(
        p,
        DVector::from_element(3, 0.1),
        0.0,
        vec![1.0; 3],
        vec![group(&[0], 1.0, 1.0)],
        0.1,
        2.0,
    );
    let s = flat.solve();
    assert!(s.step.is_none());
    assert_eq!(s.status, "the quadratic has a zero or non-finite diagonal");
    assert_eq!((s.solves, s.iterations, s.zeroed), (0, 0, 0));
    // The ungrouped parameters 1 and 2 with P_UU = [[1, 2], [2, 1]].
    let mut p = DMatrix::identity(3, 3);
    p[(1, 2)] = 2.0;
    p[(2, 1)] = 2.0;
    let saddle = case(
        p,
        DVector::from_element(3, 0.1),
        0.0,
        vec![1.0; 3],
        vec![group(&[0], 1.0, 1.0)],
        0.1,
        2.0,
    );
    let s = saddle.solve();
    assert!(s.step.is_none());
    assert_eq!(s.status, "the quadratic is not positive definite");
}

#[test]
fn a_group_with_no_free_entry_is_left_out_of_the_program() {
    // Group (8, 9) is fixed entirely (theta has two more entries): it adds
    // a constant to the penalty and nothing to the step or the counts.
    let c = several(2, 0.2, 1.0);
    let mut fixed = Case {
        theta: c.theta.iter().copied().chain([0.5, -0.5]).collect(),
        ..several(2, 0.2, 1.0)
    };
    fixed.groups.push(ConeGroup {
        entries: vec![(8, None), (9, None)],
        phi: 1.0,
        varphi: 2.0,
    });
    let (s, t) = (c.solve(), fixed.solve());
    assert_eq!(s.step, t.step);
    assert_eq!((s.zeroed, s.solves), (t.zeroed, t.solves));
    let extra = 0.2 * 2.0 * 0.5f64.hypot(0.5);
    assert!((fixed.cone().penalty(None) - c.cone().penalty(None) - extra).abs() < 1e-14);
}
