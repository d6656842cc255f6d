//! Unit tests of Algorithm 1 (`super`): the problems they run on, the
//! weights (21)-(23) by hand, the settled rule, the single cone step's
//! objective and the path; the loop's rules in `tests_loop.rs`.

use super::*;
use crate::base::layout::Matrix;
use crate::error::Error;
use crate::eval::objective::GaussNewton;
use crate::fit::Silent;
use crate::testing::Lcg;
use crate::{frequency_response, FrfData, ModelAt, Problem};
use num_complex::Complex64 as C64;

// ------------------------------------------------------------ problems

/// `r = A theta - b`: a least-squares objective whose Gauss-Newton model is
/// exact, over the shape n = 2, r = 1, l = 1, Nb = 2 (27 parameters).
struct Linear {
    shape: Shape,
    /// `m x p`, column-major.
    a: Vec<f64>,
    b: Vec<f64>,
}

const ROWS: usize = 60;

impl Linear {
    /// Data from a theta whose groups A(1) and C(1) are the only ones in
    /// use, plus `noise` times uniform numbers.
    fn new(noise: f64) -> (Self, Vec<f64>) {
        let shape = Shape::new(2, 1, 1, 2).unwrap();
        let p = shape.len();
        let mut rng = Lcg(11);
        let a: Vec<f64> = (0..ROWS * p).map(|_| rng.next_f64()).collect();
        let mut truth = vec![0.0; p];
        for (x, i) in [
            (Matrix::A, 0),
            (Matrix::B, 0),
            (Matrix::C, 0),
            (Matrix::D, 0),
            (Matrix::A, 1),
            (Matrix::C, 1),
        ] {
            for k in shape.block(x, i) {
                truth[k] = 1.0 + rng.next_f64();
            }
        }
        let mut b = vec![0.0; ROWS];
        for (j, t) in truth.iter().enumerate() {
            for (i, bi) in b.iter_mut().enumerate() {
                *bi += a[i + j * ROWS] * t;
            }
        }
        b.iter_mut().for_each(|v| *v += noise * rng.next_f64());
        (Linear { shape, a, b }, truth)
    }

    fn residual(&self, theta: &[f64]) -> Vec<f64> {
        let mut r: Vec<f64> = self.b.iter().map(|v| -v).collect();
        for (j, t) in theta.iter().enumerate() {
            for (i, ri) in r.iter_mut().enumerate() {
                *ri += self.a[i + j * ROWS] * t;
            }
        }
        r
    }
}

impl Objective for Linear {
    fn shape(&self) -> &Shape {
        &self.shape
    }
    fn n_residuals(&self) -> usize {
        ROWS
    }
    fn cost(&self, theta: &[f64]) -> Result<f64> {
        Ok(self.residual(theta).iter().map(|v| v * v).sum())
    }
    fn gauss_newton(&self, theta: &[f64], free: &FreeSet) -> Result<GaussNewton> {
        let r = self.residual(theta);
        let cols: Vec<&[f64]> = free
            .indices()
            .iter()
            .map(|&j| &self.a[j * ROWS..(j + 1) * ROWS])
            .collect();
        let dot = |x: &[f64], y: &[f64]| x.iter().zip(y).map(|(a, b)| a * b).sum::<f64>();
        let nf = cols.len();
        let mut gram = vec![0.0; nf * nf];
        for i in 0..nf {
            for j in 0..nf {
                gram[i + j * nf] = dot(cols[i], cols[j]);
            }
        }
        Ok(GaussNewton {
            vnls: dot(&r, &r),
            gradient: cols.iter().map(|c| 2.0 * dot(c, &r)).collect(),
            gram,
            factors: None,
        })
    }
    fn response(&self, theta: &[f64]) -> Result<Vec<f64>> {
        Ok(self.residual(theta))
    }
}

