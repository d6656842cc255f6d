//! Algorithm 1's loop (`super::super`): each stopping rule at its margin,
//! the gain ratio on a linear problem (whose quadratic model is exact), the
//! damping after a rejection, and the end of a reweighting that no damping
//! helps.

use super::*;

// ------------------------------------------------------------ the loop

#[test]
fn gamma_zero_is_levenberg_marquardt_with_the_fits_damping() {
    let (p, truth) = frf_problem();
    let start = perturbed(&truth, 0.05, 4);
    let s = L21Settings {
        gamma: 0.0,
        lambda0: 0.3,
        weighting: Weighting::Scaled,
        ..L21Settings::default()
    };
    let free = FreeSet::all(truth.len());
    let got = fit(&p, &start, &SUP, &s);
    let lm = LmSettings {
        lambda0: 0.3,
        ..LmSettings::default()
    };
    let want = levenberg_marquardt(&p, &start, &free, &lm, &mut Silent).unwrap();
    assert_eq!(got.theta, want.theta);
    assert_eq!(got.history[0].lambda, 0.3);
    assert_eq!(got.objective, got.vnls / p.n_residuals() as f64);
    assert_eq!(got.weights, phis(&p, &got.theta, &SUP, &s));
}

#[test]
fn on_a_linear_problem_every_step_gains_what_it_predicted() {
    // The quadratic model of a linear residual is exact, and the penalty
    // is evaluated exactly: every accepted step's gain ratio is 1.
    let (p, truth) = Linear::new(0.05);
    let s = L21Settings {
        gamma: 0.05,
        weighting: Weighting::Scaled,
        lambda0: 0.5,
        ..L21Settings::default()
    };
    let f = fit(&p, &perturbed(&truth, 0.5, 1), &SUP, &s);
    let mut checked = 0;
    let mut objective = f64::INFINITY;
    for it in &f.history {
        if it.accepted && it.objective < objective * (1.0 - 1e-6) {
            assert!((it.gain_ratio - 1.0).abs() < 1e-6, "{it:?}");
            checked += 1;
        }
        objective = it.objective;
    }
    assert!(checked >= 3, "{checked} steps checked");
    // Reweightings counted from 1; the last is the fit's count.
    let outers: Vec<usize> = f.history.iter().map(|it| it.outer).collect();
    assert_eq!(outers[0], 1);
    assert!(outers.windows(2).all(|w| w[1] == w[0] || w[1] == w[0] + 1));
    assert_eq!(*outers.last().unwrap(), f.outer_iterations);
    // The objective reported: V_NLS / M plus the penalty at the weights returned.
    let free = FreeSet::all(truth.len());
    let groups = cone_groups(p.shape(), &free, &SUP, &f.theta, &s).unwrap();
    let penalty: f64 = groups
        .iter()
        .zip(&f.weights)
        .map(|(g, w)| w * g.varphi * g.norm_at(&f.theta))
        .sum();
    let want = p.cost(&f.theta).unwrap() / ROWS as f64 + s.gamma * penalty;
    assert!(
        (f.objective - want).abs() <= 1e-12 * want,
        "{} vs {want}",
        f.objective
    );
}

#[test]
fn max_outer_counts_the_reweightings() {
    let (p, truth) = Linear::new(0.2);
    let start = perturbed(&truth, 0.5, 1);
    let s = L21Settings {
        gamma: 0.2,
        dphi_min: 0.0,
        dvnls_min: 0.0,
        ..L21Settings::default()
    };
    let needed = fit(&p, &start, &SUP, &s).outer_iterations;
    assert!(needed >= 3, "{needed}");
    for max_outer in 1..needed {
        let f = fit(&p, &start, &SUP, &L21Settings { max_outer, ..s });
        assert_eq!(f.stop, Stop::MaxIterations);
        assert_eq!(f.outer_iterations, max_outer);
        assert_eq!(f.history.last().unwrap().outer, max_outer);
    }
}

