"""One cone step (method.md (27)) from the core against cvxpy on the same problem."""

import numpy as np
import pytest

import lpvid
from lpvid import _core
from lpvid.fit.cost import build_problem, gauss_newton
from lpvid.testing import noisy_data, random_lpv


def weights_23(model, sup, eps):
    """phi and varphi of (23) and (25), written independently of the core."""
    phi, varphi = [], []
    for coef in model.matrices().values():
        n0 = np.linalg.norm(coef[0])
        for i in range(1, coef.shape[0]):
            ni = np.linalg.norm(coef[i])
            s = sup[i - 1]
            if n0 > 0:
                phi.append(1.0 / (ni * s / n0 + eps))
                varphi.append(s / n0)
            else:  # (22)
                phi.append(1.0 / (ni * s + eps))
                varphi.append(s)
    return np.array(phi), np.array(varphi)


def group_slices(model):
    out, start = [], 0
    for coef in model.matrices().values():
        k, rows, cols = coef.shape
        size = rows * cols
        start += size  # X(0)
        for _ in range(1, k):
            out.append(slice(start, start + size))
            start += size
    return out


@pytest.mark.parametrize("resting", [False, True])
@pytest.mark.parametrize("fixed", [None, {"D": True, "A": [0]}])
@pytest.mark.parametrize("gamma", [0.0, 0.05, 0.5])
def test_cone_step_matches_cvxpy(rng, gamma, fixed, resting):
    cp = pytest.importorskip("cvxpy")
    model = random_lpv(rng, n=2, r=1, l=2, nb=2, Ts=0.01)
    # The true B does not depend on p: a penalised step should zero its groups.
    B = model.B.copy()
    B[1:] = 0
    model = lpvid.LpvModel(model.A, B, model.C, model.D, model.basis, Ts=model.Ts)
    data = noisy_data(model, np.array([0.0, 0.5, 1.0]), np.linspace(1, 40, 8), rng)
    perturbation = 0.05 * rng.normal(size=model.theta.size)
    start = model.with_theta(model.theta + perturbation)
    B, C = start.B.copy(), start.C.copy()
    B[1:] = 1e-3 * rng.normal(size=B[1:].shape)
    if resting:
        # The groups of B and C exactly at zero: the step leaves them out of the
        # cone program and puts back those the solution needs (C depends on p).
        B[1:], C[1:] = 0.0, 0.0
    start = lpvid.LpvModel(start.A, B, C, start.D, start.basis, Ts=start.Ts)
    if fixed:
        # D(0) fixed at zero: its groups fall back to (22)
        D = start.D.copy()
        D[0] = 0
        start = lpvid.LpvModel(start.A, start.B, start.C, D, start.basis, Ts=start.Ts)
    free = lpvid.free_mask(start, fixed)
    sup = start.basis.sup_norms((0.0, 1.0))
    # With damping comparable to diag(J^T J) the subproblem is well conditioned,
    # so that its solution (not only its value) is determined to solver accuracy.
    eps, mu = 1e-3, 1.0
    theta = start.theta
    # Solved tighter than the default 1e-8 so that the comparison measures
    # the formulation, not the two solvers' stopping points.
    settings = {"gamma": gamma, "eps": eps, "cone_tol": 1e-10}
    out = _core.cone_step(build_problem(start, data), theta, sup, free, settings, mu)
    assert out.status in ("Solved", "AlmostSolved", "Solved (Newton)")
    phi, varphi = weights_23(start, sup, eps)
    if fixed:
        # A(0) and D(0) are fixed: (22) for their groups, whatever their value
        nb = start.n_basis
        for k, coef in ((0, start.A), (3, start.D)):
            groups = slice(k * nb, (k + 1) * nb)
            norms = np.array([np.linalg.norm(coef[i]) for i in range(1, nb + 1)])
            phi[groups] = 1.0 / (norms * sup + eps)
            varphi[groups] = sup
    np.testing.assert_allclose(out.phi, phi, rtol=1e-12)
    np.testing.assert_allclose(out.varphi, varphi, rtol=1e-12)

    # The same subproblem in cvxpy.
    _, g, H = gauss_newton(start, data, fixed)
    M = data.n_residuals
    D = np.maximum(np.diag(H), 1e-12 * np.diag(H).max())
    P = 2.0 / M * (H + mu * np.diag(D))
    # Solved in the Jacobi-scaled variable e = S d, S = sqrt(diag(P)), so
    # that the quadratic has unit diagonal: diag(P) spans 75..3.5e4 here, and
    # in the raw variable Clarabel stops at "AlmostSolved" (cvxpy 1.9 warns
    # "Solution may be inaccurate") before reaching 1e-11; scaled, it reaches it.
    scale = np.sqrt(np.diag(P))
    e = cp.Variable(g.size)
    d = e / scale
    idx = np.flatnonzero(free)
    expr_theta = []
    for sl in group_slices(start):
        parts = []
        for j in range(sl.start, sl.stop):
            pos = np.searchsorted(idx, j)
            if pos < idx.size and idx[pos] == j:
                parts.append(theta[j] + d[pos])
            else:
                parts.append(cp.Constant(theta[j]))
        expr_theta.append(cp.hstack(parts))
    penalty = sum(
        gamma * f * v * cp.norm(e, 2) for f, v, e in zip(phi, varphi, expr_theta, strict=True)
    )
    objective = g / M @ d + 0.5 * cp.quad_form(e, cp.psd_wrap(P / np.outer(scale, scale))) + penalty
    prob = cp.Problem(cp.Minimize(objective))
    # To the accuracy of the step under test (1e-10): at 1e-11 the reference
    # solve stops at "AlmostSolved" on one case or another as the last bits
    # of J^T J move (they did when its sums were reordered).
    prob.solve(
        solver=cp.CLARABEL, tol_gap_abs=1e-10, tol_gap_rel=1e-10, tol_feas=1e-10, max_iter=400
    )
    assert prob.status == "optimal"
    assert out.objective == pytest.approx(prob.value, rel=1e-6, abs=1e-9)
    step, reference = out.step, e.value / scale

    def objective_terms(d_free):  # the three terms of (27) at a step, written out in numpy
        full = theta.copy()
        full[idx] += d_free
        norms = [np.linalg.norm(full[sl]) for sl in group_slices(start)]
        return np.array([g / M @ d_free, 0.5 * d_free @ P @ d_free, gamma * phi * varphi @ norms])

    if resting:
        # Groups at the apex of their cones: the interior-point reference only
        # approaches the apex (its groups end near 1e-6, not at 0), the step
        # under test has them at zero and checked: at least as low an objective,
        # to the accuracy both were solved to (relative gap 1e-10 of the size
        # of the objective's terms; the objective is about -900 to -2000 here,
        # and the reference's value moves by 2e-9 with numpy's BLAS kernels),
        # and the same step to the reference's accuracy. A step that left out
        # the C groups the solution needs lies 750-2000 above.
        size = np.abs(objective_terms(reference)).sum()
        assert objective_terms(step).sum() <= objective_terms(reference).sum() + 1e-10 * size
        assert np.linalg.norm(step - reference) <= 1e-5 * np.linalg.norm(reference)
    else:
        assert np.linalg.norm(step - reference) <= 1e-6 * np.linalg.norm(reference)
    after = start.with_theta(theta + np.bincount(idx, step, minlength=theta.size))
    if resting and gamma < 0.5:
        # C's groups came back: the check after the solve put them in again
        assert all(np.linalg.norm(after.C[i]) > 1e-6 for i in range(1, start.n_basis + 1))
    if gamma >= 0.5 and fixed is None and not resting:
        # the B groups land on the apex of their cones: zero after the step
        assert all(np.linalg.norm(after.B[i]) < 1e-8 for i in range(1, start.n_basis + 1))


def test_zero_gamma_step_is_the_levenberg_marquardt_step(rng):
    model = random_lpv(rng, n=3, r=1, l=1, nb=1, Ts=0.01)
    data = noisy_data(model, np.array([0.0, 0.5, 1.0]), np.linspace(1, 40, 8), rng)
    start = model.with_theta(model.theta + 0.05 * rng.normal(size=model.theta.size))
    mu = 1e-3
    out = _core.cone_step(
        build_problem(start, data), start.theta, np.ones(1), None, {"gamma": 0.0}, mu
    )
    _, g, H = gauss_newton(start, data)
    D = np.maximum(np.diag(H), 1e-12 * np.diag(H).max())
    lm = np.linalg.solve(H + mu * np.diag(D), -0.5 * g)
    np.testing.assert_allclose(out.step, lm, rtol=1e-6, atol=1e-7 * np.linalg.norm(lm))
