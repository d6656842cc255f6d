"""Initial estimates by route: accuracy over noise seeds, and time per route.

Two problems:

- the heavily damped SISO system of ``tests/systems.py`` (``heavily_damped``:
  three modes at 6.6, 17 and 45 Hz whose damping ratios go from 0.32-0.47
  to 0.39-0.88 over the scheduling range, exactly affine in p), FRFs with
  1 % noise on 150 lines at 5 points, validation at the 4 midpoints,
  ``Polynomial(1)`` (and, with ``--degree``, a richer basis);
- the built-in gantry (``lpvid.datasets.gantry()``).

For every noise seed it prints, for the plain route (identify_lti + every
SMILE form + fit_nls) and for all routes of ``lpvid.initial.initial_candidates``,
the candidate :func:`lpvid.initial.choose` keeps with validation data: V_NLS
over the noise floor on identification and validation data. A route
"succeeds" when it reaches 1.1 (identification) and 1.3 (validation).

Run: python benches/bench_robust.py [--seeds 20] [--degree 1]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

import lpvid
from lpvid import initial

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
from systems import heavily_damped, lti_frf  # noqa: E402

FREQS = np.logspace(np.log10(2.0), np.log10(300.0), 150)
P = np.linspace(0.0, 1.0, 5)
MID = (P[1:] + P[:-1]) / 2


def frf_data(p: np.ndarray, seed: int, rel: float = 0.01) -> lpvid.FrfData:
    rng = np.random.default_rng(seed)
    G = np.array([lti_frf(heavily_damped(s), 2j * np.pi * FREQS) for s in p])
    sigma = rel * np.abs(G)
    G = G + sigma * (rng.normal(size=G.shape) + 1j * rng.normal(size=G.shape)) / np.sqrt(2)
    return lpvid.FrfData(p, FREQS, G, sigma)


def ok(c: initial.Candidate) -> bool:
    return c.ratio < 1.1 and (c.validation_ratio or 0.0) < 1.3


def damped(seeds: int, degree: int) -> None:
    basis = lpvid.Polynomial(degree, domain=(0.0, 1.0))
    print(f"heavily damped system, Polynomial({degree}), {seeds} noise seeds")
    print(" seed | plain: V/floor  val/floor | all routes: V/floor  val/floor  kept")
    wins = {"plain": 0, "robust": 0}
    times = []
    for seed in range(seeds):
        data, val = frf_data(P, seed), frf_data(MID, 100 + seed)
        t = time.perf_counter()
        cands = initial.initial_candidates(data, 6, basis, validation=val)
        times.append(time.perf_counter() - t)
        plain, _ = initial.choose([c for c in cands if c.name.startswith("smile:")])
        best, _ = initial.choose(cands)
        wins["plain"] += ok(plain)
        wins["robust"] += ok(best)
        print(
            f" {seed:4d} |   {plain.ratio:9.3f} {plain.validation_ratio:10.3f} |"
            f"   {best.ratio:9.3f} {best.validation_ratio:10.3f}  {best.name}"
        )
    print(
        f"reached 1.1 / 1.3 x the floor: plain route {wins['plain']}/{seeds}, "
        f"all routes {wins['robust']}/{seeds}; median {np.median(times):.2f} s per call"
    )


def gantry() -> None:
    ds = lpvid.datasets.gantry()
    data, val = ds.identification, ds.validation
    t = time.perf_counter()
    local = lpvid.identify_lti(data, ds.order)
    print(f"\ngantry: local models {time.perf_counter() - t:.2f} s")
    for route in initial.ROUTES:
        t = time.perf_counter()
        cands = initial.initial_candidates(
            data, ds.order, ds.basis, ds.fixed, validation=val, routes=(route,), local=local
        )
        dt = time.perf_counter() - t
        best, _ = initial.choose(cands)
        print(
            f"  {route:13s} {dt:5.2f} s, {len(cands)} candidates, best {best.name}: "
            f"V/floor {best.ratio:.3f}, validation {best.validation_ratio:.3f}"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--degree", type=int, default=1)
    args = parser.parse_args()
    damped(args.seeds, args.degree)
    gantry()


if __name__ == "__main__":
    main()
