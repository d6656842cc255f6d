"""A small problem iterated on at the bench: where identify's time goes, against scikit-rf.

The model-reduction community's synthetic parametric model
(:func:`lpvid.testing.synthetic_parametric`: n = 10, SISO, one parameter on
[0.02, 1]) measured at six points spread evenly on a log scale, 200 lines
log-spaced over 10^0.5 to 10^3.5 rad/s, 1 % complex noise, no validation
data; ``lpvid.identify`` with ``Polynomial(2)`` and D fixed.

Printed: the median seconds of ``identify`` over ``--repeat`` runs (after
one run that is not counted: imports and first calls), the median of every
stage of :attr:`lpvid.IdentifyResult.timings`, and the worst relative FRF
error at 20 unseen values against the truth; then the process's CPU
seconds per run (every thread's, :func:`time.process_time`), the cores
that makes on average, and the time the run would take with every core
busy throughout (the CPU seconds over the cores: a floor that more
overlap cannot beat). Then, when scikit-rf is
installed (it is no dependency of lpvid: ``pip install scikit-rf``),
``skrf.vectorFitting.VectorFittingParametric`` on the same data, with the
order it finds itself and with five complex pole pairs (the truth's order),
``auto_fit(enforce_passivity=False)`` (one vector fit per point on common
poles, its coefficients interpolated linearly between the points), timed
and judged the same way.

Run: python benches/bench_small.py [--repeat 5] [--seed 0]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
import types
import warnings

import numpy as np
from bench_few import CASES, unseen

import lpvid
from lpvid._spread import cores
from lpvid.testing import noisy_data, synthetic_parametric, worst_relative_error

FREQS_HZ = np.logspace(0.5, 3.5, 200) / (2 * np.pi)
#: The truth's order for scikit-rf: five complex pole pairs, no real pole.
FIVE_PAIRS = {"n_poles_real": 0, "n_poles_cmplx": 5}


def measured(seed: int) -> tuple[lpvid.LpvModel, lpvid.FrfData]:
    """The truth and its six measured points (evenly on a log scale), 1 % noise."""
    true = synthetic_parametric(10)
    lo, hi = true.p_range
    points = np.geomspace(lo, hi, 6)
    return true, noisy_data(true, points, FREQS_HZ, np.random.default_rng(seed), 0.01)


def time_lpvid(true: lpvid.LpvModel, data: lpvid.FrfData, repeat: int) -> None:
    """Median seconds of identify and of each of its stages, and the error between the points."""
    runs = []
    for k in range(repeat + 1):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            t, c = time.perf_counter(), time.process_time()
            res = lpvid.identify(data, 10, true.basis, fixed={"D": True})
            seconds, cpu = time.perf_counter() - t, time.process_time() - c
        if k:
            runs.append((seconds, res.timings, cpu))
    at = unseen(CASES["mor"], *map(np.atleast_1d, true.p_range))
    err = worst_relative_error(res.model, true, FREQS_HZ, at)
    print(
        f"lpvid.identify: median {statistics.median(s for s, _, _ in runs):.3f} s over {repeat} "
        f"runs; start {res.start}, {res.model.group_norms().count()} groups; worst relative "
        f"error at 20 unseen values {err:.3g}"
    )
    for stage in runs[0][1]:
        values = [t[stage] for _, t, _ in runs if stage in t]
        print(f"  {stage:>14}: {statistics.median(values):.3f} s")
    cpu = statistics.median(c for _, _, c in runs)
    used = statistics.median(c / s for s, _, c in runs)
    print(
        f"  CPU {cpu:.3f} s per run (every thread), {used:.2f} of {cores()} cores on average; "
        f"with every core busy throughout: {cpu / cores():.3f} s"
    )


def time_skrf(true: lpvid.LpvModel, data: lpvid.FrfData, repeat: int) -> None:
    """One parametric vector fit of the same data per run: median seconds and its error."""
    try:
        from skrf.network import Network
        from skrf.networkSet import NetworkSet
        from skrf.vectorFitting import VectorFittingParametric
    except ImportError:
        print("scikit-rf: not installed (pip install scikit-rf), not compared")
        return
    nets = NetworkSet(
        [
            Network(f=FREQS_HZ, s=data.G[q], f_unit="Hz", params={"mu": float(p)})
            for q, p in enumerate(data.p)
        ]
    )
    # auto_fit turns every warning into an error to catch its passivity
    # warnings (UserWarning) and so fails on a point whose pole relocation
    # ends at its 100 iterations (a RuntimeWarning) under 1 % noise: its
    # filter is made to turn only UserWarning into errors, as it means to
    # (and its reset of the filters to leave the others ignored).
    module = sys.modules[VectorFittingParametric.__module__]
    shim = types.SimpleNamespace(**vars(warnings))
    shim.filterwarnings = lambda action, *a, **k: warnings.filterwarnings(
        action, *a, **({"category": UserWarning} if action == "error" else {}), **k
    )
    shim.resetwarnings = lambda: warnings.simplefilter("ignore")
    at = unseen(CASES["mor"], *map(np.atleast_1d, true.p_range))
    G = true.frf(FREQS_HZ, at).reshape(len(at), -1)
    for label, poles in (("its own order", {}), ("5 complex pole pairs", FIVE_PAIRS)):
        seconds = []
        for k in range(repeat + 1):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                module.warnings = shim
                try:
                    t = time.perf_counter()
                    vf = VectorFittingParametric(nets, **poles)
                    vf.auto_fit(enforce_passivity=False)
                    if k:
                        seconds.append(time.perf_counter() - t)
                finally:
                    module.warnings = warnings
        H = np.array([vf.get_model_response({"mu": float(m)}, FREQS_HZ).ravel() for m in at])
        err = float(np.max(np.linalg.norm(H - G, axis=1) / np.linalg.norm(G, axis=1)))
        print(
            f"scikit-rf VectorFittingParametric ({label}): median {statistics.median(seconds):.3f} "
            f"s over {repeat} runs; worst relative error at 20 unseen values {err:.3g}"
        )


def main() -> None:
    """Time both on the same data."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    true, data = measured(args.seed)
    time_lpvid(true, data, args.repeat)
    time_skrf(true, data, args.repeat)


if __name__ == "__main__":
    main()
