"""One Levenberg-Marquardt iteration of fit_time on a gantry-size model: 10^5 samples.

Model: n=6 states, r=1 input, l=2 outputs, Nb=4 basis functions (280
parameters, all free), discrete time (``--continuous``: a continuous-time
model through the zero-order hold); one record with a random input and a
fast scheduling trajectory, initial state estimated (286 Jacobian columns
before its elimination). Prints medians over repetitions of

- one LM iteration of ``lpvid.fit_time`` (``history[0]["seconds"]``: one
  evaluation of cost, gradient and ``J^T J`` at the trial point and the
  step's solve),
- one Gauss-Newton evaluation in the core, split into its stages:
  simulation (twice: from rest for the initial state, then from it),
  matrices per sample (``A(p(t))``, ``C(p(t))``; the hold and its
  derivative in continuous time), the sensitivity recursion with the
  Jacobian rows, the Gram product ``J^T J`` with ``J^T r``, and the
  elimination of the initial state,
- the sensitivities' throughput: samples times parameters per second of
  the matrices per sample and the sensitivity recursion together, against
  the samples per second of ``LpvModel.simulate`` on the same record (the
  ratio: what one parameter's sensitivity costs in simulations).

The machines are shared and noisy: compare medians.

Run: python benches/bench_time.py [--repeat 7] [--samples 100000] [--continuous]
"""

from __future__ import annotations

import argparse

import numpy as np
from bench_core import median_time
from bench_simulate import gantry_size_model

import lpvid
from lpvid.fit.timecost import build_time_problem


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=7)
    parser.add_argument("--samples", type=int, default=100_000)
    parser.add_argument("--continuous", action="store_true")
    args = parser.parse_args()
    model = gantry_size_model()
    if args.continuous:
        # The same matrices read as dx/dt = (A - I) / dt x + B / dt u: the
        # hold of one sample is close to the discrete-time model.
        dt = 1e-3
        A = model.A.copy()
        A[0] -= np.eye(model.n_states)
        model = lpvid.LpvModel(
            A / dt, model.B / dt, model.C, model.D, model.basis, Ts=None, p_range=model.p_range
        )
    T = args.samples
    rng = np.random.default_rng(1)
    u = rng.normal(size=T)
    p = rng.uniform(24.0, 48.0, size=T)
    y = model.simulate(u, p, dt=1e-3) + 0.01 * rng.normal(size=(T, model.n_outputs))
    td = lpvid.TimeData(u, p, y, dt=1e-3, sigma=0.01)
    start = model.with_theta(model.theta * (1 + 1e-3 * rng.normal(size=model.theta.size)))
    n, r, l, nb = model.shape
    k = start.theta.size + n
    kind = "continuous time (ZOH)" if args.continuous else "discrete time"
    print(f"fit_time, {kind}: T={T} samples, n={n}, r={r}, l={l}, Nb={nb}: {k - n} parameters")
    print(
        f"Gram product J^T J (lower triangle, {k} columns, {T * l} rows): "
        f"{k * (k + 1) / 2 * T * l * 2:.3g} flops before using structure"
    )

    iters = []

    def one_iteration() -> None:
        fit = lpvid.fit_time(start, td, max_iter=1, warn=False)
        iters.append(fit.history[0]["seconds"])

    whole = median_time(one_iteration, args.repeat)
    problem = build_time_problem(start, td)
    stages: dict[str, list[float]] = {}

    def gauss_newton() -> None:
        for key, seconds in problem.gauss_newton(start.theta)[3].items():
            stages.setdefault(key, []).append(seconds)

    core = median_time(gauss_newton, args.repeat)
    simulation = median_time(lambda: start.simulate(u, p, dt=1e-3), args.repeat)
    print(f"one LM iteration (median of {len(iters)}): {1e3 * np.median(iters):8.1f} ms")
    print(f"fit_time(max_iter=1) call, start and Python included: {1e3 * whole:8.1f} ms")
    print(f"one Gauss-Newton evaluation in the core:              {1e3 * core:8.1f} ms")
    for key in ("simulation_s", "discretisation_s", "sensitivities_s", "gram_s", "schur_s"):
        print(f"  {key[:-2]:<16} {1e3 * np.median(stages[key]):8.1f} ms")
    sens = np.median(stages["discretisation_s"]) + np.median(stages["sensitivities_s"])
    per_parameter = T * (k - n) / sens
    print(f"LpvModel.simulate: {1e3 * simulation:8.1f} ms, {T / simulation:.3g} samples/s")
    print(
        f"sensitivities (matrices per sample + recursion): {per_parameter:.3g} "
        f"samples/s per parameter; all {k - n} parameters cost "
        f"{sens / simulation:.1f} simulations"
    )


if __name__ == "__main__":
    main()