#[test]
fn a_fit_that_settles_in_its_last_allowed_reweighting_has_converged() {
    // The stopping tests run once more after the last reweighting the limit
    // allows: a limit of exactly the reweightings a fit needs gives that
    // fit (the same steps, theta, weights and objective) and its stop, not
    // the iteration limit; one reweighting fewer stops at the limit, with
    // the weights at the theta it returns.
    let (sp, sstart, ss) = sparse_start(0.01, 0.01, 0.01);
    let ss = L21Settings {
        dphi_min: 0.0,
        dvnls_min: 0.0,
        ..ss
    };
    let (lp, truth) = Linear::new(0.05);
    let lstart = perturbed(&truth, 0.5, 1);
    let ls = L21Settings {
        gamma: 0.05,
        dvnls_min: 0.0,
        ..L21Settings::default()
    };
    let cases: [(&dyn Objective, &[f64], L21Settings, usize); 2] =
        [(&sp, &sstart, ss, 1), (&lp, &lstart, ls, 2)];
    for (p, start, s, least) in cases {
        let want = fit(p, start, &SUP, &s);
        assert_ne!(want.stop, Stop::MaxIterations);
        let k = want.outer_iterations;
        assert!(k >= least, "{k}");
        let limited = fit(p, start, &SUP, &L21Settings { max_outer: k, ..s });
        assert_eq!(limited.stop, want.stop);
        assert_eq!(limited.outer_iterations, k);
        assert_eq!(limited.theta, want.theta);
        assert_eq!(limited.history.len(), want.history.len());
        assert_eq!(limited.weights, want.weights);
        assert_eq!(limited.objective, want.objective);
        if k > 1 {
            let short = fit(
                p,
                start,
                &SUP,
                &L21Settings {
                    max_outer: k - 1,
                    ..s
                },
            );
            assert_eq!(short.stop, Stop::MaxIterations);
            assert_eq!(short.outer_iterations, k - 1);
            assert_eq!(short.weights, phis(p, &short.theta, &SUP, &s));
        }
    }
}

/// The run with `s`, but one reweighting only.
fn one_outer(p: &dyn Objective, start: &[f64], s: &L21Settings) -> Fit {
    fit(p, start, &SUP, &L21Settings { max_outer: 1, ..*s })
}

#[test]
fn the_weights_rule_stops_at_its_margin() {
    let (p, truth) = Linear::new(0.05);
    let start = perturbed(&truth, 0.5, 1);
    let s = L21Settings {
        gamma: 0.05,
        dvnls_min: 0.0,
        ..L21Settings::default()
    };
    let first = one_outer(&p, &start, &s);
    let (before, after) = (phis(&p, &start, &SUP, &s), phis(&p, &first.theta, &SUP, &s));
    let change = after
        .iter()
        .zip(&before)
        .map(|(a, b)| (a - b).abs() / b)
        .fold(0.0, f64::max);
    assert!(change > 1e-3, "{change}");
    for (factor, stops) in [(1.0 + 1e-6, true), (1.0 - 1e-6, false)] {
        let f = fit(
            &p,
            &start,
            &SUP,
            &L21Settings {
                dphi_min: change * factor,
                ..s
            },
        );
        assert_eq!((f.stop == Stop::Weights && f.outer_iterations == 1), stops);
        assert_eq!(f.history.len() == first.history.len(), stops);
    }
}

#[test]
fn settled_by_vnls_at_its_margin_when_the_response_moves() {
    let (p, start, s) = sparse_start(0.05, 1.0, 0.05);
    let s = L21Settings { dphi_min: 0.0, ..s };
    let first = one_outer(&p, &start, &s);
    let (m0, m1) = (
        magnitudes(&p, &start, &SUP, &s),
        magnitudes(&p, &first.theta, &SUP, &s),
    );
    assert!(settled(&m1, &m0, &s), "{m0:?} -> {m1:?}");
    let (v0, v1) = (p.cost(&start).unwrap(), first.vnls);
    let (r0, r1) = (p.residual(&start), p.residual(&first.theta));
    let moved: f64 = r0.iter().zip(&r1).map(|(a, b)| (a - b) * (a - b)).sum();
    assert!(moved > 2.0 * SETTLED_RESPONSE, "{moved}");
    let change = (v0 - v1).abs() / v0;
    assert!(change > 1e-6, "{change}");
    for (factor, stops) in [(1.0 + 1e-6, true), (1.0 - 1e-6, false)] {
        let f = fit(
            &p,
            &start,
            &SUP,
            &L21Settings {
                dvnls_min: change * factor,
                ..s
            },
        );
        assert_eq!(f.stop == Stop::Settled && f.outer_iterations == 1, stops);
    }
}