/// A nonlinear problem: FRF data of a discrete-time model (n = 2, r = l = 1,
/// basis (p, p^2) at five points), plus a little noise.
fn frf_problem() -> (Problem, Vec<f64>) {
    let shape = Shape::new(2, 1, 1, 2).unwrap();
    let mut theta = vec![0.0; shape.len()];
    for (x, i, v) in [
        (Matrix::A, 0, &[0.6, -0.3, 0.3, 0.6][..]),
        (Matrix::A, 1, &[0.1, 0.0, 0.0, -0.1]),
        (Matrix::B, 0, &[1.0, 0.5]),
        (Matrix::C, 0, &[1.0, -0.4]),
        (Matrix::C, 1, &[0.2, 0.3]),
        (Matrix::D, 0, &[0.1]),
    ] {
        theta[shape.block(x, i)].copy_from_slice(v);
    }
    let points = [-1.0, -0.5, 0.0, 0.5, 1.0];
    let psi: Vec<f64> = points.iter().flat_map(|&p| [p, p * p]).collect();
    let z: Vec<C64> = (0..20)
        .map(|k| C64::from_polar(1.0, 0.05 + 3.0 * k as f64 / 19.0))
        .collect();
    let mut g = frequency_response(&ModelAt::new(shape, &theta, &psi, points.len()), &z).unwrap();
    let mut rng = Lcg(5);
    g.iter_mut()
        .for_each(|v| *v += 0.01 * C64::new(rng.next_f64(), rng.next_f64()));
    let sigma = vec![0.01; g.len()];
    let data = FrfData::new(points.len(), 1, 1, z, g, &sigma).unwrap();
    (Problem::new(shape, data, &psi).unwrap(), theta)
}

fn perturbed(theta: &[f64], size: f64, seed: u64) -> Vec<f64> {
    let mut rng = Lcg(seed);
    theta.iter().map(|t| t + size * rng.next_f64()).collect()
}

/// `theta` moved by `size` on its non-zero entries only: the same groups in use.
fn moved_in_pattern(theta: &[f64], size: f64, seed: u64) -> Vec<f64> {
    let mut rng = Lcg(seed);
    theta
        .iter()
        .map(|&t| {
            if t == 0.0 {
                0.0
            } else {
                t + size * rng.next_f64()
            }
        })
        .collect()
}

fn fit(p: &dyn Objective, theta0: &[f64], sup: &[f64], s: &L21Settings) -> Fit {
    let free = FreeSet::all(theta0.len());
    fit_l21(p, theta0, &free, sup, s, None, &mut Silent).unwrap()
}

fn phis(p: &dyn Objective, theta: &[f64], sup: &[f64], s: &L21Settings) -> Vec<f64> {
    let free = FreeSet::all(theta.len());
    cone_groups(p.shape(), &free, sup, theta, s)
        .unwrap()
        .iter()
        .map(|g| g.phi)
        .collect()
}

fn magnitudes(p: &dyn Objective, theta: &[f64], sup: &[f64], s: &L21Settings) -> Vec<f64> {
    let free = FreeSet::all(theta.len());
    cone_groups(p.shape(), &free, sup, theta, s)
        .unwrap()
        .iter()
        .map(|g| g.magnitude(theta))
        .collect()
}

fn refused<T: std::fmt::Debug>(r: Result<T>) -> (&'static str, String) {
    match r {
        Err(Error::InvalidArgument { name, message }) => (name, message),
        other => panic!("expected InvalidArgument, got {other:?}"),
    }
}

/// The l2,1 fit's data and a start with the true groups in use (A(1),
/// C(1)), moved by `size` inside that pattern.
fn sparse_start(gamma: f64, size: f64, noise: f64) -> (Linear, Vec<f64>, L21Settings) {
    let (p, truth) = Linear::new(noise);
    let s = L21Settings {
        gamma,
        weighting: Weighting::Scaled,
        ..L21Settings::default()
    };
    (p, moved_in_pattern(&truth, size, 9), s)
}

const SUP: [f64; 2] = [2.0, 0.5];

// ------------------------------------------------------------ weights

