"""Page faults and time of Levenberg-Marquardt steps on the scale ladder's n16 rung.

A fit's large arrays (the Gauss-Newton matrix, the step's factor, the
Gram matrices) are fresh memory at every evaluation, and fresh memory
costs a page fault and the kernel's zeroing at its first write: one per
4 kB page, one per 2 MB huge page (``lpvid.memory``'s huge-page advice,
``rust/memory/mod.rs``). This runs ``fit_nls`` from the SMILE start of
``benches/bench_scale.py``'s n16 rung (n = 16, 2x2, Nb = 4, N = 9,
F = 500: 1620 free parameters) for a fixed number of steps, ``--repeat``
times, and prints per run the time per step, the minor page faults of the
process per step (``getrusage``; the first run's include the start), and a
digest of the returned theta (the same on every build that keeps the
numbers). Compare two builds by running this with each.

Run: python benches/bench_pages.py [--rung n16] [--steps 15] [--repeat 5]
"""

from __future__ import annotations

import argparse
import hashlib
import resource
import statistics
import time

import numpy as np
from bench_scale import RUNGS, problem

import lpvid


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rung", default="n16", choices=[r for r in RUNGS if r != "gantry"])
    ap.add_argument("--steps", type=int, default=15)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    data, _, n, basis, note = problem(args.rung)
    start = lpvid.smile(lpvid.identify_lti(data, n), basis=basis, form="observability")
    print(f"{args.rung}: {note}; {start.theta.size} parameters, {args.steps} LM steps per run")
    per_step = []
    for k in range(args.repeat):
        faults = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
        t0 = time.perf_counter()
        fit = lpvid.fit_nls(start, data, max_iter=args.steps, warn=False)
        seconds = time.perf_counter() - t0
        faults = resource.getrusage(resource.RUSAGE_SELF).ru_minflt - faults
        steps = len(fit.history)
        digest = hashlib.sha1(np.ascontiguousarray(fit.model.theta).tobytes()).hexdigest()[:12]
        per_step.append(1e3 * seconds / steps)
        print(
            f"run {k + 1}: {per_step[-1]:.1f} ms/step, {faults / steps:.0f} page faults/step, "
            f"V_NLS {fit.vnls:.10g}, theta {digest}"
        )
    print(f"median {statistics.median(per_step):.1f} ms/step over {args.repeat} runs")


if __name__ == "__main__":
    main()
