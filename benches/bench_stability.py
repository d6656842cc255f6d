"""Stability certificates on a box of several parameters: time of each part, median of runs.

A continuous-time model with ``n`` states whose ``A(p)`` is a quadratic
polynomial (``lpvid.Polynomial(2)``) of ``Np`` parameters: rotating 2 x 2 blocks
(frozen-stable, not quadratically stable), coupled weakly. For each case it prints
the median seconds of:

- ``scan``: ``lpvid.stability(model, quadratic=False)`` (the frozen models on a grid);
- ``quadratic``: the sum of squares on the box with a common ``P`` (and the grid
  program when it does not certify);
- ``rate``: one bounded-rate program (``lpvid.rate_stability``, ``P(p)`` of degree 2,
  ``2^Np`` rate vertices);
- ``max_rate``: the bisection (``lpvid.max_rate``), with its number of programs;

and the programs' sizes (largest block, blocks, equations, estimated memory).

Run: python benches/bench_stability.py [--n 8] [--params 2] [--runs 3]
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

import lpvid
from lpvid.stable.boxsos import program_size
from lpvid.stable.multi import model_quadratic
from lpvid.stable.ranges import polynomial_A


def model(n: int, n_params: int, seed: int = 0) -> lpvid.LpvModel:
    """Rotating 2 x 2 blocks (tests/rate_systems.py) coupled weakly, quadratic in ``p``.

    Frozen-stable, not quadratically stable (each block is unstable under a fast
    enough rotation of its parameters), so every part of the check runs.
    """
    rng = np.random.default_rng(seed)
    basis = lpvid.Polynomial(2, domain=[(0.0, 1.0)] * n_params)
    J = np.array([[0.0, -1.0], [1.0, 0.0]])
    E = [np.diag([1.0, -1.0]), np.array([[0.0, 1.0], [1.0, 0.0]])]
    A = np.zeros((len(basis.exponents) + 1, n, n))
    for i in range(0, n - 1, 2):
        b = 3.0 + rng.uniform(0.0, 1.0)
        A[0, i : i + 2, i : i + 2] = -np.eye(2) + b * J
        for j, e in enumerate(basis.exponents):
            if sum(e) == 1:
                k = e.index(1)
                # s_k = 2 p_k - 1: psi = p_k (degree 1) enters through its mapped value.
                A[j + 1, i : i + 2, i : i + 2] = 2.0 * E[k] if k < 2 else 0.3 * np.eye(2)
    A[0] += 0.05 * rng.standard_normal((n, n))
    A[-1] += 0.05 * rng.standard_normal((n, n))  # a quadratic part
    nb = len(A)
    B = np.zeros((nb, n, 1))
    B[0] = rng.standard_normal((n, 1))
    C = np.zeros((nb, 1, n))
    C[0] = rng.standard_normal((1, n))
    return lpvid.LpvModel(A, B, C, basis=basis)


def timed(f, runs: int):
    out, times = None, []
    for _ in range(runs):
        t0 = time.perf_counter()
        out = f()
        times.append(time.perf_counter() - t0)
    return out, statistics.median(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, nargs="+", default=[8])
    ap.add_argument("--params", type=int, nargs="+", default=[2])
    ap.add_argument("--runs", type=int, default=3)
    args = ap.parse_args()
    for n_params in args.params:
        for n in args.n:
            m = model(n, n_params)
            rep, t_scan = timed(lambda m=m: lpvid.stability(m, quadratic=False), args.runs)
            (q, _, _), t_quad = timed(
                lambda m=m: model_quadratic(
                    m, m.basis.domain, polynomial_A(m, m.basis.domain), False
                ),
                args.runs,
            )
            rate = 0.05 * np.ones(n_params)
            (ok, _, _), t_rate = timed(lambda m=m, r=rate: lpvid.rate_stability(m, r), args.runs)
            found, t_max = timed(lambda m=m: lpvid.max_rate(m), max(1, args.runs // 3))
            size = program_size(n, n_params, 2, 2, False)
            print(
                f"n = {n}, Np = {n_params}: frozen stable {rep.stable}; "
                f"scan {t_scan:.3f} s, quadratic {t_quad:.3f} s ({q}), "
                f"rate 0.05 {t_rate:.3f} s ({ok}), max_rate {t_max:.2f} s "
                f"({found.solves} programs, rate {found.rate})"
            )
            print(
                f"    rate program: largest block {max(size['blocks'])}, "
                f"{len(size['blocks'])} blocks, {size['equations']} equations, "
                f"{size['unknowns']} unknowns, estimate {size['bytes'] / 2**20:.0f} MiB"
            )


if __name__ == "__main__":
    main()
