"""Fits that keep stability, and what identify adds: refit, covariance, stability."""

from __future__ import annotations

import warnings
from types import SimpleNamespace

import numpy as np
import pytest

import lpvid
from lpvid.stable.enforce import STABLE_TOL, stabilised

BASIS = lpvid.Polynomial(2, domain=(0.0, 1.0))
P = np.array([0.0, 1 / 3, 2 / 3, 1.0])
FIXED = {"B": [1, 2], "C": True, "D": True}


@pytest.fixture(scope="module")
def peaked():
    """A first-order system whose pole peaks at 0.995 between the points (|2p - 1|^3 shape).

    The quadratic basis cannot follow the peak: the best quadratic through the
    data overshoots the unit circle between the two middle points.
    """
    a = 0.995 - 0.1 * np.abs(2 * P - 1) ** 3
    f = np.linspace(0.02, 0.5, 60)
    z = np.exp(2j * np.pi * f)
    G = (0.1 / (z[None, :] - a[:, None]))[:, :, None, None]
    sigma = 0.05 * np.abs(G)
    rng = np.random.default_rng(0)
    G = G + sigma * (rng.standard_normal(G.shape) + 1j * rng.standard_normal(G.shape)) / np.sqrt(2)
    return lpvid.FrfData(P, f, G, sigma=sigma, Ts=1.0)


def _start(a0=0.9):
    k = len(BASIS) + 1
    A, B, C = np.zeros((k, 1, 1)), np.zeros((k, 1, 1)), np.zeros((k, 1, 1))
    A[0], B[0], C[0] = a0, 0.1, 1.0
    return lpvid.LpvModel(A, B, C, basis=BASIS, Ts=1.0)


def _max_pole(model):
    p = np.linspace(0.0, 1.0, 100_001)
    return np.max(np.abs(lpvid.model.frozen.frozen_A(model, p)[:, 0, 0]))


def test_fit_nls_goes_unstable_between_the_points_unless_told(peaked):
    free = lpvid.fit_nls(_start(), peaked, FIXED)
    kept = lpvid.fit_nls(_start(), peaked, FIXED, stable=True)
    # Unconstrained: stable at the points, unstable between the middle two.
    assert lpvid.model.frozen.frozen_stable(free.model, P)
    rep = lpvid.stability(free.model, quadratic=False)
    assert not rep.stable and 1 / 3 < rep.worst_p < 2 / 3
    assert _max_pole(free.model) > 1.0
    # Constrained: stable on the whole range (checked densely, independently).
    assert lpvid.stability(kept.model, quadratic=False).stable
    assert _max_pole(kept.model) < 1.0
    # at a small cost in V_NLS (seen: 0.3 %)
    assert free.vnls < kept.vnls < 1.02 * free.vnls
    assert kept.converged


def test_fit_l21_keeps_stability(peaked):
    free = lpvid.fit_l21(_start(), peaked, 1e-4, fixed=FIXED)
    kept = lpvid.fit_l21(_start(), peaked, 1e-4, fixed=FIXED, stable=True)
    assert not lpvid.stability(free.model, quadratic=False).stable
    assert lpvid.stability(kept.model, quadratic=False).stable and _max_pole(kept.model) < 1.0
    assert kept.vnls < 1.02 * free.vnls
    path = lpvid.l21_path(_start(), peaked, [1e-3, 1e-4], fixed=FIXED, stable=True)
    assert all(lpvid.stability(r.model, quadratic=False).stable for r in path)


