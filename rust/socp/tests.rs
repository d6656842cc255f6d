//! Unit tests of the cone step (`super`): its pieces on hand-made numbers,
//! the active set and the elimination of the ungrouped parameters against
//! a dense solve, a closed form or the optimality conditions of (27).

use super::*;
use crate::testing::Lcg;
use faer::Mat;
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
            factors: None,
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
            newton: true,
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
        factors: None,
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
        newton: true,
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
    let basis = pinned.basis(&[1.0, 1.0]).unwrap().unwrap();
    let kept = ConeProblem {
        pinned: Some(&basis),
        newton: true,
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
    // the bound: Clarabel brings it to the cone's tip, SNAP to zero.
    let c = single([0.2, 0.2], [0.01, -0.02]);
    assert!(c.q.norm() > 0.27 && c.q.norm() <= 0.3 && gradient_at_zero(&c) <= 0.3);
    let cone = ConeProblem {
        newton: false,
        ..c.cone()
    };
    let s = cone.solve(c.mu, &mut ConeSolver::new(1e-10)).unwrap();
    assert_eq!((s.solves, s.zeroed), (1, 1));
    assert!(s.iterations > 0 && s.status != "Solved (Newton)");
    assert_eq!(s.step.unwrap(), vec![-0.01, 0.02]);
}

#[test]
fn a_group_newtons_method_finds_on_its_way_to_zero_is_held_there() {
    // The same program: Newton's method sees the group heading for its
    // kink, holds it at zero and finds zero optimal; the check confirms
    // it and the group is set exactly to zero.
    let c = single([0.2, 0.2], [0.01, -0.02]);
    let s = c.solve();
    assert_eq!((s.solves, s.zeroed), (1, 1));
    assert!(s.iterations > 0, "Newton's iterations are counted");
    assert_eq!(s.status, "Solved (Newton)");
    assert_eq!(s.step.unwrap(), vec![-0.01, 0.02]);
}

#[test]
fn newtons_iterations_before_it_gives_up_are_counted_with_clarabels() {
    // P = [[1, 2], [2, 1]] (M = 2, mu = 0: H = P, a unit diagonal, so the
    // scale is 1) has the eigenvalue -1 along (1, -1), and the group's
    // curvature (gamma 1e-3) is far too small to lift it: Newton's method
    // gives up at its first factorisation and Clarabel takes the program.
    // Whatever Clarabel makes of it, the round reports Newton's one
    // iteration on top of Clarabel's own.
    let p = DMatrix::from_row_slice(2, 2, &[1.0, 2.0, 2.0, 1.0]);
    let q = DVector::from_vec(vec![0.5, -0.25]);
    let c = case(
        p,
        q,
        0.0,
        vec![1.0, 0.5],
        vec![group(&[0, 1], 1.0, 1.0)],
        1e-3,
        2.0,
    );
    assert_eq!(c.cone().jacobi_scale(0.0), vec![1.0, 1.0]);
    let alone = ConeProblem {
        newton: false,
        ..c.cone()
    };
    let clarabel = alone.solve(c.mu, &mut ConeSolver::new(1e-10)).unwrap();
    let both = c.solve();
    assert!(clarabel.iterations > 0, "{clarabel:?}");
    assert_eq!(both.status, clarabel.status);
    assert_eq!(both.solves, 1, "{both:?}");
    assert_eq!(
        both.iterations,
        clarabel.iterations + 1,
        "{both:?} against {clarabel:?}"
    );
}

#[test]
fn newtons_iterations_up_to_a_kink_it_cannot_hold_are_counted() {
    // The program of the group held at zero above, with a third, fixed
    // entry of 1e-8 in the group: its free entries head for zero as
    // before, but the group cannot be held there (its fixed entry is off
    // zero), so Newton's method stops at the kink and Clarabel solves the
    // program. The round reports Newton's iterations on top of Clarabel's.
    let mut c = single([0.2, 0.2], [0.01, -0.02]);
    c.theta.push(1e-8);
    c.groups[0].entries.push((2, None));
    let alone = ConeProblem {
        newton: false,
        ..c.cone()
    };
    let clarabel = alone.solve(c.mu, &mut ConeSolver::new(1e-10)).unwrap();
    let both = c.solve();
    assert_eq!(both.status, clarabel.status);
    assert_eq!((both.solves, clarabel.solves), (1, 1));
    assert!(
        both.iterations > clarabel.iterations,
        "{both:?} against {clarabel:?}"
    );
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

#[path = "tests_several.rs"]
mod several;

#[path = "tests_warm.rs"]
mod warm;
