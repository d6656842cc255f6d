//! Unit tests of the cone step (`super`): its pieces on hand-made numbers,
//! the active set and the elimination of the ungrouped parameters against
//! a dense solve, a closed form or the optimality conditions of (27).

use super::*;
use crate::testing::Lcg;
use nalgebra::{DMatrix, DVector};

/// A cone step given by its quadratic: `P = (2/M)(H + mu D)` and `q = g/M`
/// are chosen, `H` and `g` follow (with a Marquardt diagonal `D` that is
/// not the identity).
struct Case {
    gn: GaussNewton,
    diag: Vec<f64>,
    theta: Vec<f64>,
    groups: Vec<ConeGroup>,
    gamma: f64,
    m: f64,
    mu: f64,
    p: DMatrix<f64>,
    q: DVector<f64>,
    pinned: Option<PinnedBasis>,
}

fn group(at: &[usize], phi: f64, varphi: f64) -> ConeGroup {
    ConeGroup {
        entries: at.iter().map(|&i| (i, Some(i))).collect(),
        phi,
        varphi,
    }
}

#[allow(clippy::too_many_arguments)]
fn case(
    p: DMatrix<f64>,
    q: DVector<f64>,
    mu: f64,
    theta: Vec<f64>,
    groups: Vec<ConeGroup>,
    gamma: f64,
    m: f64,
) -> Case {
    let nf = q.len();
    let diag: Vec<f64> = (0..nf).map(|i| 0.5 + 0.25 * i as f64).collect();
    let gram = &p * (m / 2.0) - DMatrix::from_diagonal(&DVector::from_vec(diag.clone())) * mu;
    Case {
        gn: GaussNewton {
            vnls: 1.0,
            gradient: (&q * m).as_slice().to_vec(),
            gram: gram.as_slice().to_vec(),
        },
        diag,
        theta,
        groups,
        gamma,
        m,
        mu,
        p,
        q,
        pinned: None,
    }
}

impl Case {
    fn cone(&self) -> ConeProblem<'_> {
        ConeProblem {
            gn: &self.gn,
            diag: &self.diag,
            theta: &self.theta,
            groups: &self.groups,
            gamma: self.gamma,
            n_residuals: self.m,
            pinned: self.pinned.as_ref(),
        }
    }

    fn solve(&self) -> ConeStep {
        self.cone()
            .solve(self.mu, &mut ConeSolver::new(1e-10))
            .expect("memory")
    }

    /// The gradient of the smooth part at `d`, `q + P d + C d`, by nalgebra
    /// (`C` the pinned curvature, unscaled, when given).
    fn gradient(&self, d: &[f64], c: Option<&DMatrix<f64>>) -> DVector<f64> {
        let d = DVector::from_column_slice(d);
        let mut g = &self.q + &self.p * &d;
        if let Some(c) = c {
            g += c * &d;
        }
        g
    }

    /// The largest violation of the optimality conditions of (27) at the
    /// step `d`, relative to `scale`: zero gradient on the ungrouped
    /// parameters; on an open group `G_g = -lambda_g v_g / ||v||` (`v` the
    /// group after the step, fixed entries included); on a group at zero
    /// (below `1e-7`) `||G_g|| <= lambda_g`.
    fn violation(&self, d: &[f64], c: Option<&DMatrix<f64>>, scale: f64) -> f64 {
        let g = self.gradient(d, c);
        let mut grouped = vec![false; d.len()];
        let mut worst: f64 = 0.0;
        for grp in &self.groups {
            let lambda = self.gamma * grp.phi * grp.varphi;
            let v: Vec<f64> = grp
                .entries
                .iter()
                .map(|&(i, pos)| self.theta[i] + pos.map_or(0.0, |p| d[p]))
                .collect();
            let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
            let free: Vec<(usize, f64)> = grp
                .entries
                .iter()
                .zip(&v)
                .filter_map(|(&(_, pos), &x)| pos.map(|p| (p, x)))
                .collect();
            free.iter().for_each(|&(p, _)| grouped[p] = true);
            if norm < 1e-7 {
                let gn = free.iter().map(|&(p, _)| g[p] * g[p]).sum::<f64>().sqrt();
                worst = worst.max(gn - lambda);
            } else {
                for &(p, x) in &free {
                    worst = worst.max((g[p] + lambda * x / norm).abs());
                }
            }
        }
        for (p, &is) in grouped.iter().enumerate() {
            if !is {
                worst = worst.max(g[p].abs());
            }
        }
        worst / scale
    }
}

