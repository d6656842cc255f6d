"""Levenberg-Marquardt and the reweighted l2,1 fit on a known LPV system.

The system: discrete time, 4 states, 2 inputs, 2 outputs; only A depends on
p, quadratically (A(p) = A0 + A1 p + A2 p^2); B, C and D are constant. FRF
data at 7 points with 1 % noise and known sigma. The start is the exact
cubic interpolation of its true local models, so that its groups B(i), C(i),
D(i) and A(3) are zero and the fit has to keep them so.
"""

import signal

import numpy as np
import pytest
from systems import heavily_damped, lti_frf

import lpvid

TS = 1e-3


def rotation(r, th):
    return r * np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])


def true_local(p):
    A0 = np.zeros((4, 4))
    A0[:2, :2] = rotation(0.93, 0.5)
    A0[2:, 2:] = rotation(0.88, 1.4)
    A1 = np.zeros((4, 4))
    A1[:2, :2] = [[0.0, -0.12], [0.12, 0.0]]
    A1[2:, 2:] = [[0.03, 0.1], [-0.1, 0.03]]
    A1[0, 2], A1[3, 1] = 0.05, -0.04
    A2 = np.zeros((4, 4))
    A2[:2, :2] = [[-0.03, 0.05], [-0.05, -0.03]]
    A2[2:, 2:] = [[0.02, -0.06], [0.06, 0.02]]
    B = np.array([[1.0, 0.0], [0.3, 0.5], [0.0, 1.0], [-0.4, 0.2]])
    C = np.array([[1.0, 0.2, 0.5, 0.0], [0.0, 0.7, -0.3, 1.0]])
    D = np.array([[0.1, 0.0], [0.05, -0.1]])
    return A0 + A1 * p + A2 * p**2, B, C, D


def interpolate(p, basis, locals_):
    """Least-squares interpolation of local matrices over the basis (exact here)."""
    psi = np.hstack([np.ones((len(p), 1)), basis(p)])
    out = []
    for k in range(4):
        stack = np.array([m[k] for m in locals_])
        coef = np.linalg.lstsq(psi, stack.reshape(len(p), -1), rcond=None)[0]
        out.append(coef.reshape(-1, *stack.shape[1:]))
    return lpvid.LpvModel(*out, basis=basis, Ts=TS)


@pytest.fixture(scope="module")
def case():
    p = np.linspace(0.0, 1.0, 7)
    basis = lpvid.Polynomial(3, domain=(0.0, 1.0))
    start = interpolate(p, basis, [true_local(q) for q in p])
    f = np.linspace(20.0, 400.0, 60)
    G = start.frf(f, p)
    sigma = 0.01 * np.abs(G) + 1e-3
    rng = np.random.default_rng(1)
    G = G + sigma * (rng.normal(size=G.shape) + 1j * rng.normal(size=G.shape)) / np.sqrt(2)
    data = lpvid.FrfData(p, f, G, sigma, Ts=TS)
    nls = lpvid.fit_nls(start, data)
    return start, data, nls


def test_start_has_the_true_structure(case):
    start, data, _ = case
    g = start.group_norms()
    assert g.nonzero(1e-12) == {"A": [1, 2], "B": [], "C": [], "D": []}
    assert abs(lpvid.vnls(start, data) - data.n_residuals) < 4 * np.sqrt(data.n_residuals)


def floor_after_fit(model, data):
    """Expected V_NLS at the least-squares fit: M less half the real parameters.

    Each of the M complex residuals contributes |e/sigma|^2 of mean 1 and
    variance 1, so V_NLS at the truth is M +- sqrt(M); fitting p real
    parameters removes p / 2 on average.
    """
    return data.n_residuals - model.theta.size / 2


