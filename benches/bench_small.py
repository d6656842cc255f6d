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
overlap cannot beat). With ``--cores``, also the cores each stage keeps
busy on average (the process's CPU seconds, read every 5 ms by a thread
of the benchmark, over the stage's wall time; the stages placed one after
the other from the call by their timings): where a core waits. Then, when
scikit-rf is
installed (it is no dependency of lpvid: ``pip install scikit-rf``),
``skrf.vectorFitting.VectorFittingParametric`` on the same data, with the
order it finds itself and with five complex pole pairs (the truth's order),
``auto_fit(enforce_passivity=False)`` (one vector fit per point on common
poles, its coefficients interpolated linearly between the points), timed
and judged the same way.

With ``--settings``, ``identify`` runs with the leanest of the settings it
offers in place of its defaults (:data:`SETTINGS`): the starts of the
global route alone, a lean path (two values of gamma, at most three cone
steps a reweighting and five reweightings), or both; what they save and
what they cost against the truth (over ``--seed 0`` to ``7``) is in
``docs/performance.md``.

Run: python benches/bench_small.py [--repeat 5] [--seed 0] [--cores] [--settings lean]
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import statistics
import sys
import threading
import time
import types
import warnings
from typing import Any

import numpy as np
from bench_few import CASES, unseen

import lpvid
from lpvid._spread import cores
from lpvid.fit.settings import PATH_L21
from lpvid.testing import noisy_data, synthetic_parametric, worst_relative_error

FREQS_HZ = np.logspace(0.5, 3.5, 200) / (2 * np.pi)
#: The leanest settings identify offers, by name (keyword arguments of identify):
#: the global route's starts alone, a lean path, or both.
GLOBAL_STARTS: dict[str, Any] = {"routes": ("global",)}
LEAN_PATH: dict[str, Any] = {
    "gammas": (3e-2, 3e-3),
    "settings": dataclasses.replace(PATH_L21, max_inner=3, max_outer=5),
}
SETTINGS: dict[str, dict[str, Any]] = {
    "default": {},
    "global-starts": GLOBAL_STARTS,
    "lean-path": LEAN_PATH,
    "lean": {**GLOBAL_STARTS, **LEAN_PATH},
}
#: The truth's order for scikit-rf: five complex pole pairs, no real pole.
FIVE_PAIRS = {"n_poles_real": 0, "n_poles_cmplx": 5}


def measured(seed: int) -> tuple[lpvid.LpvModel, lpvid.FrfData]:
    """The truth and its six measured points (evenly on a log scale), 1 % noise."""
    true = synthetic_parametric(10)
    lo, hi = true.p_range
    points = np.geomspace(lo, hi, 6)
    return true, noisy_data(true, points, FREQS_HZ, np.random.default_rng(seed), 0.01)


#: The wall-time stages of identify's timings, in the order they run.
STAGES = ("local_s", "smile_s", "path_s", "few_points_s", "finish_s")


class CpuTrace:
    """The process's CPU seconds against the clock, read every ``every`` seconds by a thread."""

    def __init__(self, every: float = 0.005) -> None:
        self.every, self.samples = every, [(time.perf_counter(), time.process_time())]
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._read, daemon=True)

    def _read(self) -> None:
        while not self._stop.wait(self.every):
            self.samples.append((time.perf_counter(), time.process_time()))

    def __enter__(self) -> CpuTrace:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join()
        self.samples.append((time.perf_counter(), time.process_time()))

    def cores(self, start: float, end: float) -> float:
        """Cores busy on average from ``start`` to ``end`` (the nearest readings inside)."""
        inside = [s for s in self.samples if start <= s[0] <= end]
        if len(inside) < 2 or inside[-1][0] <= inside[0][0]:
            return float("nan")
        (t0, c0), (t1, c1) = inside[0], inside[-1]
        return (c1 - c0) / (t1 - t0)


def stage_cores(trace: CpuTrace, called: float, timings: dict[str, float]) -> dict[str, float]:
    """Cores each stage kept busy: the stages one after the other from ``called``."""
    out, start = {}, called
    for stage in STAGES:
        end = start + timings[stage]
        out[stage] = trace.cores(start, end)
        start = end
    return out


def time_lpvid(
    true: lpvid.LpvModel,
    data: lpvid.FrfData,
    repeat: int,
    with_cores: bool = False,
    settings: str = "default",
) -> None:
    """Median seconds of identify and of each of its stages, and the error between the points."""
    runs, busy = [], []
    for k in range(repeat + 1):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            trace = CpuTrace() if with_cores else None
            with trace or contextlib.nullcontext():
                t, c = time.perf_counter(), time.process_time()
                res = lpvid.identify(data, 10, true.basis, fixed={"D": True}, **SETTINGS[settings])
                seconds, cpu = time.perf_counter() - t, time.process_time() - c
        if k:
            runs.append((seconds, res.timings, cpu))
            if trace is not None:
                busy.append(stage_cores(trace, t, res.timings))
    at = unseen(CASES["mor"], *map(np.atleast_1d, true.p_range))
    err = worst_relative_error(res.model, true, FREQS_HZ, at)
    median = statistics.median(s for s, _, _ in runs)
    print(
        f"lpvid.identify ({settings} settings): median {median:.3f} s over {repeat} runs; "
        f"start {res.start}, {res.model.group_norms().count()} groups; worst relative error "
        f"at 20 unseen values {err:.3g}"
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
    if busy:
        pairs = [(t, b) for (_, t, _), b in zip(runs, busy, strict=True)]
        idle = {s: statistics.median(t[s] * (cores() - b[s]) for t, b in pairs) for s in STAGES}
        print(
            "  cores busy per stage (median; core-seconds left idle): "
            + ", ".join(
                f"{s[:-2]} {statistics.median(b[s] for b in busy):.2f} ({idle[s]:.3f})"
                for s in STAGES
            )
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
    parser.add_argument(
        "--cores", action="store_true", help="also the cores each stage keeps busy on average"
    )
    parser.add_argument(
        "--settings", choices=sorted(SETTINGS), default="default", help="identify's settings"
    )
    args = parser.parse_args()
    true, data = measured(args.seed)
    time_lpvid(true, data, args.repeat, args.cores, args.settings)
    time_skrf(true, data, args.repeat)


if __name__ == "__main__":
    main()