/// The step meets the optimality conditions to the solver's accuracy: a
/// gap of 1e-10 in the objective leaves the step within about
/// `sqrt(2e-10 / sigma_min(P))` of the optimum (strong convexity), and its
/// gradient within `||P||` times that; measured up to 3e-6 here.
fn assert_optimal(c: &Case, d: &[f64], curvature: Option<&DMatrix<f64>>, scale: f64) {
    let v = c.violation(d, curvature, scale);
    assert!(v < 2e-5, "{v}: {d:?}");
}

/// A symmetric positive definite matrix with a strong diagonal.
fn spd(n: usize, coupling: f64, rng: &mut Lcg) -> DMatrix<f64> {
    let b = DMatrix::from_fn(n, n, |_, _| rng.next_f64());
    DMatrix::from_diagonal(&DVector::from_fn(n, |i, _| 1.0 + 0.3 * i as f64))
        + &b * b.transpose() * coupling
}

// ----------------------------------------------------------- the pieces

#[test]
fn penalty_is_gamma_times_the_weighted_group_norms() {
    let groups = vec![group(&[0, 1], 2.0, 0.5), group(&[2], 3.0, 4.0)];
    let c = case(
        DMatrix::identity(3, 3),
        DVector::zeros(3),
        0.0,
        vec![3.0, 4.0, -2.0],
        groups,
        0.25,
        1.0,
    );
    // 0.25 (2 * 0.5 * 5 + 3 * 4 * 2) = 0.25 * 29
    assert_eq!(c.cone().penalty(None), 7.25);
    // After d: (3, 4) + (-3, 8) = (0, 12) and -2 + 5 = 3:
    // 0.25 (1 * 12 + 12 * 3) = 12
    assert_eq!(c.cone().penalty(Some(&[-3.0, 8.0, 5.0])), 12.0);
    // gamma scales the whole term.
    let zero = Case { gamma: 0.0, ..c };
    assert_eq!(zero.cone().penalty(None), 0.0);
}

#[test]
fn model_gradient_is_g_over_m_plus_the_damped_quadratic_times_d() {
    // M = 4, H = [[2, 1], [1, 3]], g = (3, -6), D = (5, 7), mu = 0.5.
    let gn = GaussNewton {
        vnls: 1.0,
        gradient: vec![3.0, -6.0],
        gram: vec![2.0, 1.0, 1.0, 3.0],
    };
    let diag = [5.0, 7.0];
    let theta = [0.0, 0.0];
    let cone = ConeProblem {
        gn: &gn,
        diag: &diag,
        theta: &theta,
        groups: &[],
        gamma: 1.0,
        n_residuals: 4.0,
        pinned: None,
    };
    // At d = 0: g/M.
    assert_eq!(cone.model_gradient(0.5, &[0.0, 0.0]), vec![0.75, -1.5]);
    // d = (2, 0): g/M + (2/4) * 2 * (H e1 + mu D_1 e1) = (0.75 + 2 + 2.5, -1.5 + 1).
    assert_eq!(cone.model_gradient(0.5, &[2.0, 0.0]), vec![5.25, -0.5]);
    // d = (1, -2): (2/4)(H d + mu D d) = 0.5 ((0, -5) + (2.5, -7)).
    assert_eq!(cone.model_gradient(0.5, &[1.0, -2.0]), vec![2.0, -7.5]);
    // A pinned direction adds weight u (u . d): u = (3, 4)/5, weight 2.
    let pinned = Pinned {
        dirs: Mat::from_fn(2, 1, |i, _| [3.0, 4.0][i]),
        exempt: Mat::zeros(2, 0),
        weight: 2.0,
    };
    let basis = pinned.basis(&[1.0, 1.0]).unwrap();
    let kept = ConeProblem {
        pinned: Some(&basis),
        ..cone
    };
    // u . d = (3 - 8)/5 = -1: adds -2 (0.6, 0.8).
    let got = kept.model_gradient(0.5, &[1.0, -2.0]);
    for (g, want) in got.iter().zip([2.0 - 1.2, -7.5 - 1.6]) {
        assert!((g - want).abs() <= 1e-14 * want.abs(), "{got:?}");
    }
}

