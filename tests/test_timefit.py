"""fit_time and the time-record cost: derivatives, a system that frozen FRFs
cannot tell from another, divergence, and fits on FRFs and records together."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import lpvid
from lpvid.fit.timecost import TimeCost, build_time_problem, check_time_data


def two_parameter_model(rng, Ts):
    """A random MIMO model (n=3, r=2, l=2) over two scheduling parameters."""
    basis = lpvid.Polynomial(1, domain=[(0.0, 1.0), (0.0, 1.0)])
    nb = len(basis)
    A = 0.15 * rng.normal(size=(nb + 1, 3, 3))
    A[0] += (0.4 if Ts is not None else -1.3) * np.eye(3)
    B, C, D = (0.5 * rng.normal(size=s) for s in [(nb + 1, 3, 2), (nb + 1, 2, 3), (nb + 1, 2, 2)])
    return lpvid.LpvModel(A, B, C, D, basis, Ts=Ts)


def records(rng, lens, dt):
    us = [rng.normal(size=(t, 2)) for t in lens]
    ps = [rng.uniform(size=(t, 2)) for t in lens]
    ys = [rng.normal(size=(t, 2)) for t in lens]
    sig = [0.5 + rng.uniform(size=(t, 2)) for t in lens]
    return lpvid.TimeData(us, ps, ys, dt=dt, sigma=sig)


def fd_columns(f, x, h=1e-6):
    """Central differences of the vector function f at x, one column per entry."""
    cols = []
    for i in range(x.size):
        step = h * max(1.0, abs(x[i]))
        up, down = x.copy(), x.copy()
        up[i] += step
        down[i] -= step
        cols.append((f(up) - f(down)) / (2 * step))
    return np.array(cols).T


@pytest.mark.parametrize("Ts", [0.1, None], ids=["discrete", "continuous"])
@pytest.mark.parametrize("x0", ["zero", "given", "estimate"])
def test_gradient_and_gauss_newton_match_central_differences(Ts, x0):
    rng = np.random.default_rng(3)
    model = two_parameter_model(rng, Ts)
    td = records(rng, [60, 35], dt=0.1)
    n = model.n_states
    x_given = rng.normal(size=(2, n))
    cost = TimeCost(td, x0=x_given if x0 == "given" else x0, skip=3)
    fixed = {"D": [0]}
    free = lpvid.free_mask(model, fixed)
    v, g, h, stages = build_time_problem(model, cost).gauss_newton(model.theta, free)
    assert v == pytest.approx(lpvid.time_vnls(model, cost), rel=1e-12)
    assert stages["total_s"] >= stages["gram_s"] >= 0
    theta = model.theta
    idx = np.flatnonzero(free)

    def cost_at(t_free):
        t = theta.copy()
        t[idx] = t_free
        return np.array([lpvid.time_vnls(model.with_theta(t), cost)])

    fd_g = fd_columns(cost_at, theta[idx])[0]
    np.testing.assert_allclose(g, fd_g, rtol=0, atol=2e-6 * np.abs(g).max())
    # J^T J from the explicit Jacobian of the residual at the initial states
    # used (for estimated ones: over theta and x0, then the Schur complement).
    x_used = lpvid.initial_states(model, td, skip=3) if x0 == "estimate" else cost.x0_values(n)
    if x0 == "zero":
        x_used = np.zeros((2, n))

    def residual(t_free, xs=x_used):
        t = theta.copy()
        t[idx] = t_free
        return np.concatenate(lpvid.time_residual(model.with_theta(t), td, x0=xs, skip=3)).ravel()

    J = fd_columns(residual, theta[idx])
    want = J.T @ J
    if x0 == "estimate":
        Jx = fd_columns(lambda xs: residual(theta[idx], xs.reshape(2, n)), x_used.ravel())
        want = want - J.T @ Jx @ np.linalg.solve(Jx.T @ Jx, Jx.T @ J)
    m = idx.size
    np.testing.assert_allclose(h.reshape(m, m), want, rtol=0, atol=2e-6 * np.abs(want).max())


@pytest.mark.parametrize("Ts", [0.1, None], ids=["discrete", "continuous"])
def test_the_cost_weights_every_output_and_sample_by_its_own_sigma(Ts):
    # Against the simulation from rest, weighted here: sigma differs per output and sample.
    rng = np.random.default_rng(5)
    model = two_parameter_model(rng, Ts)
    td = records(rng, [40, 25, 30], dt=0.1)
    cost = TimeCost(td, x0="zero", skip=4)
    each = zip(td.u, td.p, td.y, td.sigma, strict=True)
    want = [((model.simulate(u, p, dt=0.1) - y) / s)[4:] for u, p, y, s in each]
    got = lpvid.time_residual(model, cost)
    for g, w in zip(got, want, strict=True):
        np.testing.assert_allclose(g, w, rtol=1e-10, atol=1e-12 * np.abs(w).max())
    total = sum(float(np.sum(w**2)) for w in want)
    assert lpvid.time_vnls(model, cost) == pytest.approx(total, rel=1e-10)


def test_fit_time_follows_sigma_per_output_and_per_sample():
    # y1 is precise except in a burst where sigma (and the noise) is 300 times larger;
    # y2 is noisy throughout. Weighted by sigma, the fit recovers A and B to 3e-4 (their standard
    # errors are about 5e-5); unweighted, the burst and y2 pull them ten times further off.
    rng = np.random.default_rng(2)
    T = 600
    basis = lpvid.Polynomial(1, domain=(0.0, 1.0))
    one, zero = [[1.0]], [[0.0]]
    true = lpvid.LpvModel(
        [[[0.8]], [[0.1]]], [one, zero], [[[1.0], [0.5]], [[0.0], [0.0]]], None, basis, 1.0
    )
    u, p = rng.normal(size=T), rng.uniform(size=T)
    sigma = np.tile([1e-3, 0.3], (T, 1))
    sigma[200:350, 0] = 0.3
    y = true.simulate(u, p) + sigma * rng.normal(size=(T, 2))
    fixed = {"C": True, "D": True}
    start = lpvid.LpvModel(0.95 * true.A, 0.95 * true.B, true.C, None, basis, 1.0)
    weighted = lpvid.fit_time(start, lpvid.TimeData(u, p, y, 1.0, sigma), x0="zero", fixed=fixed)
    plain = lpvid.fit_time(start, lpvid.TimeData(u, p, y, 1.0), x0="zero", fixed=fixed)
    free = lpvid.free_mask(true, fixed)
    err_w = np.abs(weighted.model.theta - true.theta)[free].max()
    err_p = np.abs(plain.model.theta - true.theta)[free].max()
    assert 0.85 < weighted.vnls / weighted.noise_floor < 1.15
    assert err_w < 3e-4 and err_p > 10 * err_w


def test_fit_time_options_reach_the_cost():
    # x0 and skip given to fit_time, or carried by a TimeCost, are the cost that is
    # minimised: the fitted vnls is time_vnls of the fitted model with the same options.
    rng = np.random.default_rng(7)
    T = 300
    basis = lpvid.Polynomial(1, domain=(0.0, 1.0))
    one, zero = [[1.0]], [[0.0]]
    true = lpvid.LpvModel([[[0.9]], [[0.05]]], [one, zero], [one, zero], None, basis, 1.0)
    u, p = rng.normal(size=T), rng.uniform(size=T)
    y = true.simulate(u, p, x0=[5.0]) + 0.01 * rng.normal(size=(T, 1))
    td = lpvid.TimeData(u, p, y, 1.0, 0.01)
    start = true.with_theta(true.theta * 0.97)
    fixed = {"C": True, "D": True}
    for x0, skip in [("zero", 0), ("zero", 40), ([5.0], 0), ("estimate", 0)]:
        fit = lpvid.fit_time(start, td, x0=x0, skip=skip, fixed=fixed)
        again = lpvid.fit_time(start, TimeCost(td, x0=x0, skip=skip), fixed=fixed)
        np.testing.assert_array_equal(again.model.theta, fit.model.theta)
        assert fit.noise_floor == T - skip
        want = lpvid.time_vnls(fit.model, td, x0=x0, skip=skip)
        assert fit.vnls == pytest.approx(want, rel=1e-9)
    # From rest, the response to x(0) = 5 is a misfit until it has died out (0.9^40 ~ 1 %).
    assert lpvid.time_vnls(true, td, x0="zero") > 100 * lpvid.time_vnls(true, td, x0=[5.0])
    with pytest.raises(ValueError, match=r"^x0, skip: a TimeCost carries its own"):
        lpvid.fit_time(start, TimeCost(td), x0="zero")
    with pytest.raises(ValueError, match=r"^gamma: expected a finite number >= 0, got -1"):
        lpvid.fit_time(start, td, gamma=-1.0)
    with pytest.warns(lpvid.ConvergenceWarning, match=r"^fit_time stopped at its iteration"):
        lpvid.fit_time(true.with_theta(true.theta * 0.5), td, max_iter=4, lambda0=10.0)


def test_fit_time_l21_settings_range_and_callback():
    # gamma 3e-3, not the core's default 1e-3. A basis without a domain: the group norms
    # are taken over the range the records visit, or over the p_range given; settings and
    # callbacks reach the fit.
    rng = np.random.default_rng(8)
    T = 300
    basis = lpvid.Polynomial(1)
    one, zero = [[1.0]], [[0.0]]
    true = lpvid.LpvModel([[[0.8]], [[0.1]]], [one, zero], [one, zero], None, basis, 1.0)
    p = 0.2 + 0.5 * rng.uniform(size=T)
    u = rng.normal(size=T)
    td = lpvid.TimeData(u, p, true.simulate(u, p) + 0.01 * rng.normal(size=(T, 1)), 1.0, 0.01)
    start = true.with_theta(true.theta * 0.97)
    kw = dict(x0="zero", fixed={"C": True, "D": True})
    seen = []
    fit = lpvid.fit_time(start, td, gamma=3e-3, callback=seen.append, **kw)
    assert seen and len(seen) == len(fit.history)
    np.testing.assert_array_equal(fit.model.C, start.C)  # fixed
    assert not np.array_equal(fit.model.B, start.B)
    assert fit.objective > fit.vnls / fit.noise_floor * (1 + 1e-4)  # the penalty counts
    less = lpvid.fit_time(start, td, gamma=1e-3, **kw)  # less shrinkage: another fit
    assert not np.allclose(less.model.theta, fit.model.theta, rtol=1e-6, atol=0)
    visited = (float(p.min()), float(p.max()))
    np.testing.assert_allclose(fit.group_norms.relative, fit.model.group_norms(visited).relative)
    wide = lpvid.fit_time(start, td, gamma=3e-3, p_range=(0.0, 2.0), **kw)
    want = wide.model.group_norms((0.0, 2.0)).relative  # ||psi_1||_inf = 2, not 0.7
    np.testing.assert_allclose(wide.group_norms.relative, want)
    assert not np.allclose(want, wide.model.group_norms(visited).relative)
    # A model with a range of its own: the group norms over that range.
    ranged = lpvid.LpvModel(
        start.A, start.B, start.C, None, lpvid.Polynomial(1, domain=(0, 2)), 1.0
    )
    own = lpvid.fit_time(ranged, td, gamma=3e-3, **kw)
    np.testing.assert_allclose(own.group_norms.relative, own.model.group_norms().relative)
    assert not np.allclose(own.group_norms.relative, own.model.group_norms(visited).relative)
    limit = r"^fit_time \(gamma = 0\.003\) stopped at its iteration limit"
    with pytest.warns(lpvid.ConvergenceWarning, match=limit):
        short = lpvid.fit_time(start, td, gamma=3e-3, settings=lpvid.L21Settings(max_outer=1), **kw)
    assert short.outer_iterations == 1 < fit.outer_iterations
    with pytest.warns(lpvid.ConvergenceWarning, match=limit):
        assert lpvid.fit_time(start, td, gamma=3e-3, max_outer=1, **kw).outer_iterations == 1
    nls = lpvid.fit_time(start, td, callback=lambda row: False, **kw)
    assert nls.interrupted and nls.n_iter == 1
    l21 = lpvid.fit_time(start, td, gamma=3e-3, callback=lambda row: False, **kw)
    assert l21.interrupted and len(l21.history) == 1


# ---------------------------------------------------------------- a known system
BASIS = lpvid.Polynomial(3)
E = np.array([[0.0, 1.0], [0.0, 0.0]])  # E @ E = 0: (I + p E)^-1 = I - p E


def poly_mul(P, Q):
    """Product of two matrix polynomials in p, coefficient lists."""
    out = [np.zeros((P[0].shape[0], Q[0].shape[1])) for _ in range(len(P) + len(Q) - 1)]
    for i, a in enumerate(P):
        for j, b in enumerate(Q):
            out[i + j] = out[i + j] + a @ b
    return out


def pad(coefs, k=4):
    return list(coefs) + [np.zeros_like(coefs[0])] * (k - len(coefs))


def known_pair(Ts):
    """A two-state LPV system and its state transform by T(p) = I + p E.

    ``T(p) A(p) T(p)^-1``, ``T(p) B(p)``, ``C(p) T(p)^-1`` are cubic in p, so
    both models live in a cubic polynomial basis. Frozen at any p they are the
    same system; along a moving p they differ.
    """
    A = [np.array([[0.6, 0.3], [-0.3, 0.5]]), np.array([[0.2, 0.0], [0.1, -0.2]])]
    if Ts is None:
        A = [40.0 * (A[0] - np.eye(2)), 40.0 * A[1]]
    B = [np.array([[1.0], [0.5]]), np.array([[0.3], [0.0]])]
    if Ts is None:  # states of the size of the outputs' noise and more
        B = [40.0 * b for b in B]
    C = [np.array([[1.0, 0.0], [0.2, 1.0]]), np.array([[0.0, 0.3], [0.0, 0.0]])]
    D = [np.zeros((2, 1))]
    T, Ti = [np.eye(2), E], [np.eye(2), -E]
    kw = dict(basis=BASIS, Ts=Ts, p_range=(0.0, 1.0))
    true = lpvid.LpvModel(pad(A), pad(B), pad(C), pad(D), **kw)
    moved = lpvid.LpvModel(
        pad(poly_mul(poly_mul(T, A), Ti)), pad(poly_mul(T, B)), pad(poly_mul(C, Ti)), pad(D), **kw
    )
    return true, moved


def record(model, seed, fast, T=2000, sigma=0.01):
    rng = np.random.default_rng(seed)
    u = rng.normal(size=T)
    t = np.arange(T)
    p = rng.uniform(size=T) if fast else 0.5 - 0.5 * np.cos(2 * np.pi * t / T)
    dt = 0.005 if model.Ts is None else model.Ts
    y = model.simulate(u, p, dt=dt) + sigma * rng.normal(size=(T, 2))
    return lpvid.TimeData(u, p, y, dt=dt, sigma=sigma)


@pytest.mark.parametrize("Ts", [1.0, None], ids=["discrete", "continuous"])
def test_a_fast_record_tells_apart_what_frozen_frfs_cannot(Ts):
    true, moved = known_pair(Ts)
    # Frozen FRFs: the same, so V_NLS on noisy FRF data is the same at the floor.
    freqs = np.linspace(0.01, 0.45, 40) if Ts else np.linspace(0.5, 40.0, 40)
    p = np.linspace(0.0, 1.0, 5)
    G = true.frf(freqs, p)
    noise = np.random.default_rng(0).normal(size=G.shape + (2,)) @ [1.0, 1j] * 0.01 / np.sqrt(2)
    data = lpvid.FrfData(p, freqs, G + noise, sigma=0.01, Ts=Ts)
    v_true, v_moved = lpvid.vnls(true, data), lpvid.vnls(moved, data)
    assert v_true == pytest.approx(v_moved, rel=1e-6)
    assert 0.8 < v_true / data.n_residuals < 1.2
    # Along a fast trajectory the moved model is far off; fit_time fixes it.
    fast, fresh = record(true, 1, True), record(true, 2, True)
    floor = fresh.n_residuals
    assert lpvid.time_vnls(true, fresh) / floor < 1.1
    assert lpvid.time_vnls(moved, fresh) / floor > 20
    fit = lpvid.fit_time(moved, fast)
    assert fit.converged and fit.noise_floor == fast.n_residuals
    assert lpvid.time_vnls(fit.model, fresh) / floor < 1.1
    # Along a slow trajectory both models agree with the data.
    slow = record(true, 3, False)
    for model in (true, moved):
        assert lpvid.time_vnls(model, slow) / slow.n_residuals < 1.1


def test_diverging_models_are_errors_and_rejected_steps():
    rng = np.random.default_rng(0)
    T = 3000
    basis = lpvid.Polynomial(1, domain=(0.0, 1.0))

    def scalar(a):
        one, zero = [[1.0]], [[0.0]]
        return lpvid.LpvModel([[[a]], [[0.02]]], [one, zero], [one, zero], None, basis, 1.0)

    u, p = rng.normal(size=T), rng.uniform(size=T)
    y = scalar(0.97).simulate(u, p) + 0.1 * rng.normal(size=(T, 1))
    td = lpvid.TimeData(u, p, y, dt=1.0, sigma=0.1)
    for a in (1.2, 3.0):  # large but finite, and beyond the floating-point range
        with pytest.raises(ValueError, match=r"^model: diverges along time record 0: .* sample"):
            lpvid.fit_time(scalar(a), td)
        with pytest.raises(ValueError, match=r"^model: diverges"):
            lpvid.time_vnls(scalar(a), td)
    # From a=0.3 with little damping the first steps overshoot past a = 1:
    # rejected, and the fit still ends at the noise floor, every number finite.
    fit = lpvid.fit_time(scalar(0.3), td, x0="zero", lambda0=1e-8)
    assert fit.n_rejected > 0
    assert all(np.isfinite(row["vnls"]) for row in fit.history)
    assert 0.9 < fit.vnls / fit.noise_floor < 1.1


def test_records_that_do_not_fit_the_model_are_named():
    true, _ = known_pair(1.0)
    td = record(true, 1, True, T=100)
    with pytest.raises(ValueError, match=r"^time_data: sample time dt=0.5 s differs"):
        lpvid.fit_time(true, lpvid.TimeData(td.u[0], td.p[0], td.y[0], dt=0.5))
    with pytest.raises(ValueError, match=r"^time_data: has 1 outputs x 1 inputs"):
        lpvid.fit_time(true, lpvid.TimeData(td.u[0], td.p[0], td.y[0][:, 0], dt=1.0))
    with pytest.warns(UserWarning, match=r"^time_data: record 0 leaves the model's scheduling"):
        lpvid.time_vnls(true, lpvid.TimeData(td.u[0], 1.5 * td.p[0], td.y[0], dt=1.0))
    with pytest.raises(
        ValueError,
        match=r"^max_iter: limits the Levenberg-Marquardt fit \(gamma = 0\); with gamma > 0 set "
        r"max_outer and max_inner \(L21Settings\)$",
    ):
        lpvid.fit_time(true, td, gamma=1e-3, max_iter=5)
    with pytest.raises(ValueError, match=r"^settings: the l2,1 settings apply"):
        lpvid.fit_time(true, td, settings=lpvid.L21Settings())
    with pytest.raises(TypeError, match=r"^eps: not a setting of the Levenberg-Marquardt"):
        lpvid.fit_time(true, td, eps=1e-3)
    with pytest.raises(ValueError, match=r"^x0, skip: a TimeCost carries its own"):
        lpvid.fit_time(true, TimeCost(td), skip=3)
    with pytest.raises(TypeError, match=r"^time_data: expected a TimeData"):
        lpvid.fit_time(true, np.ones(3))


def test_time_records_against_frf_data_and_defaults():
    true, _ = known_pair(1.0)
    td = record(true, 1, True, T=60)
    # The defaults of the helpers are those of a plain TimeCost (x0 estimated, skip 0).
    cost = TimeCost(td)
    np.testing.assert_array_equal(lpvid.initial_states(true, td), lpvid.initial_states(true, cost))
    for a, b in zip(lpvid.time_residual(true, td), lpvid.time_residual(true, cost), strict=True):
        np.testing.assert_array_equal(a, b)
    with pytest.raises(TypeError, match=r"^model: expected an LpvModel, got str$"):
        lpvid.time_vnls("model", td)
    two = lpvid.TimeData(td.u[0], np.column_stack([td.p[0], td.p[0]]), td.y[0], dt=1.0)
    with pytest.raises(
        ValueError, match=r"^time_data: has 2 scheduling parameter\(s\), the model's basis takes 1$"
    ):
        lpvid.time_vnls(true, two)
    f = np.linspace(0.01, 0.4, 5)
    frf = lpvid.FrfData([0.2, 0.8], f, true.frf(f, [0.2, 0.8]), Ts=1.0)
    one_out = lpvid.TimeData(td.u[0], td.p[0], td.y[0][:, 0], dt=1.0)
    with pytest.raises(
        ValueError,
        match=r"^time_data: 1 outputs, 1 inputs and 1 scheduling parameter\(s\), the FRF data "
        r"2, 1 and 1$",
    ):
        check_time_data(frf, one_out)
    slow = lpvid.TimeData(td.u[0], td.p[0], td.y[0], dt=0.5)
    with pytest.raises(
        ValueError,
        match=r"^time_data: sample time dt=0.5 s differs from the FRF data's Ts=1 s \(a "
        r"discrete-time model runs at one sample time\)$",
    ):
        check_time_data(frf, slow)


def test_records_leaving_the_range_warn_beyond_a_relative_1e9():
    one, zero = [[1.0]], [[0.0]]

    def leaves(lo, hi, top, bottom=None):
        basis = lpvid.Polynomial(1, domain=(lo, hi))
        m = lpvid.LpvModel([[[0.5]], [[0.1]]], [one, zero], [one, zero], None, basis, 1.0)
        p = np.linspace(lo + 0.1 * (hi - lo) if bottom is None else bottom, top, 20)
        td = lpvid.TimeData(np.ones(20), p, np.zeros(20), dt=1.0)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            lpvid.time_vnls(m, td, x0="zero")
        return [str(w.message) for w in caught]

    # The slack is 1e-9 times the width of the range (at least 1e-9).
    assert leaves(1.0, 3.0, 3.0 + 1e-9) == [] and leaves(0.0, 0.5, 0.5 + 0.9e-9) == []
    assert len(leaves(1.0, 3.0, 3.0 + 3e-9)) == 1 and len(leaves(0.0, 0.5, 0.5 + 1.5e-9)) == 1
    assert len(leaves(2.0, 3.0, 3.0, bottom=2.0 - 3e-9)) == 1  # below the range too
    assert leaves(0.0, 1.0, 1.5) == [
        "time_data: record 0 leaves the model's scheduling range [0.0, 1.0] (it spans [0.1] to "
        "[1.5]); the basis functions extrapolate there"
    ]


def test_l21_on_time_records_drops_a_spurious_group():
    true, _ = known_pair(1.0)
    fast = record(true, 4, True, T=1500)
    # The true system has no B dependence on p^2: add some and let l2,1 remove it.
    B = true.B.copy()
    B[2] = [[0.05], [-0.03]]
    start = lpvid.LpvModel(true.A, B, true.C, true.D, BASIS, Ts=1.0, p_range=(0.0, 1.0))
    fit = lpvid.fit_time(start, fast, gamma=1e-3, fixed={"D": True})
    assert isinstance(fit, lpvid.L21Result)
    assert 2 not in fit.nonzero_groups["B"]
    assert fit.vnls / fit.noise_floor < 1.1


def test_frf_data_and_time_records_together():
    true, moved = known_pair(1.0)
    freqs, p = np.linspace(0.01, 0.45, 30), np.linspace(0.0, 1.0, 5)
    G = true.frf(freqs, p)
    data = lpvid.FrfData(p, freqs, G, sigma=0.01, Ts=1.0)
    fast, fresh = record(true, 5, True, T=1500), record(true, 6, True, T=1500)
    frf_problem = lpvid.fit.cost.build_problem(moved, data)
    time_problem = build_time_problem(moved, fast)
    both = lpvid._core.SumProblem(frf_problem, time_problem)
    assert both.n_residuals == data.n_residuals + fast.n_residuals
    v, g, h = both.gauss_newton(moved.theta)
    parts = [frf_problem.gauss_newton(moved.theta), time_problem.gauss_newton(moved.theta)]
    assert v == pytest.approx(parts[0][0] + parts[1][0], rel=1e-12)
    # The sum is formed in another order: rounding of the size of the largest
    # entries (|h| up to 2e8 here, 7e-9 apart), not of each entry.
    for k in (1, 2):
        total = parts[0][k] + parts[1][k]
        np.testing.assert_allclose((g, h)[k - 1], total, rtol=0, atol=1e-12 * np.abs(total).max())
    fit = lpvid.fit_nls(moved, data, time_data=fast)
    assert fit.noise_floor == data.n_residuals + fast.n_residuals
    total = lpvid.vnls(fit.model, data) + lpvid.time_vnls(fit.model, fast)
    assert fit.vnls == pytest.approx(total, rel=1e-9)
    assert lpvid.time_vnls(fit.model, fresh) / fresh.n_residuals < 1.1
    reg = lpvid.fit_l21(moved, data, 1e-3, time_data=TimeCost(fast, x0="estimate", skip=10))
    assert reg.noise_floor == data.n_residuals + fast.n_residuals - 10 * 2


def test_identify_finishes_on_time_records():
    true, _ = known_pair(1.0)
    freqs, p = np.linspace(0.01, 0.45, 40), np.linspace(0.0, 1.0, 5)
    G = true.frf(freqs, p)
    rng = np.random.default_rng(7)
    noise = (rng.normal(size=G.shape) + 1j * rng.normal(size=G.shape)) * 0.01 / np.sqrt(2)
    data = lpvid.FrfData(p, freqs, G + noise, sigma=0.01, Ts=1.0)
    fast, fresh = record(true, 8, True, T=1500), record(true, 9, True, T=1500)
    with pytest.raises(ValueError, match=r"^time_data: sample time dt=2 s differs from the FRF"):
        lpvid.identify(data, 2, BASIS, time_data=lpvid.TimeData(fast.u, fast.p, fast.y, dt=2.0))
    result = lpvid.identify(data, 2, BASIS, gammas=[1e-2, 1e-3], time_data=fast)
    assert isinstance(result.time_data, TimeCost) and result.time_data.data is fast
    floor = data.n_residuals + fast.n_residuals
    assert all(e.noise_floor == floor for e in result.entries)
    e = result.entry
    total = lpvid.vnls(e.model, data) + lpvid.time_vnls(e.model, fast)
    assert e.vnls == pytest.approx(total, rel=1e-9)
    assert e.vnls / floor < 1.1
    assert lpvid.time_vnls(result.model, fresh) / fresh.n_residuals < 1.1
    assert "time record" in result.summary()
    # The FRFs alone fit as well but cannot see the dynamic dependence on p.
    frf_only = lpvid.identify(data, 2, BASIS, gammas=[1e-2, 1e-3]).model
    assert lpvid.vnls(frf_only, data) / data.n_residuals < 1.1
    assert lpvid.time_vnls(frf_only, fresh) / fresh.n_residuals > 20
