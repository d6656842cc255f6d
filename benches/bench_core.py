"""Timings of the lpvid core on a gantry-size problem.

Problem: n=6 states, l=2 outputs, r=1 input, Nb=4 basis functions, N=5
scheduling points, F=300 lines, discrete time. Prints medians over many
repetitions (the machines are shared and noisy: compare medians and ratios):

- one evaluation of residual, V_NLS, gradient and J^T J (and a numpy
  implementation with the full Jacobian, for the ratio);
- one Levenberg-Marquardt iteration and one SOCP step of the l2,1 fit, as
  timed inside the core during real fits (step, trial V_NLS, J^T J at the
  new point);
- the cone program alone (build and solve with Clarabel in Rust), and the
  same program written in cvxpy and solved with Clarabel from Python, the
  way a Python user would write it.

Run: python benches/bench_core.py [--repeat 200]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import lpvid
from lpvid import _core
from lpvid.fit.cost import build_problem


def gantry_size_problem(seed: int = 0) -> tuple[lpvid.LpvModel, lpvid.FrfData]:
    """A random stable model of gantry size and noisy FRF data of it."""
    rng = np.random.default_rng(seed)
    n, r, l, nb = 6, 1, 2, 4
    basis = lpvid.Polynomial(nb, domain=(24.0, 48.0))
    A = 0.05 * rng.normal(size=(nb + 1, n, n))
    A[0] += 0.6 * np.eye(n)
    model = lpvid.LpvModel(
        A,
        rng.normal(size=(nb + 1, n, r)),
        rng.normal(size=(nb + 1, l, n)),
        rng.normal(size=(nb + 1, l, r)),
        basis,
        Ts=1e-3,
    )
    p = np.array([24.0, 30.0, 36.0, 42.0, 48.0])
    f = np.linspace(50.0, 300.0, 300)
    G = model.frf(f, p)
    sigma = 0.01 * (np.abs(G) + 0.1)
    noise = sigma * (rng.normal(size=G.shape) + 1j * rng.normal(size=G.shape)) / np.sqrt(2)
    return model, lpvid.FrfData(p, f, G + noise, sigma, Ts=1e-3)


def median_time(fn, repeat: int) -> float:
    """Median wall time of ``fn()`` in seconds, after a warm-up call."""
    fn()
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def numpy_full_jacobian(model: lpvid.LpvModel, data: lpvid.FrfData):
    """Reference: residual, V_NLS, gradient and J^T J from the full Jacobian in numpy."""
    n, r, l, nb = model.shape
    psi = np.hstack([np.ones((data.n_points, 1)), model.basis(data.p)])
    z = data.z
    rows = []
    res = []
    for q in range(data.n_points):
        a, b, c, d = model.at(data.p[q])
        M = z[:, None, None] * np.eye(n) - a  # (F, n, n)
        X = np.linalg.solve(M, np.broadcast_to(b, (len(z), n, r)))  # (F, n, r)
        Y = np.linalg.solve(np.transpose(M, (0, 2, 1)), np.broadcast_to(c.T, (len(z), n, l)))
        Y = np.transpose(Y, (0, 2, 1))  # (F, l, n)
        G = c @ X + d
        w = 1.0 / data.sigma[q]
        e = (G - data.G[q]) * w
        # dG_jk/dA_ab = Y_ja X_bk ; vec column-major: index a + b n
        dA = np.einsum("fja,fbk->fjkba", Y, X).reshape(len(z), l, r, n * n)
        dB = np.einsum("fja,kc->fjkca", Y, np.eye(r)).reshape(len(z), l, r, n * r)
        dC = np.einsum("ja,fbk->fjkba", np.eye(l), X).reshape(len(z), l, r, l * n)
        dD = np.einsum("ja,kc->jkca", np.eye(l), np.eye(r)).reshape(1, l, r, l * r)
        dD = np.broadcast_to(dD, (len(z), l, r, l * r))
        Jq = np.concatenate([dA, dB, dC, dD], axis=-1) * w[..., None]
        parts = [
            np.concatenate([Jq[..., s] * psi[q, i] for i in range(nb + 1)], axis=-1)
            for s in _lti_slices(n, r, l)
        ]
        rows.append(np.concatenate(parts, axis=-1).reshape(-1, Jq.shape[-1] * (nb + 1)))
        res.append(e.ravel())
    Jc = np.concatenate(rows)
    rc = np.concatenate(res)
    J = np.concatenate([Jc.real, Jc.imag])
    rr = np.concatenate([rc.real, rc.imag])
    return rr @ rr, 2 * J.T @ rr, J.T @ J


def _lti_slices(n: int, r: int, l: int) -> list[slice]:
    sizes = [n * n, n * r, l * n, l * r]
    starts = np.cumsum([0, *sizes])
    return [slice(int(s), int(s + k)) for s, k in zip(starts[:-1], sizes, strict=True)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=200)
    args = parser.parse_args()
    model, data = gantry_size_problem()
    problem = build_problem(model, data)
    theta = model.theta
    t_core = median_time(lambda: problem.gauss_newton(theta), args.repeat)
    t_cost = median_time(lambda: problem.vnls(theta), args.repeat)
    v_np, g_np, h_np = numpy_full_jacobian(model, data)
    v, g, h = problem.gauss_newton(theta)
    h = h.reshape(g.size, g.size)
    assert np.isclose(v, v_np, rtol=1e-10)
    assert np.allclose(g, g_np, rtol=1e-8, atol=1e-8 * np.abs(g).max())
    assert np.allclose(h, h_np, rtol=1e-8, atol=1e-8 * np.abs(h).max())
    t_np = median_time(lambda: numpy_full_jacobian(model, data), max(5, args.repeat // 20))
    print("gantry-size problem: n=6, l=2, r=1, Nb=4, N=5, F=300, discrete time")
    print(f"  residual + V_NLS + gradient + J^T J (core) : {t_core * 1e3:8.3f} ms median")
    print(f"  residual + V_NLS only (core)               : {t_cost * 1e3:8.3f} ms median")
    print(f"  same with the full Jacobian in numpy        : {t_np * 1e3:8.3f} ms median")
    print(f"  ratio numpy / core                          : {t_np / t_core:8.1f} x")
    iteration_timings(model, data, problem, args.repeat)


def perturbed(model: lpvid.LpvModel, scale: float, seed: int = 1) -> lpvid.LpvModel:
    """The model with every parameter perturbed by ``scale`` (relative)."""
    rng = np.random.default_rng(seed)
    theta = model.theta
    return model.with_theta(theta * (1 + scale * rng.normal(size=theta.size)))


def cvxpy_cone_step(g, H, diag, mu, theta, groups, phi, varphi, gamma, m_res):
    """The cone program (27), written in cvxpy and solved with Clarabel."""
    import cvxpy as cp

    d = cp.Variable(g.size)
    P = 2.0 / m_res * (H + mu * np.diag(diag))
    penalty = sum(
        gamma * f * v * cp.norm(theta[sl] + d[sl], 2)
        for f, v, sl in zip(phi, varphi, groups, strict=True)
    )
    objective = g / m_res @ d + 0.5 * cp.quad_form(d, cp.psd_wrap(P)) + penalty
    problem = cp.Problem(cp.Minimize(objective))
    problem.solve(solver=cp.CLARABEL)
    return d.value


def iteration_timings(model, data, problem, repeat: int) -> None:
    """LM iteration, SOCP step, cone program alone, cvxpy comparison."""
    start = perturbed(model, 1e-3)
    nls = lpvid.fit_nls(start, data, max_iter=40, ftol=0.0, xtol=0.0)
    lm = np.median([h["seconds"] for h in nls.history])
    gamma = 1e-3
    reg = lpvid.fit_l21(nls.model, data, gamma, max_outer=4)
    socp = np.median([h["seconds"] for h in reg.history])
    print(f"  one LM iteration (in a fit, {nls.n_iter} iterations)  : {lm * 1e3:8.3f} ms median")
    print(f"  one SOCP step (in a fit, {reg.n_iter} steps)         : {socp * 1e3:8.3f} ms median")

    # The cone program alone: cone_step = J^T J at theta + build + solve.
    theta = nls.model.theta
    sup = model.basis.sup_norms((24.0, 48.0))
    mu = 1e-4
    settings = {"gamma": gamma}
    t_step = median_time(
        lambda: _core.cone_step(problem, theta, sup, None, settings, mu), max(10, repeat // 10)
    )
    t_gn = median_time(lambda: problem.gauss_newton(theta), repeat)
    t_cone = t_step - t_gn
    out = _core.cone_step(problem, theta, sup, None, settings, mu)
    v, g, h = problem.gauss_newton(theta)
    H = h.reshape(g.size, g.size)
    diag = np.maximum(np.diag(H), 1e-12 * np.diag(H).max())
    n, r, l, nb = model.shape
    groups, start_i = [], 0
    for size in (n * n, n * r, l * n, l * r):
        start_i += size
        for _ in range(nb):
            groups.append(slice(start_i, start_i + size))
            start_i += size
    args = (g, H, diag, mu, theta, groups, out.phi, out.varphi, gamma, data.n_residuals)
    t_cvx = median_time(lambda: cvxpy_cone_step(*args), 5)
    d_cvx = cvxpy_cone_step(*args)
    gap = np.linalg.norm(d_cvx - out.step) / np.linalg.norm(d_cvx)
    print(f"  cone program, build + solve (Rust Clarabel)  : {t_cone * 1e3:8.3f} ms median")
    print(f"  same program in cvxpy + Clarabel (Python)    : {t_cvx * 1e3:8.3f} ms median")
    print(f"  ratio cvxpy / core                          : {t_cvx / t_cone:8.1f} x")
    print(f"  relative difference of the two steps         : {gap:8.1e}")


if __name__ == "__main__":
    main()