#[test]
fn settled_when_the_response_stops_moving_whatever_vnls_did() {
    let (p, start, s) = sparse_start(0.01, 0.01, 0.01);
    let s = L21Settings {
        dphi_min: 0.0,
        dvnls_min: 0.0,
        ..s
    };
    let first = one_outer(&p, &start, &s);
    let (r0, r1) = (p.residual(&start), p.residual(&first.theta));
    let moved: f64 = r0.iter().zip(&r1).map(|(a, b)| (a - b) * (a - b)).sum();
    assert!(moved < 0.5 * SETTLED_RESPONSE && moved > 0.0, "{moved}");
    assert_ne!(p.cost(&start).unwrap(), first.vnls);
    let f = fit(&p, &start, &SUP, &s);
    assert_eq!((f.stop, f.outer_iterations), (Stop::Settled, 1));
}

#[test]
fn the_inner_loop_stops_at_the_objective_and_step_margins() {
    let (p, truth) = Linear::new(0.05);
    let start = perturbed(&truth, 0.5, 1);
    let s = L21Settings {
        gamma: 0.05,
        ftol: 0.0,
        dtheta_min: 0.0,
        lambda0: 0.5,
        max_outer: 1,
        ..L21Settings::default()
    };
    let f = fit(&p, &start, &SUP, &s);
    let h = &f.history;
    assert!(h.len() >= 3 && h[0].accepted, "{h:?}");
    // The first step's relative decrease of the objective, and its size.
    let free = FreeSet::all(truth.len());
    let groups = cone_groups(p.shape(), &free, &SUP, &start, &s).unwrap();
    let objective0 = p.cost(&start).unwrap() / ROWS as f64
        + s.gamma
            * groups
                .iter()
                .map(|g| g.phi * g.varphi * g.norm_at(&start))
                .sum::<f64>();
    let gain = (objective0 - h[0].objective) / objective0;
    let theta_norm = norm(&start);
    let step = h[0].step_norm;
    // dtheta_min at which the first step is just small:
    // step = x (theta_norm + x).
    let x = 0.5 * (-theta_norm + (theta_norm * theta_norm + 4.0 * step).sqrt());
    for (factor, stops) in [(1.0 + 1e-6, true), (1.0 - 1e-6, false)] {
        let by_gain = fit(
            &p,
            &start,
            &SUP,
            &L21Settings {
                ftol: gain * factor,
                ..s
            },
        );
        assert_eq!(by_gain.history.len() == 1, stops, "ftol {factor}");
        let by_step = fit(
            &p,
            &start,
            &SUP,
            &L21Settings {
                dtheta_min: x * factor,
                ..s
            },
        );
        assert_eq!(by_step.history.len() == 1, stops, "dtheta_min {factor}");
    }
}

/// The FRF problem, a start 0.3 off and a small initial damping: bold
/// first steps, some rejected.
fn bold() -> (Problem, Vec<f64>, L21Settings) {
    let (p, truth) = frf_problem();
    let s = L21Settings {
        gamma: 1e-2,
        lambda0: 1e-3,
        ..L21Settings::default()
    };
    (p, perturbed(&truth, 0.3, 7), s)
}