def test_unstable_start_is_refused(peaked):
    with pytest.raises(
        ValueError,
        match=r"^model: stable=True needs a stable start, but .* at p = 0 is unstable",
    ):
        lpvid.fit_nls(_start(1.01), peaked, FIXED, stable=True)
    with pytest.raises(
        ValueError,
        match=r"^model: stable=True needs a stable start, .* \(stability margin -0\.01",
    ):
        lpvid.fit_l21(_start(1.01), peaked, 1e-3, fixed=FIXED, stable=True)
    with pytest.raises(
        ValueError,
        match=r"^model: stable=True needs a stable start, .* closer to the stability boundary",
    ):
        lpvid.fit_nls(_start(1 - STABLE_TOL / 2), peaked, FIXED, stable=True)
    with pytest.raises(ValueError, match=r"^p_range: \(0, 2\) reaches outside the basis domain"):
        lpvid.fit_nls(_start(), peaked, FIXED, stable=True, p_range=(0.0, 2.0))
    with pytest.raises(TypeError, match=r"^stable: expected True or False, got str"):
        lpvid.fit_nls(_start(), peaked, FIXED, stable="yes")


def test_stabilised_moves_poles_inside():
    m = _start(1.2)
    s = stabilised(m)
    rep = lpvid.stability(s, quadratic=False)
    assert rep.stable and rep.margin == pytest.approx(1e-3)
    assert stabilised(_start(0.5)) is not None and stabilised(_start(0.5)).A[0, 0, 0] == 0.5
    ct = lpvid.LpvModel(
        [[[0.5]], [[1.0]], [[0.0]]], [[[1.0]], [[0]], [[0]]], [[[1.0]], [[0]], [[0]]], basis=BASIS
    )
    assert lpvid.stability(stabilised(ct), quadratic=False).stable


def test_identify_with_and_without_stability(peaked):
    with pytest.warns(lpvid.ConvergenceWarning, match="unstable frozen models"):
        free = lpvid.identify(peaked, 1, BASIS, fixed={"D": True})
    assert not free.stability.stable
    assert "NOT stable" in free.summary()
    with warnings.catch_warnings():
        warnings.simplefilter("error", lpvid.ConvergenceWarning)
        kept = lpvid.identify(peaked, 1, BASIS, fixed={"D": True}, stable=True)
    assert kept.stability.stable and "frozen models stable over p in [0, 1]" in kept.summary()
    for e in kept.entries:
        assert lpvid.stability(e.model, quadratic=False).stable
    assert kept.final.vnls < 1.02 * free.final.vnls


def _peaked_at(p, seed):
    a = 0.995 - 0.1 * np.abs(2 * np.asarray(p) - 1) ** 3
    f = np.linspace(0.02, 0.5, 60)
    z = np.exp(2j * np.pi * f)
    G = (0.1 / (z[None, :] - a[:, None]))[:, :, None, None]
    sigma = 0.05 * np.abs(G)
    rng = np.random.default_rng(seed)
    G = G + sigma * (rng.standard_normal(G.shape) + 1j * rng.standard_normal(G.shape)) / np.sqrt(2)
    return lpvid.FrfData(p, f, G, sigma=sigma, Ts=1.0)


def test_refit_removes_the_shrinkage(peaked):
    res = lpvid.identify(peaked, 1, BASIS, fixed={"D": True}, stable=True, gammas=[0.1])
    e = res.entry
    assert e.gamma == 0.1 and 0 < e.n_groups < res.entries[0].n_groups
    fit, held = lpvid.refit(e.model, peaked, {"D": True}, stable=True, warn=False)
    # Levenberg-Marquardt on the support from the l2,1 model: no worse on the data.
    assert fit.vnls <= e.vnls * (1 + 1e-9)
    assert fit.model.group_norms().count() == e.n_groups
    # the dropped groups are exactly zero and held there
    for x, kept in e.nonzero_groups.items():
        coef = getattr(fit.model, x)
        for i in range(1, coef.shape[0]):
            if i not in kept:
                assert np.all(coef[i] == 0)
                assert np.all(held[lpvid.fixed_mask(fit.model, {x: [i]})])


