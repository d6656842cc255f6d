"""Timings of the trust tools on the gantry's identified model (lpvid.datasets.gantry()).

Prints medians over repetitions (the machines are shared and noisy):

- ``lpvid.stability``: frozen models only, and with the quadratic (LMI) test;
- the core's check of one trial step in fits with ``stable=True``
  (``FrozenRange.worst`` on the 2049 check points), next to one evaluation
  of V_NLS, gradient and J^T J;
- ``covariance`` and ``frf_std`` on a 60 x 300 grid (the report's map);
- one ``fit_nls`` from the identified model with and without ``stable=True``.

Set OPENBLAS_NUM_THREADS=1 on a loaded machine: numpy's threaded
eigenvalue routines then stop fighting over the cores.

Run: python benches/bench_trust.py [--repeat 20]
"""

from __future__ import annotations

import argparse
import warnings

import numpy as np
from bench_core import median_time

import lpvid
from lpvid.fit.cost import build_problem
from lpvid.stable.enforce import check_points
from lpvid.stable.ranges import check_range
from lpvid.trust.support import dropped_mask


def main() -> None:
    """Identify the gantry once, then time the pieces."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeat", type=int, default=20)
    args = parser.parse_args()
    ds = lpvid.datasets.gantry()
    data = ds.identification
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lpvid.ConvergenceWarning)
        res = lpvid.identify(data, ds.order, ds.basis, validation=ds.validation, fixed=ds.fixed)
    model = res.model
    rows = []
    rows.append(
        (
            "stability(), frozen models only",
            median_time(lambda: lpvid.stability(model, quadratic=False), args.repeat),
        )
    )
    rows.append(
        (
            "stability(), with the quadratic LMI",
            median_time(lambda: lpvid.stability(model), max(3, args.repeat // 5)),
        )
    )
    points = check_points(model, check_range(model, None), [])
    rows.append(
        (
            "stable=True check of one trial step (2049 points)",
            median_time(lambda: points.worst(model.theta), 10 * args.repeat),
        )
    )
    problem = build_problem(model, data)
    held = dropped_mask(model) | lpvid.fixed_mask(model, ds.fixed)
    rows.append(
        (
            "V_NLS, gradient and J^T J (for scale)",
            median_time(lambda: problem.gauss_newton(model.theta), 10 * args.repeat),
        )
    )
    rows.append(
        (
            "covariance()",
            median_time(lambda: lpvid.covariance(model, data, held, warn=False), args.repeat),
        )
    )
    p = np.linspace(24.0, 48.0, 60)
    rows.append(
        (
            "frf_std on 60 p x 300 lines",
            median_time(lambda: res.covariance.frf_std(data.freqs_hz, p), args.repeat),
        )
    )
    for stable in (False, True):
        fit = lpvid.fit_nls(model, data, ds.fixed, stable=stable, max_iter=20, warn=False)
        per = fit.timings["lm_iter_s"]
        rows.append((f"one LM iteration, stable={stable}", per))
    width = max(len(name) for name, _ in rows)
    for name, t in rows:
        print(f"{name:<{width}}  {t * 1e3:9.2f} ms")


if __name__ == "__main__":
    main()