#[test]
fn a_rejected_step_raises_the_damping_and_the_reweighting_goes_on() {
    let (p, start, s) = bold();
    let f = fit(&p, &start, &[1.0, 1.0], &s);
    let h = &f.history;
    let mut after_rejection = 0;
    for w in h.windows(2).filter(|w| w[0].outer == w[1].outer) {
        if w[0].accepted {
            // Nielsen's rule: a good step (gain ratio 1/2 or more) lowers it.
            if w[0].gain_ratio >= 0.5 {
                assert!(w[1].lambda <= w[0].lambda, "{w:?}");
            }
        } else {
            assert!(w[1].lambda > w[0].lambda, "{w:?}");
            after_rejection += 1;
        }
    }
    assert!(after_rejection > 0, "no step followed a rejection");
}

#[test]
fn a_doubtful_cone_step_is_judged_by_its_cost_alone_and_its_pieces_come_only_when_taken() {
    let (p, start, s) = bold();
    let counted = crate::testing::Counted::new(&p);
    let f = fit(&counted, &start, &[1.0, 1.0], &s);
    let h = &f.history;
    // Doubtful: a reweighting's first step and every step after a rejection.
    let doubtful = |k: usize| k == 0 || h[k - 1].outer != h[k].outer || !h[k - 1].accepted;
    assert!(
        (0..h.len()).any(|k| doubtful(k) && !h[k].accepted),
        "no doubtful step was rejected"
    );
    assert!(
        (0..h.len()).any(|k| doubtful(k) && h[k].accepted),
        "no doubtful step was taken"
    );
    assert_eq!(counted.calls(), crate::testing::expected_calls(h, doubtful));
}

/// The linear problem's cost, defined only at one point and flat there
/// (zero gradient and Gauss-Newton matrix): every trial point fails to
/// evaluate (an error that is not fatal), so every step is rejected, and
/// the steps do not shrink as the damping grows (the Jacobi scaling
/// undoes it; only the penalty moves them), so the step-size rule does not
/// end the reweighting first.
struct Wall {
    inner: Linear,
    at: Vec<f64>,
}

impl Wall {
    fn check(&self, theta: &[f64]) -> Result<()> {
        if theta == self.at.as_slice() {
            Ok(())
        } else {
            Err(crate::error::invalid("model", "not defined here"))
        }
    }
}

impl Objective for Wall {
    fn shape(&self) -> &Shape {
        self.inner.shape()
    }
    fn n_residuals(&self) -> usize {
        self.inner.n_residuals()
    }
    fn cost(&self, theta: &[f64]) -> Result<f64> {
        self.check(theta)?;
        self.inner.cost(theta)
    }
    fn gauss_newton(&self, theta: &[f64], free: &FreeSet) -> Result<GaussNewton> {
        self.check(theta)?;
        Ok(GaussNewton {
            vnls: self.inner.cost(theta)?,
            gradient: vec![0.0; free.len()],
            gram: vec![0.0; free.len() * free.len()],
            factors: None,
        })
    }
    fn response(&self, theta: &[f64]) -> Result<Vec<f64>> {
        self.check(theta)?;
        self.inner.response(theta)
    }
}

#[test]
fn a_reweighting_ends_when_no_damping_gives_a_decrease() {
    let (p, truth) = Linear::new(0.05);
    let start = perturbed(&truth, 0.5, 1);
    let wall = Wall {
        inner: p,
        at: start.clone(),
    };
    let s = L21Settings {
        gamma: 0.05,
        max_inner: 100,
        ..L21Settings::default()
    };
    let f = fit(&wall, &start, &SUP, &s);
    // Rejections until the damping passes its limit (the factor grows
    // 2, 4, 8, ...: a dozen from lambda0 = 1e-2), then the weights at the
    // same point are the same.
    let h = &f.history;
    assert!(h.iter().all(|it| !it.accepted && it.outer == 1));
    assert!(h.iter().all(|it| it.step_norm > 0.1), "{h:?}");
    assert!(h.len() > 5 && h.len() < 20, "{} steps", h.len());
    assert_eq!((f.stop, f.theta), (Stop::Weights, start));
}