def test_identify_keeps_a_refit_only_where_it_validates_better(peaked):
    # Without validation data nothing judges a refit: the path's model is returned.
    res = lpvid.identify(peaked, 1, BASIS, fixed={"D": True}, stable=True, gammas=[0.1])
    assert res.refit is None and not res.refitted and res.model is res.entry.model
    assert res.final is res.entry and "not refitted" in res.reason
    cov = res.covariance
    assert cov is not None and cov.model is res.model
    held = lpvid.fixed_mask(res.model, {"D": True})
    assert np.all(cov.theta[held] == 0)  # linearised on the support of the model returned
    # With validation data the refit is run and judged on them.
    seen = {True: 0, False: 0}
    for seed in range(4):
        val = _peaked_at([1 / 6, 1 / 2, 5 / 6], seed + 10)
        res = lpvid.identify(
            peaked, 1, BASIS, validation=val, fixed={"D": True}, stable=True, gammas=[0.1]
        )
        e, r = res.entry, res.refit_entry
        assert res.refit is not None and r is not None
        better = r.validation_vnls < (1 - lpvid.trust.support.REFIT_MARGIN) * e.validation_vnls
        assert res.refitted == better
        seen[better] += 1
        assert res.final.validation_vnls <= e.validation_vnls
        assert lpvid.vnls(res.model, val) == res.final.validation_vnls
        assert ("refitted on the support" in res.reason) == better
        assert res.covariance.model is res.model and res.stability.stable
        line = [x for x in res.summary().splitlines() if x.startswith("refit on the support")]
        assert line and line[0].endswith("; kept" if better else "the path's model returned")
    no = lpvid.identify(
        peaked, 1, BASIS, validation=val, fixed={"D": True}, stable=True, gammas=[0.1], refit=False
    )
    assert no.refit is None and no.model is no.entry.model and no.final is no.entry
    assert no.covariance is not None and "refit=False" in no.reason


def _ct_window():
    """x' = a(p) x, a stable start (a = -1) and a model unstable only in a narrow window.

    a(s) = 1e-8 - (s - s0)^2 (s = 2p - 1) is positive for |p - p0| < 5e-5 only, p0 midway
    between two of the core's check points (a uniform grid of 2049 points on [0, 1]).
    """
    from lpvid.stable.enforce import CHECK_POINTS

    p0 = (1000.5) / (CHECK_POINTS - 1)
    s0 = 2 * p0 - 1
    k = len(BASIS) + 1
    B = np.zeros((k, 1, 1))
    B[0] = 1.0
    start = lpvid.LpvModel([[[-1.0]], [[0.0]], [[0.0]]], B, B.copy(), basis=BASIS)
    bad = lpvid.LpvModel([[[1e-8 - s0**2]], [[2 * s0]], [[-1.0]]], B, B.copy(), basis=BASIS)
    return start, bad, p0


def test_stable_fits_recheck_the_continuum_between_the_check_points():
    # A stand-in for the core's fit: it returns the window model whenever the check points
    # it is given call it stable (as the core would), else it stays at the start.
    from lpvid.stable.enforce import run_stable

    start, bad, p0 = _ct_window()
    assert (
        lpvid.model.frozen.stability_margin(lpvid.model.frozen.frozen_poles(bad, [p0]), None)[0] < 0
    )
    seen = []

    def fit(points):
        seen.append(points.worst(bad.theta)[1])
        theta = bad.theta if seen[-1] >= STABLE_TOL else start.theta
        return SimpleNamespace(theta=theta, interrupted=False)

    raw = run_stable(start, None, fit)
    # The first fit passed its check points; the check of the continuum found the window
    # and the second fit, with its place among the check points, refused the model.
    assert seen[0] == 1.0 and seen[1] < 0 and len(seen) == 2
    np.testing.assert_array_equal(raw.theta, start.theta)
    # A fit that keeps returning an unstable model is an error after MAX_ROUNDS, never a result.
    seen.clear()
    with pytest.raises(RuntimeError, match=r"^stable=True: after 3 rounds .*\(at p = 0\.4885"):
        run_stable(start, None, lambda points: SimpleNamespace(theta=bad.theta, interrupted=False))
    # An interrupted fit is returned as it is (the caller reports it).
    out = run_stable(start, None, lambda points: SimpleNamespace(theta=bad.theta, interrupted=True))
    assert out.interrupted


