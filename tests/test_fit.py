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


def test_fit_nls_reaches_the_noise_floor(case):
    start, data, nls = case
    m = data.n_residuals
    assert abs(nls.vnls - m) <= 0.2 * m
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
    assert abs(fit.vnls - data.n_residuals) <= 0.2 * data.n_residuals


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
    assert reg.objective == pytest.approx(
        reg.vnls / data.n_residuals + reg.gamma * np.sum(1.0 / reg.weights[:2] * 0 + 1), rel=0.2
    )


def test_larger_gamma_never_keeps_more_groups(case):
    _, data, nls = case
    # from keeping noise-fitting groups to the true structure; V_NLS stays within
    # 10 % of the unregularised fit over this range
    counts = [lpvid.fit_l21(nls.model, data, g).n_groups for g in (1e-3, 3e-3, 1e-2, 3e-2, 0.1)]
    assert all(a >= b for a, b in zip(counts, counts[1:], strict=False)), counts
    assert counts[0] > counts[-1]


def test_zero_gamma_gives_the_nls_answer(case):
    start, data, nls = case
    reg = lpvid.fit_l21(start, data, gamma=0.0)
    np.testing.assert_array_equal(reg.model.theta, nls.model.theta)
    assert reg.vnls == nls.vnls


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

    with pytest.raises(RuntimeError, match="boom"):
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
    "kwargs, exc, name",
    [
        (dict(gamma=-1.0), ValueError, "gamma"),
        (dict(gamma=0.1, weights="other"), ValueError, "weights"),
        (dict(gamma=0.1, eps=0.0), ValueError, "eps"),
        (dict(gamma=0.1, max_outer=0), ValueError, "max_outer"),
        (dict(gamma=0.1, callback=3), TypeError, "callback"),
        (dict(gamma="a"), TypeError, "gamma"),
        (dict(gamma=0.1, fixed={"Q": True}), ValueError, "fixed"),
        (dict(gamma=0.1, epsilon=1e-3), TypeError, "epsilon"),
        (dict(gamma=0.1, settings={"eps": 1e-3}), TypeError, "settings"),
    ],
)
def test_bad_arguments(case, kwargs, exc, name):
    start, data, _ = case
    with pytest.raises(exc, match=name):
        lpvid.fit_l21(start, data, **kwargs)


def test_bad_nls_arguments(case):
    start, data, _ = case
    with pytest.raises(ValueError, match="max_iter"):
        lpvid.fit_nls(start, data, max_iter=0)
    with pytest.raises(ValueError, match="lambda0"):
        lpvid.fit_nls(start, data, lambda0=0.0)
    with pytest.raises(ValueError, match="gammas"):
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
