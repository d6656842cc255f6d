"""Is the model right between the points? identify() on systems with a known truth, over seeds.

Cases (1 % noise, ``lpvid.testing.noisy_data``; identify's defaults with D fixed):

- ``val5``: :func:`lpvid.testing.one_group_lpv` (10 states, SISO, one group
  ``A(1)``), 5 points on [0, 1], validation at mu = 0.3 and 0.7, quadratic
  basis: validation V_NLS over its floor of the path's entry, of the model
  returned and of the truth (the noise realisation's own level);
- ``noval6``: the same system at 6 points, no validation data: the worst
  relative FRF error (:func:`lpvid.testing.worst_relative_error`) at 20
  unseen mu in [0.03, 0.97];
- ``more``: the same system without validation data at 3 points (0.02,
  0.5, 1.0), then with a fourth at 0.75, 0.1 and 0.05 (and each of those
  with a fifth at 0.25): the worst relative error before and after the
  point is added;
- ``cross2``, ``cross3``: :func:`lpvid.testing.crossing_lpv` (10 states,
  3 outputs x 2 inputs, two modes crossing) on a 3x3 and a 3x3x3 grid,
  total-degree-2 basis, validation at 4 random points: validation V/floor
  and worst relative error at 20 random unseen points;
- ``gantry``, ``stage``: the built-in sets (the seed sets their noise) with
  their validation data; ``gantry-noval``, ``stage-noval`` without, judged
  after on them.

Every row gives the groups kept, whether the refit was kept, and seconds.
Summary lines give the median and the worst over the seeds.

Run: python benches/bench_between.py [--cases val5 noval6 ...] [--seeds 8] [--lines 200]
"""

from __future__ import annotations

import argparse
import itertools
import statistics
import time
import warnings
from collections.abc import Callable

import numpy as np

import lpvid
from lpvid.testing import crossing_lpv, noisy_data, one_group_lpv, worst_relative_error

FIXED = {"D": True}
UNSEEN = np.linspace(0.03, 0.97, 20)


def _identify(
    data: lpvid.FrfData,
    n: int,
    basis: lpvid.Basis,
    val: lpvid.FrfData | None,
    fixed: object = FIXED,
):
    t = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = lpvid.identify(data, n, basis, validation=val, fixed=fixed)
    return res, time.perf_counter() - t, [str(w.message) for w in caught]


def _ratio(model: lpvid.LpvModel, val: lpvid.FrfData) -> float:
    return lpvid.vnls(model, val) / val.n_residuals


def _row(label: str, res, seconds: float, warns: list[str], extra: str) -> None:
    e = res.entry
    print(
        f"  {label}: gamma {e.gamma:g}, {e.n_groups} groups {_groups(e.nonzero_groups)}, "
        f"{'refit kept' if _refitted(res) else 'entry returned'}; {extra}; {seconds:.1f} s"
        + (f"; {len(warns)} warning(s): {warns[0][:80]}" if warns else "")
    )


def _refitted(res) -> bool:
    # (getattr: the same script measures commits from before IdentifyResult.refitted)
    return bool(getattr(res, "refitted", res.refit is not None))


def _groups(nz: dict[str, list[int]]) -> str:
    return "{" + ", ".join(f"{x}: {v}" for x, v in nz.items() if v) + "}"


def val5(seed: int, lines: int) -> dict[str, float]:
    """One group, 5 points, validation at 0.3 and 0.7."""
    true, f = one_group_lpv(seed), np.linspace(2, 100, lines)
    rng = np.random.default_rng(1000 + seed)
    data = noisy_data(true, np.linspace(0, 1, 5), f, rng, 0.01)
    val = noisy_data(true, [0.3, 0.7], f, rng, 0.01)
    res, s, w = _identify(data, 10, true.basis, val)
    out = {
        "entry": _ratio(res.entry.model, val),
        "returned": _ratio(res.model, val),
        "truth": _ratio(true, val),
        "unregularised": _ratio(res.entries[0].model, val),
        "groups": res.entry.n_groups,
        "rel": worst_relative_error(res.model, true, f, UNSEEN),
    }
    _row(f"seed {seed}", res, s, w, ", ".join(f"{k} {v:.4g}" for k, v in out.items()))
    return out