def _window_at(p0: float, start):
    """The model of :func:`_ct_window` with its window of instability at ``p0``."""
    s0 = 2 * p0 - 1
    return lpvid.LpvModel([[[1e-8 - s0**2]], [[2 * s0]], [[-1.0]]], start.B, start.C, basis=BASIS)


def _adversary(start, near: float, reach: float):
    """A stand-in fit that puts the window wherever the check points it is given miss it.

    Of the places within ``reach`` of ``near`` (a fine grid), the first where the check
    points see no margin below STABLE_TOL; the start when there is none (as the core would
    refuse every step). What a fit whose optimum sits in the window does (seen on
    lpvid.testing.synthetic_parametric at four points: the window moved 1e-5 a round).
    """
    places = near + np.linspace(-reach, reach, 4001)

    def fit(points):
        for q in places:
            model = _window_at(q, start)
            if points.worst(model.theta)[1] >= STABLE_TOL:
                return SimpleNamespace(theta=model.theta, interrupted=False)
        return SimpleNamespace(theta=start.theta, interrupted=False)

    return fit


def test_a_window_that_moves_beside_each_point_added_is_closed_by_adding_it_whole():
    from lpvid.stable.enforce import CHECK_POINTS, run_stable

    start, _, p0 = _ct_window()
    h = 1.0 / (CHECK_POINTS - 1)
    # the window moves within one check-point spacing of where it was first found
    raw = run_stable(start, None, _adversary(start, p0, h))
    assert lpvid.stability(start.with_theta(raw.theta), (0.0, 1.0)).stable
    np.testing.assert_array_equal(raw.theta, start.theta)


def test_a_floor_lets_the_check_points_see_a_real_pole_near_the_origin():
    from lpvid.stable.enforce import run_stable

    start, bad, p0 = _ct_window()
    # the check points next to the window: a real pole 1e-7 or less from the origin,
    # damping ratio 1 without a floor; against a floor of 1 rad/s, a margin below STABLE_TOL
    grid = lpvid.stable.enforce.check_points(bad, [(0.0, 1.0)], [])
    floored = lpvid.stable.enforce.check_points(bad, [(0.0, 1.0)], [], floor=1.0)
    assert grid.worst(bad.theta)[1] == 1.0
    assert 0 < floored.worst(bad.theta)[1] < STABLE_TOL
    # anywhere in the range: with the floor no place between the check points hides it
    raw = run_stable(start, None, _adversary(start, 0.5, 0.5), floor=1.0)
    np.testing.assert_array_equal(raw.theta, start.theta)
    # the start itself: a real pole at -1 against a floor of 1, margin 1
    assert lpvid.stable.enforce.check_points(start, [(0.0, 1.0)], [], 1.0).worst(start.theta)[
        1
    ] == pytest.approx(1.0)


def test_the_floor_is_the_lowest_measured_angular_frequency():
    from lpvid.stable.enforce import pole_floor

    start, _, _ = _ct_window()
    data = lpvid.FrfData([0.0, 0.5, 1.0], [0.0, 0.25, 4.0], np.ones((3, 3, 1, 1), complex))
    assert pole_floor(start, data) == 2 * np.pi * 0.25
    assert pole_floor(start, None) == 0.0
    discrete = lpvid.LpvModel(start.A, start.B, start.C, basis=BASIS, Ts=0.1)
    assert pole_floor(discrete, data) == 0.0


@pytest.mark.parametrize("how", ["stable", "pinned"])
def test_ctrl_c_stops_a_stable_or_pinned_sweep(peaked, how):
    # Ctrl-C during the first fit (a callback that raises it once): the sweep returns that
    # interrupted fit and starts no other.
    calls = []

    def once(row):
        calls.append(row)
        if len(calls) == 1:
            raise KeyboardInterrupt

    path = lpvid.l21_path(
        _start(), peaked, [1e-2, 1e-3, 1e-4], fixed=FIXED, callback=once, warn=False, **{how: True}
    )
    assert len(path) == 1 and path[-1].interrupted and path[-1].stop == "keyboard_interrupt"
    assert len(calls) == 1