#[test]
fn weights_follow_each_rule_by_hand() {
    // n = r = l = 1, Nb = 2: every block is one entry; theta by block.
    let shape = Shape::new(1, 1, 1, 2).unwrap();
    let mut theta = vec![0.0; shape.len()];
    let value = |x: Matrix, i: usize| match (x, i) {
        (Matrix::A, 0) => 4.0,
        (Matrix::A, 1) => -0.5,
        (Matrix::A, 2) => 2.0,
        (Matrix::B, 0) => 0.0, // B's groups fall back to (22): X(0) = 0
        (Matrix::B, 1) => 3.0,
        (Matrix::C, 0) => -2.0, // fixed below: C's groups fall back too
        (Matrix::C, 1) => 1.0,
        (Matrix::D, 0) => 0.5,
        (Matrix::D, 2) => -0.25,
        _ => 0.0,
    };
    for g in [Matrix::A, Matrix::B, Matrix::C, Matrix::D] {
        for i in 0..3 {
            theta[shape.block(g, i).start] = value(g, i);
        }
    }
    let mut mask = vec![true; shape.len()];
    mask[shape.block(Matrix::C, 0).start] = false;
    let free = FreeSet::from_mask(&mask);
    let sup = [2.0, 0.5];
    let eps = 0.01;
    for weighting in [Weighting::Relative, Weighting::Scaled, Weighting::Plain] {
        let s = L21Settings {
            eps,
            weighting,
            ..L21Settings::default()
        };
        let groups = cone_groups(&shape, &free, &sup, &theta, &s).unwrap();
        assert_eq!(groups.len(), shape.groups().len());
        for (g, got) in shape.groups().iter().zip(&groups) {
            let norm_i = value(g.matrix, g.basis).abs();
            let norm_0 = value(g.matrix, 0).abs();
            let psi = sup[g.basis - 1];
            let relative =
                weighting == Weighting::Relative && matches!(g.matrix, Matrix::A | Matrix::D);
            let (phi, varphi) = if relative {
                (1.0 / (norm_i * psi / norm_0 + eps), psi / norm_0)
            } else if weighting == Weighting::Plain {
                (1.0 / (norm_i + eps), 1.0)
            } else {
                (1.0 / (norm_i * psi + eps), psi)
            };
            let close = |a: f64, b: f64| (a - b).abs() <= 1e-14 * b.abs();
            assert!(
                close(got.phi, phi) && close(got.varphi, varphi),
                "{weighting:?} {:?}({}): ({}, {}) vs ({phi}, {varphi})",
                g.matrix,
                g.basis,
                got.phi,
                got.varphi
            );
            assert_eq!(
                got.entries,
                vec![(g.range.start, free.position(g.range.start))]
            );
        }
    }
}

#[test]
fn sup_norms_are_checked_and_named() {
    let (p, truth) = Linear::new(0.0);
    let free = FreeSet::all(truth.len());
    let s = L21Settings::default();
    for bad in [vec![1.0], vec![1.0, 1.0, 1.0]] {
        let (name, message) = refused(cone_groups(p.shape(), &free, &bad, &truth, &s));
        assert_eq!(name, "sup_norms");
        assert_eq!(
            message,
            format!(
                "expected 2 values (one per basis function), got {}",
                bad.len()
            )
        );
    }
    for bad in [-1.0, f64::INFINITY, f64::NAN] {
        let r = cone_groups(p.shape(), &free, &[1.0, bad], &truth, &s);
        assert_eq!(refused(r), ("sup_norms", "must be finite and >= 0".into()));
    }
    assert!(cone_groups(p.shape(), &free, &[0.0, 1.0], &truth, &s).is_ok());
}

#[test]
fn settled_when_the_same_groups_are_in_use_and_none_is_dying() {
    let s = L21Settings {
        eps: 1e-3,
        threshold: 1e-6,
        ..L21Settings::default()
    };
    let yes = |m: &[f64], p: &[f64]| settled(m, p, &s);
    assert!(yes(&[0.5, 0.0], &[0.7, 0.0]));
    assert!(yes(&[], &[]));
    // A group leaves or comes back: not settled.
    assert!(!yes(&[0.5, 0.0], &[0.7, 0.2]));
    assert!(!yes(&[0.5, 0.2], &[0.7, 0.0]));
    // At the threshold a group is not in use.
    assert!(yes(&[1e-6], &[0.0]) && yes(&[0.0], &[1e-6]));
    assert!(!yes(&[1e-6], &[2e-6]));
    // Between the threshold and eps / 10: dying when it halved or more.
    assert!(!yes(&[4e-5], &[8e-5 * (1.0 + 1e-9)]));
    assert!(!yes(&[4e-5], &[1.0]));
    assert!(yes(&[4e-5], &[8e-5]));
    assert!(yes(&[4e-5], &[5e-5]));
    // Above eps / 10 a shrinking group is not dying.
    assert!(yes(&[1e-4], &[1.0]));
    assert!(yes(&[5e-4], &[1.0]));
    assert!(!yes(&[1e-4 * (1.0 - 1e-9)], &[1.0]));
}

