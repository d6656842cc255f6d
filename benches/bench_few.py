"""Few measured points: is the model right between them, and does the result say what is open?

Known truths, measured at few scheduling points placed at random (the ends
of the range always, the rest drawn uniformly in between; for two
parameters the four corners and the rest uniform in the square), 1 %
complex noise (``lpvid.testing.noisy_data``), no validation data,
``lpvid.identify`` with its defaults and D fixed:

- ``mor``: :func:`lpvid.testing.synthetic_parametric` (the model-reduction
  community's synthetic parametric model: n = 10, SISO, one parameter on
  [0.02, 1]), ``Polynomial(2)``, 120 lines log-spaced over 10^0.5 to
  10^3.5 rad/s;
- ``onegroup``: :func:`lpvid.testing.one_group_lpv` (n = 10, SISO, one
  parameter, its seed the draw's), ``Polynomial(2)``, 120 lines over 2-100 Hz;
- ``cross2``: :func:`lpvid.testing.crossing_lpv` with two parameters (n = 10,
  3 outputs x 2 inputs, total degree 2: five basis functions), 100 lines
  over 4-100 Hz.

For every draw: the worst relative FRF error at 20 unseen scheduling values
(:func:`lpvid.testing.worst_relative_error`), V_NLS over its noise floor,
and, where the result gives them, what the points leave open
(``result.between``: its count of silent directions, the spread between
the points, the spread's coverage of the truth and its worst over the
actual worst error). The summary line of each (case, N) gives the median,
90 % quantile and worst error, how many draws are above 0.02, how many
models sit more than twice their noise floor, and the median seconds.

With ``--resample B``, every draw's result is also resampled
(:func:`lpvid.resampled`, B runs on data simulated from the model returned)
and the same coverage and spread over error are given for its spread.

Run: python benches/bench_few.py [--cases mor onegroup cross2] [--points 3 4 5 6]
     [--draws 20] [--first 0] [--json out.json] [--dump out.pkl] [--resample 5]
"""

from __future__ import annotations

import argparse
import json
import pickle
import statistics
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

import lpvid
from lpvid.testing import (
    crossing_lpv,
    noisy_data,
    one_group_lpv,
    synthetic_parametric,
    worst_relative_error,
)

FIXED = {"D": True}


@dataclass
class Case:
    """A known truth and how it is measured."""

    truth: Callable[[int], lpvid.LpvModel]
    n: int
    freqs_hz: np.ndarray
    n_params: int
    default_points: tuple[int, ...]


CASES = {
    "mor": Case(
        lambda draw: synthetic_parametric(10),
        10,
        np.logspace(0.5, 3.5, 120) / (2 * np.pi),
        1,
        (3, 4, 5, 6),
    ),
    "onegroup": Case(
        lambda draw: one_group_lpv(draw), 10, np.linspace(2, 100, 120), 1, (3, 4, 5, 6)
    ),
    "cross2": Case(lambda draw: crossing_lpv(2), 10, np.linspace(4, 100, 100), 2, (6, 7, 8)),
}


def placement(case: Case, lo: np.ndarray, hi: np.ndarray, n_points: int, rng) -> np.ndarray:
    """The ends (corners) of the range and the rest uniform in between."""
    if case.n_params == 1:
        inner = rng.uniform(lo[0], hi[0], n_points - 2)
        return np.sort(np.concatenate([[lo[0], hi[0]], inner]))
    corners = np.array([[lo[0], lo[1]], [hi[0], lo[1]], [lo[0], hi[1]], [hi[0], hi[1]]])
    inner = rng.uniform(lo, hi, size=(n_points - 4, 2))
    return np.concatenate([corners, inner])