def test_fit_nls_reaches_the_noise_floor(case):
    start, data, nls = case
    m = data.n_residuals
    # three standard deviations of the floor (seen: 2 below the expectation)
    assert abs(nls.vnls - floor_after_fit(start, data)) <= 3 * np.sqrt(m)
    assert nls.vnls < lpvid.vnls(start, data)
    assert nls.vnls == pytest.approx(lpvid.vnls(nls.model, data), rel=1e-12)
    assert nls.n_iter == len(nls.history) > 0
    assert all(h["kind"] == "lm" for h in nls.history)
    accepted = [h["vnls"] for h in nls.history if h["accepted"]]
    assert all(np.diff(accepted) < 0)
    assert nls.n_rejected == sum(not h["accepted"] for h in nls.history)
    assert nls.timings["lm_iter_s"] > 0 and np.isnan(nls.timings["socp_iter_s"])
    assert nls.timings["total_s"] >= nls.timings["lm_iter_s"]


def test_fit_nls_from_a_perturbed_start(case):
    start, data, nls = case
    rng = np.random.default_rng(5)
    theta = start.theta * (1 + 1e-2 * rng.normal(size=start.theta.size))
    far = start.with_theta(theta)
    assert lpvid.vnls(far, data) > 3 * data.n_residuals
    fit = lpvid.fit_nls(far, data, max_iter=200)
    assert abs(fit.vnls - floor_after_fit(start, data)) <= 3 * np.sqrt(data.n_residuals)
    # the same minimum as from the exact start (seen: 0.03 lower, sqrt(M) = 41)
    assert abs(fit.vnls - nls.vnls) <= 1.0


def test_fit_l21_finds_the_true_structure(case):
    _, data, nls = case
    reg = lpvid.fit_l21(nls.model, data, gamma=0.01)
    assert reg.converged, reg.message
    assert reg.nonzero_groups == {"A": [1, 2], "B": [], "C": [], "D": []}
    rel = reg.group_norms.relative
    assert np.all(rel[1:] < 1e-6)  # every B, C, D group
    assert rel[0, 2] < 1e-6  # the cubic A group
    assert reg.vnls <= 1.1 * nls.vnls
    assert reg.n_groups == 2
    assert all(h["kind"] == "socp" for h in reg.history)
    assert reg.timings["socp_iter_s"] > 0
    # the objective V_NLS / M + gamma sum phi varphi ||theta_g||, with phi the
    # final weights and varphi of (25) computed here from the fitted model
    assert reg.stop in ("weights", "settled")  # then the weights are those of the fit
    sup = reg.model.basis.sup_norms((0.0, 1.0))
    groups = [
        (np.linalg.norm(coef[i]), sup[i - 1] / np.linalg.norm(coef[0]))
        for coef in reg.model.matrices().values()
        for i in range(1, coef.shape[0])
    ]
    assert len(groups) == reg.weights.size == 12
    penalty = sum(
        phi * varphi * norm for phi, (norm, varphi) in zip(reg.weights, groups, strict=True)
    )
    expected = lpvid.vnls(reg.model, data) / data.n_residuals + 0.01 * penalty
    assert reg.objective == pytest.approx(expected, rel=1e-12)
    # phi of (23) at the fitted model, eps = 1e-3
    phi = [1.0 / (norm * varphi + 1e-3) for norm, varphi in groups]
    np.testing.assert_allclose(reg.weights, phi, rtol=1e-12)


def test_larger_gamma_never_keeps_more_groups(case):
    _, data, nls = case
    # from keeping noise-fitting groups to the true structure; V_NLS stays within
    # 10 % of the unregularised fit over this range
    counts = [lpvid.fit_l21(nls.model, data, g).n_groups for g in (1e-3, 3e-3, 1e-2, 3e-2, 0.1)]
    assert all(a >= b for a, b in zip(counts, counts[1:], strict=False)), counts
    assert counts[0] > counts[-1]


def test_small_gamma_cone_path_reaches_the_levenberg_marquardt_minimum(case):
    """At a small gamma > 0 the cone steps minimise V_NLS as LM does.

    From a start 470 above the minimum, both descend; the penalty can hold
    V_NLS above LM's by at most gamma M per group in use (each group costs at
    most about gamma in V_NLS / M with the relative weights): 0.2 here.
    """
    _, data, nls = case
    rng = np.random.default_rng(3)
    near = nls.model.with_theta(
        nls.model.theta * (1 + 1e-3 * rng.normal(size=nls.model.theta.size))
    )
    gamma, m = 1e-5, data.n_residuals
    lm = lpvid.fit_nls(near, data)
    reg = lpvid.fit_l21(near, data, gamma)
    explained = gamma * m * reg.weights.size
    assert lpvid.vnls(near, data) - lm.vnls > 1000 * explained
    assert reg.n_iter > 0 and all(h["kind"] == "socp" for h in reg.history)
    assert reg.converged, reg.message
    # not below LM's minimum (LM stopped at its iteration limit, 0.03 above
    # the cone path's point seen: its last steps crawl along a flat valley)
    assert reg.vnls >= min(lm.vnls, nls.vnls) - 0.1
    assert reg.vnls <= min(lm.vnls, nls.vnls) + explained


