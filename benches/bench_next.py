"""Where to measure next: does the suggested point help more than the middle of the largest gap?

On systems with a known truth, 1 % noise (``lpvid.testing.noisy_data``),
identify's defaults with D fixed and no validation data, starting from
``N = Nb + 1`` points:

- ``one``: :func:`lpvid.testing.one_group_lpv` (10 states, SISO,
  ``Polynomial(2, domain=(0, 1))``) at 0, u and 1 with u drawn from
  [0.3, 0.7] per seed;
- ``one-noisy-end``: the same with the point at 1 measured with 10 times
  the noise (a bad day on the bench); the next measurement has the
  ordinary noise, and ``next_points`` is told so (``sigma=``);
- ``two``: :func:`lpvid.testing.crossing_lpv` (2 scheduling parameters,
  3 modes, 3 % damping: 6 states, 3 outputs x 2 inputs, 5 basis
  functions) at the 4 corners of [0, 1]^2 and 2 points drawn from
  [0.2, 0.8]^2 per seed.

For every seed the model identified from the start is given ``k`` more
points (default 1), chosen either by :func:`lpvid.next_points` or as the
middle of the largest gap between the measured points (two parameters:
the default candidate farthest from every measured point; ``k > 1``: one
after the other), each measured with the same 1 % noise for both
strategies, and identified again. The figure is the worst relative FRF
error against the truth (:func:`lpvid.testing.worst_relative_error`) over
a fine grid of the range (41 values; 11 x 11). Summary lines give the
median, the quartiles and the worst over the seeds, and how often each
strategy was better.

Run: python benches/bench_next.py [--cases one one-noisy-end two] [--seeds 20] [--lines 100] [--k 1]
"""

from __future__ import annotations

import argparse
import time
import warnings
from collections.abc import Callable

import numpy as np

import lpvid
from lpvid.testing import crossing_lpv, noisy_data, one_group_lpv, worst_relative_error

FIXED = {"D": True}
NOISE = 0.01


def _identify(data: lpvid.FrfData, order: int, basis: lpvid.Basis) -> lpvid.IdentifyResult:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # unstable frozen models are part of what is measured
        return lpvid.identify(data, order, basis, fixed=FIXED)


def farthest(measured: np.ndarray, candidates: np.ndarray, k: int) -> np.ndarray:
    """``k`` candidates, each the farthest from the measured ones and those chosen before.

    Distances in the scheduling values as given (the ranges here are [0, 1]);
    ties go to the first candidate. In one dimension: the middle of the
    largest gap.
    """
    pts = measured.reshape(len(measured), -1)
    cands = candidates.reshape(len(candidates), -1)
    out = []
    for _ in range(k):
        d = np.min(np.linalg.norm(cands[:, None, :] - pts[None, :, :], axis=2), axis=1)
        best = cands[int(np.argmax(d))]
        out.append(best)
        pts = np.vstack([pts, best])
    arr = np.array(out)
    return arr[:, 0] if measured.ndim == 1 else arr


def suggested(res: lpvid.IdentifyResult, k: int, sigma: np.ndarray | None) -> np.ndarray:
    """:func:`lpvid.next_points` with its default candidates."""
    return lpvid.next_points(res, k=k, sigma=sigma)


def gap(res: lpvid.IdentifyResult, k: int, sigma: np.ndarray | None) -> np.ndarray:
    """The middle of the largest gap (one parameter), else the farthest default candidate."""
    p = res.data.p
    if p.ndim == 1:
        pts = np.sort(p)
        out = []
        for _ in range(k):
            i = int(np.argmax(np.diff(pts)))
            out.append(0.5 * (pts[i] + pts[i + 1]))
            pts = np.sort(np.append(pts, out[-1]))
        return np.array(out)
    grid = lpvid.experiment.nextpoints.default_candidates(res.data.p_range, p)
    return farthest(p, grid, k)


STRATEGIES: dict[str, Callable[[lpvid.IdentifyResult, int, np.ndarray | None], np.ndarray]] = {
    "suggested": suggested,
    "gap": gap,
}


def _one(seed: int, lines: int) -> dict[str, object]:
    true = one_group_lpv(seed)
    u = 0.3 + 0.4 * np.random.default_rng(500 + seed).random()
    return {
        "true": true,
        "start": np.array([0.0, u, 1.0]),
        "f": np.linspace(2, 100, lines),
        "fine": np.linspace(0, 1, 41),
        "order": 10,
    }


def _one_noisy_end(seed: int, lines: int) -> dict[str, object]:
    case = _one(seed, lines)
    case["noisier"] = 2  # the point at 1 measured with 10 times the noise
    return case


