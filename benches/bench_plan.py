"""Measure next where lpvid says, or at the midpoint of the largest gap, or on an even grid?

The loop an engineer runs at a test bench, on a system with a known truth:
start from ``Nb + 1`` points (the ends of the range and one drawn
uniformly in between), identify (no validation data, D fixed), and while
the model's worst relative FRF error at 20 unseen values is above the goal
(0.01), add one measured point and identify again, up to ``--most``
points added. Three ways to choose the next point:

- ``next``: :func:`lpvid.next_points` on the result (with ``--resample B``:
  on :func:`lpvid.resampled` of it with ``B`` runs, the committee's
  criterion applied to the resampled spread instead of the committee's, as
  ``next_points`` did until 2026-11-30: the placement it measured and left);
- ``gap``: the midpoint of the largest gap between the points measured;
- ``grid``: no loop: an even grid of ``Nb + 1 + k`` points, ``k = 0, 1, ...``
  (every point measured anew), until the goal is met.

Each measurement is the truth's FRF at that value with 1 % complex noise
(``lpvid.testing.noisy_data``) whose random numbers are fixed by the draw
and the value itself (:func:`measure`): every way that measures a value
gets the same FRF there, as on a bench where a point measured once is
kept. (Until 2026-11-29 the noise came from one stream per draw, and the
grid drew it anew at every count, the ends included: at errors near the
noise's own level that is a fresh try of the noise per count, which the
loops, keeping what they measured, never get; see docs/fewpoints.md.) The
summary gives, per way, the mean and median number of points added to
meet the goal (a draw that does not meet it within ``--most`` counts as
``most + 1``), how many draws met it, the FRFs measured beyond the first
set to get there (:func:`measured_beyond`: the grid measures each count's
values anew), and the mean error after each number of added points.

Run: python benches/bench_plan.py [--cases mor onegroup] [--draws 20] [--most 5] [--resample B]
"""

from __future__ import annotations

import argparse
import statistics
import warnings

import numpy as np
from bench_few import CASES, FIXED, unseen

import lpvid
from lpvid.testing import noisy_data, worst_relative_error

GOAL = 0.01


def _identify(data: lpvid.FrfData, case, true) -> lpvid.IdentifyResult:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return lpvid.identify(data, case.n, true.basis, fixed=FIXED)


def measure(true: lpvid.LpvModel, points, freqs_hz, draw: int) -> lpvid.FrfData:
    """The truth's FRF at ``points``, each value's noise drawn from ``(draw, the value's bits)``."""
    return lpvid.FrfData.stack([_one(true, float(p), freqs_hz, draw) for p in points])


def _one(true: lpvid.LpvModel, p: float, freqs_hz, draw: int) -> lpvid.FrfData:
    seed = [7000 + draw, int.from_bytes(np.float64(p).tobytes(), "little")]
    return noisy_data(true, [p], freqs_hz, np.random.default_rng(seed), 0.01)


def _by_resampled(res: lpvid.IdentifyResult, draws: int) -> float:
    """The next point by the committee's criterion on the spread of ``draws`` resampled runs."""
    from lpvid.experiment import nextpoints

    again = lpvid.resampled(res, draws)
    placing = nextpoints._placing
    nextpoints._placing = lambda between: between  # keep the resampled models
    try:
        return float(lpvid.next_points(again)[0])
    finally:
        nextpoints._placing = placing


def loop(name: str, draw: int, way: str, most: int, resample: int = 0) -> list[float]:
    """The worst error after 0, 1, ... added points (stops once the goal is met)."""
    case = CASES[name]
    true = case.truth(draw)
    lo, hi = true.p_range
    at = unseen(case, np.array([lo]), np.array([hi]))
    nb1 = len(true.basis) + 1
    rng = np.random.default_rng(7000 + draw)
    first = np.sort(np.concatenate([[lo, hi], rng.uniform(lo, hi, nb1 - 2)]))
    errors = []
    if way == "grid":
        for k in range(most + 1):
            data = measure(true, np.linspace(lo, hi, nb1 + k), case.freqs_hz, draw)
            errors.append(
                worst_relative_error(_identify(data, case, true).model, true, case.freqs_hz, at)
            )
            if errors[-1] <= GOAL:
                break
        return errors
    data = measure(true, first, case.freqs_hz, draw)
    for k in range(most + 1):
        res = _identify(data, case, true)
        errors.append(worst_relative_error(res.model, true, case.freqs_hz, at))
        if errors[-1] <= GOAL or k == most:
            break
        if way == "next":
            new = float(_by_resampled(res, resample) if resample else lpvid.next_points(res)[0])
        else:
            p = np.sort(data.p)
            gaps = np.diff(p)
            j = int(np.argmax(gaps))
            new = float(p[j] + gaps[j] / 2)
        data = lpvid.FrfData.stack([data, measure(true, [new], case.freqs_hz, draw)])
    return errors


def measured_beyond(name: str, way: str, added: int, most: int) -> int:
    """FRFs measured beyond the first ``Nb + 1`` to end with ``added`` more points.

    The loops measure one per added point. The grid measures every count's
    grid anew but for the values an earlier grid measured (the ends, and
    such as 0.5 in the grids of three and five points): to end at
    ``Nb + 1 + k`` points it has measured every value of the grids up to
    that count. A draw that never met the goal counts ``most + 1`` added
    points (and for the grid, one FRF more than all its grids).
    """
    if way != "grid":
        return added
    case = CASES[name]
    nb1 = len(case.truth(0).basis) + 1
    k = min(added, most)
    lo, hi = case.truth(0).p_range
    seen = {float(x) for j in range(k + 1) for x in np.linspace(lo, hi, nb1 + j)}
    return len(seen) - nb1 + (added > most)


def main() -> None:
    """Run the loops and print their rows and summaries."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="+", choices=["mor", "onegroup"], default=["mor"])
    parser.add_argument("--draws", type=int, default=20)
    parser.add_argument("--most", type=int, default=5)
    parser.add_argument("--ways", nargs="+", default=["next", "gap", "grid"])
    parser.add_argument(
        "--resample", type=int, default=0, help="next: follow lpvid.resampled's spread, B runs"
    )
    args = parser.parse_args()
    lines = []
    for name in args.cases:
        for way in args.ways:
            added, curves = [], []
            for draw in range(args.draws):
                errs = loop(name, draw, way, args.most, args.resample)
                met = errs[-1] <= GOAL
                added.append(len(errs) - 1 if met else args.most + 1)
                curves.append(errs + [errs[-1]] * (args.most + 1 - len(errs)))
                trail = " ".join(f"{e:.3g}" for e in errs)
                print(f"  {name} {way} draw {draw}: added {added[-1]}; errors {trail}", flush=True)
            mean_curve = " ".join(
                f"{np.mean([c[k] for c in curves]):.3g}" for k in range(args.most + 1)
            )
            met = sum(a <= args.most for a in added)
            frfs = [measured_beyond(name, way, a, args.most) for a in added]
            lines.append(
                f"## {name} {way}: points added mean {np.mean(added):.2f}, median "
                f"{statistics.median(added):g}, met {met}/{len(added)}; FRFs measured beyond "
                f"the first set mean {np.mean(frfs):.2f}; mean error after 0.. "
                f"{args.most} added: {mean_curve}"
            )
            print(lines[-1], flush=True)
    print("\n".join(lines))


if __name__ == "__main__":
    main()