@pytest.fixture(scope="module")
def raw_case(case):
    """The same system and data with p scaled to [0, 2] and a basis without a domain.

    ``||psi_i||_inf`` = 2, 4, 8 on [0, 2], so the weighting rules (21), (22)
    and (23) differ.
    """
    _, data, _ = case
    q = 2 * data.p
    basis = lpvid.Polynomial(3)
    exact = interpolate(q, basis, [true_local(x / 2) for x in q])
    start = lpvid.LpvModel(*exact.matrices().values(), basis=basis, Ts=TS, p_range=(0.0, 2.0))
    raw = lpvid.FrfData(q, data.freqs_hz, data.G, data.sigma, Ts=TS)
    return start, raw, lpvid.fit_nls(start, raw)


@pytest.mark.parametrize("weights", ["relative", "scaled", "plain"])
def test_every_weighting_rule_finds_the_true_structure(raw_case, weights):
    start, data, nls = raw_case
    sup = start.basis.sup_norms((0.0, 2.0))
    np.testing.assert_allclose(sup, [2.0, 4.0, 8.0])
    assert start.group_norms().nonzero(1e-12) == {"A": [1, 2], "B": [], "C": [], "D": []}
    reg = lpvid.fit_l21(nls.model, data, 0.01, weights=weights)
    assert reg.converged and reg.stop in ("weights", "settled"), reg.message
    assert reg.nonzero_groups == {"A": [1, 2], "B": [], "C": [], "D": []}
    assert reg.vnls <= 1.02 * nls.vnls  # seen: 1.3 % above
    # the final weights are (21), (22) or (23) at the fitted model, eps = 1e-3
    phi = []
    for coef in reg.model.matrices().values():
        n0 = np.linalg.norm(coef[0])
        for i in range(1, coef.shape[0]):
            ni = np.linalg.norm(coef[i])
            phi.append(
                {
                    "plain": 1.0 / (ni + 1e-3),
                    "scaled": 1.0 / (ni * sup[i - 1] + 1e-3),
                    "relative": 1.0 / (ni * sup[i - 1] / n0 + 1e-3),
                }[weights]
            )
    np.testing.assert_allclose(reg.weights, phi, rtol=1e-12)


@pytest.fixture(scope="module")
def continuous():
    """A continuous-time system whose A is affine in p (heavily damped modes, D = 0).

    The start is the exact interpolation of its local models over a
    quadratic basis: the true structure is A(1) alone.
    """
    p = np.linspace(0.0, 1.0, 5)
    f = np.logspace(np.log10(2.0), np.log10(300.0), 60)
    rng = np.random.default_rng(2)

    def measured(points):
        G = np.array([lti_frf(heavily_damped(s), 2j * np.pi * f) for s in points])
        sigma = 0.01 * np.abs(G)
        G = G + sigma * (rng.normal(size=G.shape) + 1j * rng.normal(size=G.shape)) / np.sqrt(2)
        return lpvid.FrfData(points, f, G, sigma)

    basis = lpvid.Polynomial(2, domain=(0.0, 1.0))
    psi = np.hstack([np.ones((p.size, 1)), basis(p)])
    coef = []
    for k in range(4):
        stack = np.array([heavily_damped(s)[k] for s in p])
        c = np.linalg.lstsq(psi, stack.reshape(p.size, -1), rcond=None)[0]
        coef.append(c.reshape(-1, *stack.shape[1:]))
    start = lpvid.LpvModel(*coef, basis=basis, Ts=None)
    return start, measured(p), measured((p[1:] + p[:-1]) / 2)


