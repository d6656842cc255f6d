"""How close one Gauss-Newton evaluation comes to the machine's matrix-multiply rate.

Usage::

    python benches/bench_rate.py [--rung n32] [--repeat 5]

Builds a rung of ``benches/bench_scale.py`` (its data, and a model of its
shapes near the truth), times one Gauss-Newton evaluation of the core
(residual, gradient and ``J^T J`` through ``lpvid._core.Problem.gauss_newton``,
the work of every Levenberg-Marquardt step; medians of ``--repeat``), and
sets it against

- the flops of its Kronecker Gram products (``kron_gram``: per point, two
  real products over ``S = F min(l, r)`` samples between the triangle of
  the rank-one side and the other side's, ``T(n + r)`` entries with
  ``T(d) = d (d + 1) / 2``; the rank-one side's last rows are zero but on
  their own output's samples, which the core skips, so its triangle
  counts ``T(n) + n + 1`` entries per sample: ``4 S (T(n) + n + 1) T(n +
  r)`` flops a point), the bulk of the evaluation;
- the machine's measured rate of a large matrix product (numpy's BLAS on
  every core, ``4096 x 4096``, medians), and the peak of fused
  multiply-adds measured by a register-only loop (docs/performance.md:
  98.5 Gflop/s a core with AVX-512, 66 with AVX2).

Prints the evaluation's time, its Gram flops, the rate they come to, and
that rate as a fraction of the measured matrix-multiply rate.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import numpy as np
from bench_scale import RUNGS, problem

import lpvid
from lpvid.fit.cost import build_problem


def _tri(d: int) -> int:
    return d * (d + 1) // 2


#: Gflop/s a core of a register-only loop of fused multiply-adds on this
#: machine (docs/performance.md), by the core's route.
FMA_PEAK = {"avx512": 98.5, "avx2": 66.0}


def gram_flops(n: int, l: int, r: int, n_points: int, n_lines: int) -> float:
    """Flops of the Kronecker Gram products of one evaluation, the skipped zeros left out."""
    samples = n_lines * min(l, r)
    other = max(l, r)
    return 4.0 * samples * (_tri(n) + n + 1) * _tri(n + other) * n_points


def matmul_rate(size: int = 4096, repeat: int = 5) -> float:
    """Flop/s of numpy's matrix product of two ``size x size`` matrices (median)."""
    rng = np.random.default_rng(0)
    a, b = rng.standard_normal((size, size)), rng.standard_normal((size, size))
    a @ b  # warm up the BLAS threads
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        a @ b
        times.append(time.perf_counter() - t)
    return 2.0 * size**3 / statistics.median(times)


def model_near(data: lpvid.FrfData, n: int, basis: lpvid.Basis) -> lpvid.LpvModel:
    """A model of the rung's shapes: the first point's local model, constant in p."""
    lti = lpvid.identify_lti(data.subset([0]), n)[0]
    pad = len(basis)
    A, B, C, D = (
        np.concatenate([x[:1], np.zeros((pad, *x.shape[1:]))]) for x in lti.matrices().values()
    )
    return lpvid.LpvModel(A, B, C, D, basis, Ts=data.Ts)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rung", default="n32", choices=sorted(RUNGS))
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    data, _, n, basis, note = problem(args.rung)
    model = model_near(data, n, basis)
    core = build_problem(model, data)
    theta = np.ascontiguousarray(model.theta)
    core.gauss_newton(theta)  # warm up
    times = []
    for _ in range(args.repeat):
        t = time.perf_counter()
        core.gauss_newton(theta)
        times.append(time.perf_counter() - t)
    seconds = statistics.median(times)
    flops = gram_flops(n, data.n_outputs, data.n_inputs, data.n_points, data.n_lines)
    rate = matmul_rate(repeat=args.repeat)
    kernel = lpvid.kernel_route()
    cores = os.cpu_count() or 1
    peak = FMA_PEAK.get(kernel, FMA_PEAK["avx2"]) * cores * 1e9
    reached = flops / seconds
    print(f"{args.rung}: {note}, {theta.size} parameters, route {kernel}, {cores} cores")
    print(f"one Gauss-Newton evaluation: {seconds * 1e3:.0f} ms (median of {args.repeat})")
    print(f"its Kronecker Gram products: {flops / 1e9:.1f} Gflop")
    print(f"  -> {reached / 1e9:.0f} Gflop/s over the whole evaluation")
    print(f"numpy's matrix product (4096 x 4096, all cores): {rate / 1e9:.0f} Gflop/s")
    print(f"fraction of numpy's matrix-product rate: {reached / rate:.2f}")
    print(
        f"fraction of the fused multiply-add peak ({peak / 1e9:.0f} Gflop/s): {reached / peak:.2f}"
    )


if __name__ == "__main__":
    main()