def test_stable_fit_replaces_only_what_is_unstable_on_its_range():
    # a(p) = 0.99 + 0.02 p: margin 5e-3 on [0, 0.25], 0 at p = 0.5, unstable beyond.
    from lpvid.trust.steps import stable_fit

    basis = lpvid.Polynomial(1, domain=(0.0, 1.0))  # s = 2 p - 1
    one, zero = [[1.0]], [[0.0]]
    true = lpvid.LpvModel([[[1.0]], [[0.01]]], [[[0.1]], zero], [one, zero], None, basis, 1.0)
    p = np.array([0.0, 0.25, 0.5])
    f = np.linspace(0.02, 0.5, 40)
    data = lpvid.FrfData(p, f, true.frf(f, p), sigma=0.01, Ts=1.0)
    fit = lpvid.fit_nls(true, data, {"D": True})
    assert fit.model.D[0, 0, 0] == 0.0
    assert stable_fit(fit, data, {"D": True}, 1e-6, (0.0, 0.25)) is fit
    out = stable_fit(fit, data, {"D": True}, 1e-6, (0.0, 0.5))
    rep = lpvid.stability(out.model, (0.0, 0.5), quadratic=False)
    assert out is not fit and rep.stable and rep.margin >= STABLE_TOL
    assert out.model.D[0, 0, 0] == 0.0  # fixed stays fixed
    assert not lpvid.stability(out.model, quadratic=False).stable  # beyond the range: free


def test_stabilised_on_its_range_only_and_to_the_margin_asked():
    # Discrete time, a(p) = 0.9999 (margin 1e-4): scaled to margin 1e-3 exactly.
    close = stabilised(_start(0.9999))
    assert lpvid.stability(close, quadratic=False).margin == pytest.approx(1e-3, rel=1e-9)
    # a(s) = 0.9 + 0.2 s: stable with margin 0.1 on p in [0, 0.5], unstable beyond:
    # unchanged on [0, 0.5], scaled on the whole range.
    base = _start(0.9)
    A = base.A.copy()
    A[1, 0, 0] = 0.2
    tilted = lpvid.LpvModel(A, base.B, base.C, basis=BASIS, Ts=1.0)
    assert stabilised(tilted, (0.0, 0.5)) is tilted
    assert lpvid.stability(stabilised(tilted), quadratic=False).margin == pytest.approx(1e-3)
    # Continuous time over two parameters: A(p) = -0.5 + 1.5 s1 + 0.2 s2 (unstable where
    # s1 > 1/3): shifted until stable on the box.
    basis = lpvid.Polynomial(1, domain=[(0.0, 1.0), (0.0, 1.0)])
    B = np.zeros((3, 1, 1))
    B[0] = 1.0
    ct = lpvid.LpvModel([[[-0.5]], [[1.5]], [[0.2]]], B, B.copy(), basis=basis)
    assert not lpvid.stability(ct, quadratic=False).stable
    rep = lpvid.stability(stabilised(ct), quadratic=False)
    assert rep.stable and rep.margin > 0


