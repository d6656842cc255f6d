//! Unit tests of the cone program and the solver kept between steps
//! (`super`): reuse only for the same sparsity pattern, and a reused
//! solver gives what a new one gives.

use super::*;

/// Two one-entry groups: `x = [e0, e1, t0, t1]`, minimise
/// `1/2 ||e||^2 + q'e + lambda (t0 + t1)` with `|theta_k + e_k| <= t_k`.
/// Its answer is soft-thresholding: `theta_k + e_k = shrink(theta_k - q_k, lambda)`.
fn program(theta: [f64; 2], q: [f64; 2], lambda: f64) -> Program {
    Program {
        p: Csc {
            colptr: vec![0, 1, 2, 2, 2],
            rowval: vec![0, 1],
            values: vec![1.0, 1.0],
        },
        q: vec![q[0], q[1], lambda, lambda],
        a: Csc {
            colptr: vec![0, 1, 2, 3, 4],
            rowval: vec![1, 3, 0, 2],
            values: vec![-1.0; 4],
        },
        b: vec![0.0, theta[0], 0.0, theta[1]],
        cones: vec![Cone::Soc(2), Cone::Soc(2)],
    }
}

fn base() -> Program {
    program([1.0, -0.2], [0.3, 0.1], 0.5)
}

/// What a new solver gives for `prog`.
fn fresh(prog: &Program) -> String {
    let mut solver = ConeSolver::new(1e-10);
    outcome(solver.run(prog).expect("memory"))
}

/// A solve's outcome, exactly: the numbers, the status and the
/// iterations, or why it failed.
fn outcome(r: Result<Solved, String>) -> String {
    match r {
        Ok(s) => format!("{:?} {:?} {}", s.x, s.status, s.iterations),
        Err(why) => why,
    }
}

#[test]
fn the_program_is_solved_to_its_closed_form() {
    let mut solver = ConeSolver::new(1e-10);
    let sol = solver.run(&base()).unwrap().unwrap();
    assert_eq!(sol.status, SolverStatus::Solved);
    // shrink(1 - 0.3, 0.5) = 0.2: e0 = -0.8, t0 = 0.2; shrink(-0.3, 0.5) = 0:
    // e1 = 0.2, t1 = 0.
    for (x, want) in sol.x.iter().zip([-0.8, 0.2, 0.2, 0.0]) {
        assert!((x - want).abs() < 1e-7, "{:?}", sol.x);
    }
}

#[test]
fn a_solver_is_reused_for_the_same_pattern_and_gives_a_new_ones_answer() {
    let mut solver = ConeSolver::new(1e-10);
    assert_eq!(
        format!("{solver:?}"),
        "ConeSolver { cached: false, builds: 0 }"
    );
    solver.run(&base()).unwrap().unwrap();
    assert_eq!(
        format!("{solver:?}"),
        "ConeSolver { cached: true, builds: 1 }"
    );
    for (theta, q) in [([0.4, 2.0], [-0.1, 0.6]), ([-3.0, 0.1], [0.2, 0.2])] {
        let next = program(theta, q, 0.25);
        assert!(next.has_key(&base().key()));
        let reused = outcome(solver.run(&next).unwrap());
        assert_eq!(reused, fresh(&next));
        assert_eq!(solver.builds(), 1);
    }
}

/// One change of a program's pattern.
type Change = fn(&mut Program);

#[test]
fn a_program_that_differs_in_one_part_of_its_key_gets_a_new_solver() {
    let variants: [(&str, Change); 5] = [
        // e1 loses its curvature (an explicit zero at (1, 2) instead).
        ("P's columns", |p| {
            p.p.colptr = vec![0, 1, 1, 2, 2];
            p.p.values = vec![1.0, 0.0];
        }),
        ("P's rows", |p| {
            p.p.rowval = vec![0, 0];
            p.p.values = vec![1.0, 0.0];
        }),
        // e0 in both cones, e1 in none.
        ("A's columns", |p| p.a.colptr = vec![0, 2, 2, 3, 4]),
        // e0 in the second cone, e1 in the first.
        ("A's rows", |p| p.a.rowval = vec![3, 1, 0, 2]),
        // One cone: t0 >= ||(theta0 + e0, t1, theta1 + e1)||.
        ("the cones", |p| p.cones = vec![Cone::Soc(4)]),
    ];
    for (what, change) in variants {
        let mut solver = ConeSolver::new(1e-10);
        solver.run(&base()).unwrap().unwrap();
        let mut other = base();
        change(&mut other);
        assert!(!other.has_key(&base().key()), "{what}");
        let got = outcome(solver.run(&other).unwrap());
        assert_eq!(solver.builds(), 2, "{what}");
        assert_eq!(got, fresh(&other), "{what}");
        assert!(got.contains("Solved"), "{what}: {got}");
        // And back: the first pattern again is one more build.
        solver.run(&base()).unwrap().unwrap();
        assert_eq!(solver.builds(), 3, "{what}");
    }
}

#[test]
fn a_program_whose_b_alone_is_longer_is_not_given_the_kept_solver() {
    // The cones fix b's length in a well-formed program: this one is not,
    // and gets Clarabel's own refusal rather than the kept solver.
    let mut solver = ConeSolver::new(1e-10);
    solver.run(&base()).unwrap().unwrap();
    let mut longer = base();
    longer.b.push(0.0);
    assert!(!longer.has_key(&base().key()));
    let got = outcome(solver.run(&longer).unwrap());
    assert_eq!(got, fresh(&longer));
    assert!(got.starts_with("setup failed"), "{got}");
    assert_eq!(
        format!("{solver:?}"),
        "ConeSolver { cached: false, builds: 1 }"
    );
}

#[test]
fn iterative_refinement_only_below_the_default_tolerance() {
    for (tol, refine) in [(1e-10, true), (DEFAULT_CONE_TOL, false), (1e-6, false)] {
        let mut solver = ConeSolver::new(tol);
        solver.run(&base()).unwrap().unwrap();
        let (_, kept) = solver.cached.as_ref().unwrap();
        assert_eq!(kept.settings().iterative_refinement_enable, refine, "{tol}");
        assert_eq!(kept.settings().tol_gap_abs, tol);
    }
    assert_eq!(ConeSolver::default().tol, DEFAULT_CONE_TOL);
}

#[test]
fn a_key_is_the_pattern_and_the_sizes() {
    let prog = base();
    assert_eq!(
        prog.key(),
        (
            vec![0, 1, 2, 2, 2],
            vec![0, 1],
            vec![0, 1, 2, 3, 4],
            vec![1, 3, 0, 2],
            vec![Cone::Soc(2), Cone::Soc(2)],
            4
        )
    );
}
