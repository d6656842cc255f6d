"""Per-evaluation timings of the lpvid core on a gantry-size problem.

Problem: n=6 states, l=2 outputs, r=1 input, Nb=4 basis functions, N=5
scheduling points, F=300 lines, discrete time. Prints medians over many
repetitions (the machines are shared and noisy: compare medians and ratios).

Run: python benches/bench_core.py [--repeat 200]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import lpvid
from lpvid.cost import build_problem


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


if __name__ == "__main__":
    main()