def test_continuous_time_l21_fit_finds_the_true_structure(continuous):
    start, data, mid = continuous
    assert start.group_norms().nonzero(1e-10) == {"A": [1], "B": [], "C": [], "D": []}
    nls = lpvid.fit_nls(start, data, fixed={"D": True})
    reg = lpvid.fit_l21(nls.model, data, 0.1, fixed={"D": True})
    assert reg.model.Ts is None and not np.any(reg.model.D)
    assert reg.converged, reg.message
    assert reg.nonzero_groups == {"A": [1], "B": [], "C": [], "D": []}
    m, mv = data.n_residuals, mid.n_residuals
    # at the noise floor, on the points and between them (3 sigma of the floor)
    assert nls.vnls <= reg.vnls <= m + 3 * np.sqrt(m)
    assert lpvid.vnls(reg.model, mid) <= mv + 3 * np.sqrt(mv)


def test_fixed_parameters_never_move(case):
    start, data, _ = case
    fixed = {"D": True, "A": [0], "C": np.array([[True, False, False, False]] * 2)}
    mask = lpvid.fixed_mask(start, fixed)
    perturbed = start.with_theta(start.theta + 1e-4 * ~mask)
    # Few steps on purpose (only the fixed parameters matter here): no ConvergenceWarning.
    nls = lpvid.fit_nls(perturbed, data, fixed=fixed, max_iter=20, warn=False)
    reg = lpvid.fit_l21(nls.model, data, 0.01, fixed=fixed, max_outer=3, warn=False)
    for fit in (nls, reg):
        np.testing.assert_array_equal(fit.model.theta[mask], perturbed.theta[mask])
        assert np.any(fit.model.theta[~mask] != perturbed.theta[~mask])


def test_d_fixed_at_zero(case):
    start, data, _ = case
    zero_d = lpvid.LpvModel(start.A, start.B, start.C, np.zeros_like(start.D), start.basis, Ts=TS)
    nls = lpvid.fit_nls(zero_d, data, fixed={"D": True}, max_iter=30)
    reg = lpvid.fit_l21(nls.model, data, 0.01, fixed={"D": True})
    assert np.all(reg.model.D == 0)
    assert np.all(np.isfinite(reg.weights))
    # D's groups fall back to (22) and stay at zero: counted as removed
    assert reg.nonzero_groups["D"] == []
    assert np.isfinite(reg.vnls) and reg.vnls < lpvid.vnls(zero_d, data)


def test_gamma_path_is_warm_started_and_sorted(case):
    _, data, nls = case
    seen = []
    path = lpvid.l21_path(nls.model, data, [1e-3, 0.1, 1e-2], callback=seen.append)
    np.testing.assert_array_equal(path.gammas, [0.1, 1e-2, 1e-3])
    assert len(path) == 3 and len(seen) == sum(r.n_iter for r in path)
    assert all(a <= b for a, b in zip(path.n_groups, path.n_groups[1:], strict=False))
    assert path.vnls[0] >= path.vnls[-1]
    # warm start: the second fit continues from the first
    single = lpvid.fit_l21(path[0].model, data, 1e-2)
    np.testing.assert_array_equal(single.model.theta, path[1].model.theta)
    assert "gamma" in path.table() and str(path[0].n_groups) in path.table()


def test_callback_can_stop_the_fit(case):
    start, data, _ = case
    rows = []

    def stop_after_two(row):
        rows.append(row)
        return len(rows) < 2

    fit = lpvid.fit_nls(start, data, callback=stop_after_two)
    assert fit.interrupted and not fit.converged and fit.n_iter == 2 == len(rows)
    assert set(rows[0]) >= {"vnls", "objective", "step_norm", "lambda", "accepted", "status"}


def test_callback_errors_propagate(case):
    start, data, _ = case

    def broken(row):
        raise RuntimeError("boom")

    with pytest.raises(RuntimeError, match=r"^boom$"):
        lpvid.fit_l21(start, data, 0.01, callback=broken)