def noval6(seed: int, lines: int) -> dict[str, float]:
    """One group, 6 points, no validation data: worst relative error between the points."""
    true, f = one_group_lpv(seed), np.linspace(2, 100, lines)
    rng = np.random.default_rng(2000 + seed)
    data = noisy_data(true, np.linspace(0, 1, 6), f, rng, 0.01)
    res, s, w = _identify(data, 10, true.basis, None)
    out = {
        "entry": worst_relative_error(res.entry.model, true, f, UNSEEN),
        "returned": worst_relative_error(res.model, true, f, UNSEEN),
        "unregularised": worst_relative_error(res.entries[0].model, true, f, UNSEEN),
        "groups": res.entry.n_groups,
    }
    _row(f"seed {seed}", res, s, w, ", ".join(f"{k} {v:.4g}" for k, v in out.items()))
    return out


def more(seed: int, lines: int) -> dict[str, float]:
    """Worst relative error before and after one more point (no validation data)."""
    true, f = one_group_lpv(seed), np.linspace(2, 100, lines)
    out: dict[str, float] = {}
    ladders = [[0.02, 0.5, 1.0, extra, 0.25] for extra in (0.75, 0.1, 0.05)]
    for ladder in ladders:
        rng = np.random.default_rng(3000 + seed)
        full = noisy_data(true, ladder, f, rng, 0.01)  # the same noise at the same points
        errs = []
        for k in (3, 4, 5):
            res, s, w = _identify(full.subset(list(range(k))), 10, true.basis, None)
            errs.append(worst_relative_error(res.model, true, f, UNSEEN))
            _row(f"seed {seed}, points {ladder[:k]}", res, s, w, f"worst rel {errs[-1]:.4g}")
        out[f"{ladder[3]}: 3->4"] = errs[1] / errs[0]
        out[f"{ladder[3]}: 4->5"] = errs[2] / errs[1]
    return out


def _crossing(k: int) -> Callable[[int, int], dict[str, float]]:
    def case(seed: int, lines: int) -> dict[str, float]:
        true = crossing_lpv(k)
        f = np.linspace(4, 100, lines)
        rng = np.random.default_rng(4000 + seed)
        grid = np.array(list(itertools.product([0.0, 0.5, 1.0], repeat=k)))
        data = noisy_data(true, grid, f, rng, 0.01)
        val = noisy_data(true, rng.uniform(0.1, 0.9, size=(4, k)), f, rng, 0.01)
        unseen = rng.uniform(0.05, 0.95, size=(20, k))
        res, s, w = _identify(data, 10, true.basis, val)
        out = {
            "entry": _ratio(res.entry.model, val),
            "returned": _ratio(res.model, val),
            "truth": _ratio(true, val),
            "groups": res.entry.n_groups,
            "rel": worst_relative_error(res.model, true, f, unseen),
        }
        _row(f"seed {seed}", res, s, w, ", ".join(f"{k} {v:.4g}" for k, v in out.items()))
        return out

    case.__doc__ = (
        f"Crossing modes, {k} scheduling parameters on a 3^{k} grid, validation at 4 points."
    )
    return case


def _builtin(name: str, with_validation: bool) -> Callable[[int, int], dict[str, float]]:
    def case(seed: int, lines: int) -> dict[str, float]:
        ds = getattr(lpvid.datasets, name)(seed=seed)
        val = ds.validation if with_validation else None
        res, s, w = _identify(ds.identification, ds.order, ds.basis, val, ds.fixed)
        out = {
            "entry": _ratio(res.entry.model, ds.validation),
            "returned": _ratio(res.model, ds.validation),
            "groups": res.entry.n_groups,
        }
        _row(f"seed {seed}", res, s, w, ", ".join(f"{k} {v:.4g}" for k, v in out.items()))
        return out

    case.__doc__ = f"The built-in {name} (seed of its noise), " + (
        "with its validation data." if with_validation else "judged after on its validation data."
    )
    return case


CASES = {
    "val5": val5,
    "noval6": noval6,
    "more": more,
    "cross2": _crossing(2),
    "cross3": _crossing(3),
    "gantry": _builtin("gantry", True),
    "gantry-noval": _builtin("gantry", False),
    "stage": _builtin("positioning_stage", True),
    "stage-noval": _builtin("positioning_stage", False),
}


def main() -> None:
    """Run the cases and print their rows and summaries."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="+", choices=list(CASES), default=list(CASES))
    parser.add_argument("--seeds", type=int, default=4)
    parser.add_argument("--lines", type=int, default=200)
    args = parser.parse_args()
    for name in args.cases:
        print(f"\n== {name}: {CASES[name].__doc__}", flush=True)
        rows = [CASES[name](seed, args.lines) for seed in range(args.seeds)]
        for key in rows[0]:
            values = [r[key] for r in rows]
            print(
                f"  {key}: median {statistics.median(values):.4g}, "
                f"min {min(values):.4g}, max {max(values):.4g}",
                flush=True,
            )


if __name__ == "__main__":
    main()