#[test]
fn bound_is_gamma_phi_varphi_and_the_scale_gives_a_unit_diagonal() {
    let c = case(
        DMatrix::from_row_slice(2, 2, &[4.0, 1.0, 1.0, 9.0]),
        DVector::zeros(2),
        0.5,
        vec![1.0, 1.0],
        vec![group(&[0, 1], 3.0, 0.5)],
        0.2,
        8.0,
    );
    assert_eq!(c.cone().bound(&c.groups[0]), 0.2 * 3.0 * 0.5);
    // S = diag(P)^-1/2: P_ii s_i^2 = 1.
    let s = c.cone().jacobi_scale(c.mu);
    for (i, si) in s.iter().enumerate() {
        assert!((c.p[(i, i)] * si * si - 1.0).abs() < 1e-14);
    }
    assert!((s[0] - 0.5).abs() < 1e-15 && (s[1] - 1.0 / 3.0).abs() < 1e-15);
}

// ------------------------------------------------- the single-group cases

/// One group of two free entries, `P = [[2, 0.5], [0.5, 1]]`, `M = 2`,
/// `mu = 0` (so `H = P` and `q = g/2` exactly), `lambda = 0.3`. Its
/// prediction uses `||q||` (`<= 0.27` to predict zero), its confirmation
/// and its answer `||q - P theta||` (`<= 0.3`: zero is optimal).
fn single(q: [f64; 2], theta: [f64; 2]) -> Case {
    case(
        DMatrix::from_row_slice(2, 2, &[2.0, 0.5, 0.5, 1.0]),
        DVector::from_column_slice(&q),
        0.0,
        theta.to_vec(),
        vec![group(&[0, 1], 1.5, 0.5)],
        0.4,
        2.0,
    )
}

fn gradient_at_zero(c: &Case) -> f64 {
    let minus: Vec<f64> = c.theta.iter().map(|t| -t).collect();
    c.gradient(&minus, None).norm()
}

#[test]
fn a_group_predicted_and_confirmed_at_zero_needs_no_solve() {
    let c = single([0.1, 0.1], [0.01, -0.02]);
    assert!(c.q.norm() <= 0.27 && gradient_at_zero(&c) <= 0.3);
    let s = c.solve();
    assert_eq!((s.solves, s.zeroed, s.iterations), (0, 1, 0));
    assert_eq!(s.status, "Solved (every group at zero)");
    assert_eq!(s.step.unwrap(), vec![-0.01, 0.02]);
}

#[test]
fn a_prediction_the_zero_point_refutes_is_solved_once() {
    let c = single([0.1, 0.1], [1.0, 0.5]);
    assert!(c.q.norm() <= 0.27 && gradient_at_zero(&c) > 0.3);
    let s = c.solve();
    assert_eq!((s.solves, s.zeroed), (1, 0));
    assert!(s.iterations > 0);
    let d = s.step.unwrap();
    assert_optimal(&c, &d, None, 0.3);
    assert!(c.groups[0].norm_after(&c.theta, &d) > 0.1);
}