def unseen(case: Case, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """20 scheduling values strictly inside the range (the same for every draw)."""
    if case.n_params == 1:
        return lo[0] + (hi[0] - lo[0]) * np.linspace(0.01, 0.99, 20)
    rng = np.random.default_rng(12345)
    return lo + (hi - lo) * rng.uniform(0.05, 0.95, size=(20, 2))


def coverage(res, true: lpvid.LpvModel, f: np.ndarray, p: np.ndarray) -> tuple[float, float]:
    """Share of (line, point) pairs whose error lies inside the spread, and worst spread / error."""
    between = getattr(res, "between", None)
    if between is None:
        return float("nan"), float("nan")
    G, Gt = res.model.frf(f, p), true.frf(f, p)
    spread = between.spread(f, p)
    err = np.abs(G - Gt)
    inside = float(np.mean(err <= spread))
    ref = np.linalg.norm(Gt.reshape(len(p), -1), axis=1)
    worst_spread = float(np.max(np.linalg.norm(spread.reshape(len(p), -1), axis=1) / ref))
    worst_err = float(np.max(np.linalg.norm(err.reshape(len(p), -1), axis=1) / ref))
    return inside, worst_spread / worst_err


def measured(case: Case, n_points: int, draw: int):
    """The draw's truth, its data at ``n_points`` placed points, and the range's corners lo, hi."""
    true = case.truth(draw)
    pairs = lpvid.data.schedule.range_pairs(true.p_range, case.n_params)
    lo, hi = np.array([a for a, _ in pairs]), np.array([b for _, b in pairs])
    rng = np.random.default_rng(100 * n_points + draw)
    p = placement(case, lo, hi, n_points, rng)
    return true, noisy_data(true, p, case.freqs_hz, rng, 0.01), lo, hi


def run(
    name: str,
    n_points: int,
    draws: int,
    dump: list | None = None,
    first: int = 0,
    resample: int = 0,
) -> list[dict[str, float]]:
    """Draws ``first`` to ``first + draws - 1`` of one case at one number of points.

    With ``resample``, also the spread of :func:`lpvid.resampled` with so
    many runs (its coverage and its worst over the actual worst error).
    """
    case = CASES[name]
    rows = []
    for draw in range(first, first + draws):
        true, data, lo, hi = measured(case, n_points, draw)
        t = time.perf_counter()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            res = lpvid.identify(data, case.n, true.basis, fixed=FIXED)
        seconds = time.perf_counter() - t
        at = unseen(case, lo, hi)
        err = worst_relative_error(res.model, true, case.freqs_hz, at)
        inside, ratio = coverage(res, true, case.freqs_hz, at)
        again_inside = again_ratio = float("nan")
        if resample:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                again = lpvid.resampled(res, resample)
            again_inside, again_ratio = coverage(again, true, case.freqs_hz, at)
        between = getattr(res, "between", None)
        count = getattr(between, "count", None)
        silent = float("nan") if count is None else count.silent
        if dump is not None and between is not None:
            dump.append(
                {
                    "case": name,
                    "N": n_points,
                    "draw": draw,
                    "G": res.model.frf(case.freqs_hz, at),
                    "true": true.frf(case.freqs_hz, at),
                    "band": None
                    if between.band is None
                    else between.band.frf_std(case.freqs_hz, at),
                    "members": [m.model.frf(case.freqs_hz, at) for m in between.members],
                    "names": [m.name for m in between.members],
                    "vnls": [m.vnls for m in between.members],
                    "stable": [m.stable for m in between.members],
                    "start": res.start,
                    "gamma": res.entry.gamma,
                    "model_vnls": res.entry.vnls,
                    "floor": res.entry.noise_floor,
                }
            )
        row = {
            "draw": draw,
            "error": err,
            "ratio": res.entry.vnls / res.entry.noise_floor,
            "groups": res.entry.n_groups,
            "coverage": inside,
            "spread_over_error": ratio,
            "coverage_resampled": again_inside,
            "spread_over_error_resampled": again_ratio,
            "silent": float(silent),
            "seconds": seconds,
            "warnings": len(caught),
        }
        where = np.array2string(np.round(data.p, 3).ravel(), separator=",")
        print(
            f"  {name} N={n_points} draw {draw}: error {err:.3g}, V/floor {row['ratio']:.3f}, "
            f"{row['groups']} groups, start {res.start}, silent {silent}, coverage {inside:.2f}, "
            f"spread/error {ratio:.3g}"
            + (
                f" (resampled: coverage {again_inside:.2f}, spread/error {again_ratio:.3g})"
                if resample
                else ""
            )
            + f", {seconds:.1f} s, {len(caught)} warning(s); p {where}",
            flush=True,
        )
        rows.append(row)
    return rows


def summary(name: str, n_points: int, rows: list[dict[str, float]]) -> str:
    """One line: the error's median, 90 % and worst, and what the spread says."""
    e = np.array([r["error"] for r in rows])
    misfits = sum(r["ratio"] > 2 for r in rows)
    seconds = statistics.median(r["seconds"] for r in rows)
    line = (
        f"## {name} N={n_points}: median {np.median(e):.3g}, 90 % {np.quantile(e, 0.9):.3g}, "
        f"worst {e.max():.3g}, above 0.02 {int(np.sum(e > 0.02))}/{e.size}, "
        f"V/floor > 2 {misfits}/{e.size}, median {seconds:.2f} s"
    )
    for label, key in (("", ""), ("resampled: ", "_resampled")):
        cov = [r[f"coverage{key}"] for r in rows if np.isfinite(r.get(f"coverage{key}", np.nan))]
        ratio = [
            r[f"spread_over_error{key}"]
            for r in rows
            if np.isfinite(r.get(f"spread_over_error{key}", np.nan))
        ]
        if cov:
            within = np.mean([(r >= 1) and (r <= 10) for r in ratio]) if ratio else float("nan")
            covered = np.mean(np.array(cov) >= 0.9)
            line += (
                f"; {label}coverage median {np.median(cov):.2f} (>= 0.9 in {covered:.0%}),"
                f" spread/error median {np.median(ratio):.3g}, in [1, 10] in {within:.0%}"
            )
    return line


def main() -> None:
    """Run the cases and print their rows and summaries."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="+", choices=list(CASES), default=list(CASES))
    parser.add_argument("--points", nargs="+", type=int, default=None)
    parser.add_argument("--draws", type=int, default=20)
    parser.add_argument("--first", type=int, default=0, help="the first draw")
    parser.add_argument("--json", default=None, help="write every row to this file")
    parser.add_argument("--dump", default=None, help="pickle the FRFs at the unseen points here")
    parser.add_argument(
        "--resample", type=int, default=0, help="also lpvid.resampled with so many runs"
    )
    args = parser.parse_args()
    out: dict[str, list[dict[str, float]]] = {}
    dump: list | None = [] if args.dump else None
    lines = []
    for name in args.cases:
        for n_points in args.points or CASES[name].default_points:
            rows = run(name, n_points, args.draws, dump, args.first, args.resample)
            out[f"{name} N={n_points}"] = rows
            lines.append(summary(name, n_points, rows))
            print(lines[-1], flush=True)
    print("\n".join(lines))
    if args.dump:
        with open(args.dump, "wb") as fh:
            pickle.dump(dump, fh)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(out, fh, indent=1)


if __name__ == "__main__":
    main()