def test_judged_refit_without_validation_and_the_report_lines():
    from types import SimpleNamespace

    from lpvid.trust.steps import refit_line, trust_lines
    from lpvid.trust.support import judged_refit

    # B(1) = 1e-7 B(0) (relative 1e-7: dropped at the default 1e-6), A(1) = 0.5 A(0) on
    # [0, 1] but 2 over p_range (0, 4) of a domain-free basis: kept.
    one, zero = [[1.0]], [[0.0]]
    m = lpvid.LpvModel(
        [[[0.2]], [[0.05]]], [one, [[1e-7]]], [one, zero], None, lpvid.Polynomial(1), 1.0
    )
    judged = judged_refit(m, None, None, {"D": True}, p_range=(0.0, 1.0))
    assert judged.model is m and judged.fit is None and judged.kept is False
    assert judged.note == (
        "not refitted: without validation data nothing tells whether a refit on the support "
        "interpolates better (lpvid.refit runs it)"
    )
    want = lpvid.fixed_mask(m, {"D": True, "B": [1], "C": [1]})
    np.testing.assert_array_equal(judged.held, want)
    assert judged_refit(m, None, None, threshold=0.3, p_range=(0.0, 1.0)).held[1]  # A(1) 0.25
    assert not judged_refit(m, None, None, threshold=0.3, p_range=(0.0, 4.0)).held[1]  # 1.0
    entry = SimpleNamespace(vnls=120.0, validation_vnls=80.0)
    refitted = SimpleNamespace(vnls=110.0, validation_vnls=70.0)
    head = "refit on the support (dropped groups fixed at zero): V_NLS 120 -> 110"
    assert refit_line(entry, refitted, True) == head + "; validation V_NLS 80 -> 70; kept"
    alone = SimpleNamespace(vnls=110.0, validation_vnls=None)
    assert refit_line(entry, alone, False) == head + "; not kept, the path's model returned"
    assert refit_line(SimpleNamespace(vnls=120.0, validation_vnls=None), refitted, True) == (
        head + "; kept"
    )
    cov = SimpleNamespace(rank=7, n_unidentified=2)
    lines = trust_lines(entry, refitted, False, cov, None)
    assert lines[0].endswith("; not kept, the path's model returned")
    assert lines[1] == (
        "covariance: rank 7; 2 parameter direction(s) leave the FRF at every identification "
        "point unchanged (the data cannot tell them apart) and are left out: between the "
        "points the band may be too narrow"
    )
    assert trust_lines(entry, None, False, SimpleNamespace(rank=7, n_unidentified=0), None) == []


def test_judged_refit_keeps_the_refit_only_when_it_validates_better(peaked):
    # Against an independent run of the same steps: refit on the support to convergence, the
    # validation V_NLS before and after, kept only beyond REFIT_MARGIN.
    from lpvid.trust.support import REFIT_MARGIN, dropped_mask, judged_refit

    model = lpvid.fit_l21(_start(), peaked, 1e-3, fixed=FIXED).model
    val = lpvid.FrfData(P[1:3], peaked.freqs_hz, peaked.G[1:3], sigma=peaked.sigma[1:3], Ts=1.0)
    fit, held = lpvid.refit(model, peaked, FIXED, threshold=1e-3, p_range=(0.0, 1.0))
    assert fit.converged
    before, after = lpvid.vnls(model, val), lpvid.vnls(fit.model, val)
    change = f"validation V_NLS {before:.6g} -> {after:.6g}"
    judged = judged_refit(model, peaked, val, FIXED, threshold=1e-3, p_range=(0.0, 1.0))
    np.testing.assert_array_equal(judged.fit.model.theta, fit.model.theta)
    kept = after < (1 - REFIT_MARGIN) * before
    assert judged.kept is kept
    if kept:
        assert (
            judged.model is judged.fit.model
            and judged.note == f"refitted on the support ({change})"
        )
        np.testing.assert_array_equal(judged.held, held)
    else:
        assert judged.model is model
        assert judged.note == f"the refit on the support validated no better ({change}); not kept"
    # A validation V_NLS given for the model is the one compared with.
    worse = judged_refit(model, peaked, val, FIXED, validation_vnls=10 * after, threshold=1e-3)
    assert worse.kept and worse.model is worse.fit.model
    assert worse.note.startswith(f"refitted on the support (validation V_NLS {10 * after:.6g} ->")
    better = judged_refit(model, peaked, val, FIXED, validation_vnls=after, threshold=1e-3)
    assert not better.kept and better.model is model and better.fit is not None
    dropped = lpvid.fixed_mask(model, FIXED) | dropped_mask(model, 1e-3)
    np.testing.assert_array_equal(better.held, dropped)
    # A refit stopped at its step limit is not kept, even where it validates
    # better (told it validated ten times worse before), and its note says so.
    stopped = judged_refit(
        model,
        peaked,
        val,
        FIXED,
        validation_vnls=10 * before,
        threshold=1e-3,
        max_iter=1,
        ftol=0.0,
        xtol=0.0,
    )
    assert not stopped.fit.converged and stopped.fit.n_iter == 1
    after1 = lpvid.vnls(stopped.fit.model, val)
    assert after1 < (1 - REFIT_MARGIN) * 10 * before
    assert not stopped.kept and stopped.model is model
    np.testing.assert_array_equal(stopped.held, dropped)
    change = f"validation V_NLS {10 * before:.6g} -> {after1:.6g}"
    assert stopped.note == (
        "the refit on the support stopped at its step limit (1 steps), not converged "
        f"({change}): where it stopped follows the last bits; not kept"
    )