#[test]
fn a_group_left_at_a_negligible_size_is_snapped_to_zero() {
    // Not predicted (||q|| > 0.27), but its gradient at zero is inside
    // the bound: the solver brings it to the cone's tip, SNAP to zero.
    let c = single([0.2, 0.2], [0.01, -0.02]);
    assert!(c.q.norm() > 0.27 && c.q.norm() <= 0.3 && gradient_at_zero(&c) <= 0.3);
    let s = c.solve();
    assert_eq!((s.solves, s.zeroed), (1, 1));
    assert!(s.iterations > 0);
    assert_eq!(s.step.unwrap(), vec![-0.01, 0.02]);
}

#[test]
fn a_resting_group_on_its_bound_stays_at_zero() {
    // theta_g = 0 and a gradient at the check's own tolerance,
    // bound (1 + 1e-9) with bound = 1 exactly: not put back.
    let edge: f64 = 1.0 + 1e-9;
    assert_eq!((edge * edge).sqrt(), edge);
    let c = case(
        DMatrix::identity(1, 1),
        DVector::from_element(1, edge),
        0.0,
        vec![0.0],
        vec![group(&[0], 1.0, 1.0)],
        1.0,
        2.0,
    );
    assert_eq!(c.cone().model_gradient(0.0, &[0.0]), vec![edge]);
    let s = c.solve();
    assert_eq!((s.solves, s.zeroed), (0, 1));
    assert_eq!(s.step.unwrap(), vec![0.0]);
}

#[test]
fn a_group_with_a_fixed_nonzero_entry_is_never_snapped() {
    // Entry 1 is fixed at 1e-12: the group cannot vanish; a large bound
    // pulls the free entry to about that size, below SNAP.
    let c = case(
        DMatrix::from_element(1, 1, 2.0),
        DVector::from_element(1, 0.3),
        0.0,
        vec![0.5, 1e-12],
        vec![ConeGroup {
            entries: vec![(0, Some(0)), (1, None)],
            phi: 1.0,
            varphi: 1.0,
        }],
        10.0,
        2.0,
    );
    let s = c.solve();
    let d = s.step.clone().unwrap();
    let size = c.groups[0].norm_after(&c.theta, &d);
    assert!(size <= SNAP, "{size}: not a test of SNAP");
    assert_eq!((s.solves, s.zeroed), (1, 0), "{s:?}");
    assert_ne!(d[0], -0.5);
}

// ----------------------------------------------------- several groups

/// Groups (0, 1), (2, 3, 4), (5) and two ungrouped parameters (6, 7).
fn several(seed: u64, gamma: f64, theta_scale: f64) -> Case {
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
    for i in 0..6 {
        assert!((d[i] + c.theta[i]).abs() <= 1e-15 * c.theta[i].abs());
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
        .solve_with(c.mu, &zero, &scale, None, &mut solver)
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
    let d = s.step.unwrap();
    assert_optimal(&c, &d, None, 1.0);
    assert!(c.groups[0].norm_after(&c.theta, &d) > 0.01);
    let first = cone_gradient_norm_after_first_round(&c);
    assert!(first > 0.05 * (1.0 + 1e-9) && first < 1.05, "{first}");
    assert_eq!(s.zeroed, 0);
    // Iterations are the two rounds' together: first with the group at
    // zero, then with it back.
    let cone = c.cone();
    let scale = cone.jacobi_scale(c.mu);
    let rounds: u32 = [[true, false, false], [false, false, false]]
        .iter()
        .map(|zero| {
            let r = cone
                .solve_with(c.mu, zero, &scale, None, &mut ConeSolver::new(1e-10))
                .unwrap();
            assert!(r.solved && r.iterations > 0);
            r.iterations
        })
        .sum();
    assert_eq!(s.iterations, rounds);
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
    c.pinned = pinned.basis(&[1.0; 8]);
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