def _two(seed: int, lines: int) -> dict[str, object]:
    true = crossing_lpv(2, modes=3, damping=0.03)
    rng = np.random.default_rng(500 + seed)
    corners = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
    while True:  # 6 points that determine a quadratic in two parameters
        start = np.vstack([corners, rng.uniform(0.2, 0.8, size=(2, 2))])
        psi = true.basis_values(start)
        if np.linalg.cond(np.hstack([np.ones((6, 1)), psi])) < 1e4:
            break
    g = np.linspace(0, 1, 11)
    return {
        "true": true,
        "start": start,
        "f": np.linspace(4, 100, lines),
        "fine": np.array([(a, b) for a in g for b in g]),
        "order": 6,
    }


CASES = {"one": _one, "one-noisy-end": _one_noisy_end, "two": _two}


def _data(case: dict, seed: int) -> tuple[lpvid.FrfData, np.ndarray | None]:
    """The start's data, and the sigma of a new measurement to pass (None: the default)."""
    true, start, f = case["true"], case["start"], case["f"]
    rng = np.random.default_rng(seed)
    data = noisy_data(true, start, f, rng, NOISE)
    q = case.get("noisier")
    if q is None:
        return data, None
    sigma = data.sigma.copy()
    sigma[q] *= 10.0
    G = true.frf(f, start)
    noise = (rng.normal(size=G.shape) + 1j * rng.normal(size=G.shape)) / np.sqrt(2)
    # The next measurement has the ordinary noise: say so (the default would
    # take the noisier point's sigma near it).
    ordinary = data.sigma[[i for i in range(len(start)) if i != q]].mean(axis=0)
    return lpvid.FrfData(start, f, G + sigma * noise, sigma, Ts=true.Ts), ordinary


def run_case(name: str, seeds: int, lines: int, k: int) -> dict[str, list[float]]:
    """Print one row per seed and return the errors per strategy (and of the start)."""
    errors: dict[str, list[float]] = {"start": [], **{s: [] for s in STRATEGIES}}
    for seed in range(seeds):
        case = CASES[name](seed, lines)
        true, f, fine, order = case["true"], case["f"], case["fine"], case["order"]
        data, sigma = _data(case, seed)
        t = time.perf_counter()
        res = _identify(data, order, true.basis)
        errors["start"].append(worst_relative_error(res.model, true, f, fine))
        row = [f"start {errors['start'][-1]:.3g}"]
        for sname, strategy in STRATEGIES.items():
            ts = time.perf_counter()
            pts = strategy(res, k, sigma)
            choose_s = time.perf_counter() - ts
            # The same noise at the new points for every strategy.
            extra = noisy_data(true, pts, f, np.random.default_rng(10_000 + seed), NOISE)
            more = _identify(lpvid.FrfData.stack([data, extra]), order, true.basis)
            errors[sname].append(worst_relative_error(more.model, true, f, fine))
            where = "; ".join(
                ", ".join(f"{x:.2f}" for x in np.atleast_1d(p)) for p in np.atleast_1d(pts)
            )
            row.append(f"{sname} [{where}] {errors[sname][-1]:.3g} ({choose_s:.2f} s)")
        print(
            f"  seed {seed}: " + "; ".join(row) + f"; {time.perf_counter() - t:.0f} s", flush=True
        )
    return errors


def summary(errors: dict[str, list[float]]) -> list[str]:
    """Median, quartiles and worst per strategy; wins of the suggestion over the gap."""
    lines = []
    for name, vals in errors.items():
        q = np.percentile(vals, [25, 50, 75])
        lines.append(
            f"  {name:>9}: median {q[1]:.3g} (quartiles {q[0]:.3g}-{q[2]:.3g}), "
            f"worst {max(vals):.3g}, mean {np.mean(vals):.3g}"
        )
    s, g = np.array(errors["suggested"]), np.array(errors["gap"])
    ratio = s / g
    q = np.percentile(ratio, [25, 50, 75])
    lines.append(
        f"  suggested / gap: median {q[1]:.3g} (quartiles {q[0]:.3g}-{q[2]:.3g}); suggested "
        f"lower in {int(np.sum(s < g))} of {len(s)} seeds, higher in {int(np.sum(s > g))}"
    )
    return lines


def main() -> None:
    """Run the cases and print their rows and summaries."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="+", choices=list(CASES), default=list(CASES))
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--lines", type=int, default=100)
    parser.add_argument("--k", type=int, default=1)
    args = parser.parse_args()
    for name in args.cases:
        print(f"{name}: {args.seeds} seeds, {args.lines} lines, k = {args.k}")
        errors = run_case(name, args.seeds, args.lines, args.k)
        print("\n".join(summary(errors)), flush=True)


if __name__ == "__main__":
    main()