def test_ctrl_c_returns_the_best_model_so_far(case, python_sigint):
    start, data, _ = case
    calls = []

    def interrupt(row):
        calls.append(row)
        if len(calls) == 3:
            signal.raise_signal(signal.SIGINT)

    fit = lpvid.fit_nls(start, data, callback=interrupt)
    assert fit.interrupted and fit.stop == "keyboard_interrupt" and len(calls) == 3
    assert fit.vnls <= lpvid.vnls(start, data)
    assert fit.vnls == pytest.approx(lpvid.vnls(fit.model, data), rel=1e-12)


def test_a_start_whose_vnls_is_not_finite_is_refused(case):
    start, data, _ = case
    # |G| ~ 1e200 / sigma ~ 1e-3: every residual is finite, V_NLS overflows.
    huge = lpvid.LpvModel(start.A, start.B * 1e100, start.C * 1e100, start.D, start.basis, Ts=TS)
    assert np.all(np.isfinite(huge.frf(data.freqs_hz, data.p)))
    message = "model: V_NLS at the start is not finite"
    for fit in [
        lambda: lpvid.fit_nls(huge, data),
        lambda: lpvid.fit_l21(huge, data, gamma=0.1),
        lambda: lpvid.fit_l21(huge, data, gamma=0.0),
        lambda: lpvid.l21_path(huge, data, [0.1, 0.01]),
    ]:
        with pytest.raises(ValueError, match=message):
            fit()


@pytest.mark.parametrize(
    "kwargs, exc, match",
    [
        (dict(gamma=-1.0), ValueError, r"^gamma: expected a finite number >= 0"),
        (
            dict(gamma=0.1, weights="other"),
            ValueError,
            r"^weights: expected one of \('relative', 'scaled', 'plain'\)",
        ),
        (dict(gamma=0.1, eps=0.0), ValueError, r"^eps: expected a finite number > 0"),
        (dict(gamma=0.1, max_outer=0), ValueError, r"^max_outer: expected an integer >= 1"),
        (dict(gamma=0.1, callback=3), TypeError, r"^callback: expected a callable"),
        (dict(gamma="a"), TypeError, r"^gamma: expected a real number"),
        (
            dict(gamma=0.1, fixed={"Q": True}),
            ValueError,
            r"^fixed: unknown matrix name\(s\) \['Q'\]",
        ),
        (dict(gamma=0.1, epsilon=1e-3), TypeError, r"^epsilon: not a setting of the l2,1 fit"),
        (
            dict(gamma=0.1, settings={"eps": 1e-3}),
            TypeError,
            r"^settings: expected an L21Settings, got dict",
        ),
    ],
)
def test_bad_arguments(case, kwargs, exc, match):
    start, data, _ = case
    with pytest.raises(exc, match=match):
        lpvid.fit_l21(start, data, **kwargs)


def test_bad_nls_arguments(case):
    start, data, _ = case
    with pytest.raises(ValueError, match=r"^max_iter: expected an integer >= 1"):
        lpvid.fit_nls(start, data, max_iter=0)
    with pytest.raises(ValueError, match=r"^lambda0: expected a finite number > 0"):
        lpvid.fit_nls(start, data, lambda0=0.0)
    with pytest.raises(ValueError, match=r"^gammas: needs at least one value"):
        lpvid.l21_path(start, data, [])


@pytest.mark.parametrize("gamma", [1e6, 1e300])
def test_a_gamma_that_no_group_is_worth_returns_the_constant_model(case, gamma):
    """Every penalised group ends exactly at zero; V_NLS is that of the constant model."""
    start, data, nls = case
    reg = lpvid.fit_l21(nls.model, data, gamma, warn=False)
    assert reg.n_groups == 0
    for x in reg.model.matrices().values():
        assert np.all(x[1:] == 0.0)
    groups = {x: list(range(1, start.n_basis + 1)) for x in "ABCD"}
    mask = lpvid.fixed_mask(nls.model, groups)
    constant = lpvid.fit_nls(
        nls.model.with_theta(np.where(mask, 0.0, nls.model.theta)), data, mask, warn=False
    )
    # The l2,1 fit takes cone steps rather than LM steps on the constant part:
    # close to the constant model's optimum, and never below it.
    assert constant.vnls * (1 - 1e-9) <= reg.vnls <= 1.05 * constant.vnls