def test_refit_holds_the_groups_dropped_over_its_range_at_zero(peaked):
    # A(1) is 0.022 of A(0) over [0, 1] and 0.089 over [0, 4] (a domain-free basis); A(2) is
    # 1e-9 of it, small but not zero: the refit starts from zero there and holds it.
    from lpvid.trust.support import dropped_mask, judged_refit

    one = np.zeros((3, 1, 1))
    one[0] = 1.0
    m = lpvid.LpvModel([[[0.9]], [[0.02]], [[1e-9]]], 0.1 * one, one, basis=lpvid.Polynomial(2))
    m = lpvid.LpvModel(m.A, m.B, m.C, basis=m.basis, Ts=1.0)
    a1, only2 = lpvid.fixed_mask(m, {"A": [1]}), lpvid.fixed_mask(m, {"A": [2]})
    zero = lpvid.fixed_mask(m, {x: [1, 2] for x in "BCD"})  # the groups at zero
    a2 = only2 | zero
    np.testing.assert_array_equal(dropped_mask(m, 0.05, (0.0, 1.0)), a1 | a2)
    np.testing.assert_array_equal(dropped_mask(m, 0.05, (0.0, 4.0)), a2)
    at = m.group_norms((0.0, 1.0)).relative[0, 0]  # "at most": a group exactly at it is dropped
    np.testing.assert_array_equal(dropped_mask(m, at, (0.0, 1.0)), a1 | a2)
    np.testing.assert_array_equal(dropped_mask(m, np.nextafter(at, 0.0), (0.0, 1.0)), a2)
    with pytest.raises(ValueError, match=r"^threshold: expected a finite number > 0, got -1.0$"):
        dropped_mask(m, -1.0)
    # The default threshold is 1e-6 (A(2) at 1.1e-9 dropped, a group at 1e-5 kept).
    bigger = m.with_theta(np.where(only2, 1e-5, m.theta))
    np.testing.assert_array_equal(dropped_mask(bigger, p_range=(0.0, 1.0)), zero)
    np.testing.assert_array_equal(dropped_mask(m, p_range=(0.0, 1.0)), a2)
    lti = lpvid.LpvModel([[[0.5]]], [[[1.0]]], [[[1.0]]], Ts=1.0)
    none = dropped_mask(lti, 0.5)
    assert none.dtype == bool and none.shape == lti.theta.shape and not none.any()
    val = lpvid.FrfData(P[1:3], peaked.freqs_hz, peaked.G[1:3], sigma=peaked.sigma[1:3], Ts=1.0)
    for p_range, dropped in [((0.0, 1.0), a1 | a2), ((0.0, 4.0), a2)]:
        fit, held = lpvid.refit(m, peaked, FIXED, threshold=0.05, p_range=p_range)
        want = lpvid.fixed_mask(m, FIXED) | dropped
        np.testing.assert_array_equal(held, want)
        start = m.with_theta(np.where(dropped, 0.0, m.theta))
        alone = lpvid.fit_nls(start, peaked, want, p_range=p_range)
        np.testing.assert_array_equal(fit.model.theta, alone.model.theta)
        assert np.all(fit.model.theta[dropped] == 0.0)
        # judged_refit hands its range to the refit and says what it held.
        judged = judged_refit(m, peaked, val, FIXED, threshold=0.05, p_range=p_range)
        np.testing.assert_array_equal(judged.fit.model.theta, fit.model.theta)
        np.testing.assert_array_equal(judged.held, want)