// ------------------------------------------------------------ one step, the path

#[test]
fn single_cone_step_reports_the_subproblems_objective() {
    let (p, truth) = frf_problem();
    let theta = perturbed(&truth, 0.1, 2);
    let free = FreeSet::all(truth.len());
    let s = L21Settings {
        gamma: 0.02,
        ..L21Settings::default()
    };
    let mu = 0.3;
    let r = single_cone_step(&p, &theta, &free, &[1.0, 1.0], &s, mu).unwrap();
    let d = r.step.expect("solved");
    // (g/M)^T d + (1/M) d^T (H + mu D) d + gamma sum phi varphi ||theta_g + d_g||.
    let gn = p.gauss_newton(&theta, &free).unwrap();
    let diag = marquardt_diagonal(&gn);
    let m = p.n_residuals() as f64;
    let nf = d.len();
    let mut quad = 0.0;
    for i in 0..nf {
        for j in 0..nf {
            let h = gn.gram[i + j * nf] + if i == j { mu * diag[i] } else { 0.0 };
            quad += d[i] * h * d[j];
        }
    }
    let linear: f64 = gn.gradient.iter().zip(&d).map(|(g, x)| g * x).sum();
    let penalty: f64 = r
        .groups
        .iter()
        .map(|g| g.phi * g.varphi * g.norm_after(&theta, &d))
        .sum();
    let want = linear / m + quad / m + s.gamma * penalty;
    let scale = (linear.abs() + quad) / m + s.gamma * penalty;
    assert!(
        (r.objective - want).abs() <= 1e-10 * scale,
        "{} vs {want}",
        r.objective
    );
    for bad in [-1.0, f64::NAN, f64::INFINITY] {
        let (name, _) = refused(single_cone_step(&p, &theta, &free, &[1.0, 1.0], &s, bad));
        assert_eq!(name, "mu");
    }
}

/// Stops the fit after `left` iterations.
struct StopAfter {
    left: usize,
}

impl Monitor for StopAfter {
    fn iteration(&mut self, _: &Iteration) -> bool {
        self.left = self.left.saturating_sub(1);
        self.left > 0
    }
}

#[test]
fn the_path_runs_from_the_largest_gamma_each_fit_from_the_last() {
    let (p, truth) = Linear::new(0.05);
    let start = perturbed(&truth, 0.5, 1);
    let free = FreeSet::all(truth.len());
    let s = L21Settings {
        max_outer: 3,
        ..L21Settings::default()
    };
    let gammas = [0.01, 0.2, 0.05];
    let path = l21_path(&p, &start, &free, &SUP, &gammas, &s, &mut Silent).unwrap();
    let order: Vec<f64> = path.iter().map(|(g, _)| *g).collect();
    assert_eq!(order, vec![0.2, 0.05, 0.01]);
    let mut theta = start.clone();
    for (gamma, got) in &path {
        let want = fit(&p, &theta, &SUP, &L21Settings { gamma: *gamma, ..s });
        assert_eq!(got.theta, want.theta);
        assert_eq!(got.objective, want.objective);
        theta = want.theta;
    }
    // Interrupted inside the second fit: the path ends there.
    let mut monitor = StopAfter {
        left: path[0].1.history.len() + 1,
    };
    let cut = l21_path(&p, &start, &free, &SUP, &gammas, &s, &mut monitor).unwrap();
    assert_eq!(cut.len(), 2);
    assert_eq!(cut[1].1.stop, Stop::Interrupted);
    for bad in [vec![], vec![0.1, -1.0], vec![f64::NAN], vec![f64::INFINITY]] {
        let r = l21_path(&p, &start, &free, &SUP, &bad, &s, &mut Silent);
        assert_eq!(refused(r).0, "gammas");
    }
}

#[path = "tests_loop.rs"]
mod rules;
