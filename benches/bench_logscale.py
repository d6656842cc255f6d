"""The log scale on two known truths: where it is right and where it is wrong.

Each truth is measured at 10 noisy scheduling points (FRFs with 1 % noise,
``lpvid.testing.noisy_data``) and 2 noisy validation points, and
``lpvid.select`` (its default ``log_scale="auto"``) runs over orders and
polynomial degrees on the data's range; every pair is identified on the
linear and on the log scale. The error of a model is its worst relative
FRF error against the truth at 5 scheduling values no data were taken at
(``lpvid.testing.worst_relative_error``). Printed per truth: the error of
the pair select would choose from the linear-scale pairs alone (what
``log_scale=False`` returns), from the log-scale pairs alone, and of
select's own choice among all, with the goal: select's choice within 15 %
of the better of the two scales.

The two choices per scale are select's rule (``choose_pair``) applied to
that scale's rows of the one grid: identify returns the same model to the
last bit whichever grid a pair is run in, so this is what a select over
one scale returns, at a third of the cost.

- ``rod``: ``lpvid.testing.diffusion_rod``, a finite-difference heat rod
  whose conductivity on half the rod is the scheduling ``k`` in [0.1, 10];
  points spread evenly in ``log10(k)``. The log scale is right here.
- ``poly``: ``lpvid.testing.modal_lpv`` over p in [1, 30] (1.5 decades:
  the rule tries the log scale), three modes whose frequencies are
  quadratic in p itself; points spread evenly in p. The log scale is wrong
  here: the rule must not cost accuracy.

Every seed draws other noise; with ``--random`` it also draws the points:
the ends of the range and 8 between them uniformly (in ``log10(k)`` for
the rod, in p for the modes). The last lines sum up over the seeds.

Run: python benches/bench_logscale.py [--truth rod poly] [--states 101]
[--orders 4 6 8 10] [--degrees 2 3] [--seeds 0 1 2 3 4] [--random] [--table]
(``--orders 4 5 6 7 8 9 10`` is the grid of issue 61, 2.5 times as long.)
"""

from __future__ import annotations

import argparse
import time
import warnings
from typing import Any

import numpy as np
from numpy.typing import NDArray

import lpvid
import lpvid.testing
from lpvid.selection.result import choose_pair

NOISE = 0.01
GOAL = 1.15


def rod(states: int) -> dict[str, Any]:
    """The heat rod: conductivity from 0.1 to 10, points evenly in log10(k)."""
    true = lpvid.testing.diffusion_rod(states)
    return {
        "true": true,
        "freqs": np.geomspace(0.01, 10.0, 30),
        "p": np.geomspace(0.1, 10.0, 10),
        "p_val": 10.0 ** np.array([-0.6, 0.3]),
        "p_test": 10.0 ** np.array([-0.9, -0.45, 0.0, 0.45, 0.9]),
        "name": f"diffusion rod, {true.n_states} states, k in [0.1, 10] (log scale right)",
        "log": True,
    }


def poly(states: int) -> dict[str, Any]:
    """Three modes whose frequencies are quadratic in p over [1, 30], points evenly in p."""
    true = lpvid.testing.modal_lpv(
        [[8.0, 3.0, 1.0], [20.0, -4.0, 2.0], [40.0, 6.0, -2.0]],
        damping=0.03,
        l=1,
        domain=(1.0, 30.0),
    )
    return {
        "true": true,
        "freqs": np.linspace(2.0, 60.0, 60),
        "p": np.linspace(1.0, 30.0, 10),
        "p_val": np.array([6.0, 21.0]),
        "p_test": np.array([2.5, 9.0, 15.5, 19.0, 28.0]),
        "name": "three modes quadratic in p over [1, 30] (log scale wrong)",
        "log": False,
    }


def drawn(case: dict[str, Any], rng: np.random.Generator, log: bool) -> NDArray[np.float64]:
    """The ends of the case's points and 8 drawn between them (uniformly in log10 if ``log``)."""
    lo, hi = case["p"][0], case["p"][-1]
    if log:
        inner = 10.0 ** rng.uniform(np.log10(lo), np.log10(hi), 8)
    else:
        inner = rng.uniform(lo, hi, 8)
    return np.concatenate([[lo], np.sort(inner), [hi]])


def run(
    case: dict[str, Any], orders: list[int], degrees: list[int], seed: int, random: bool = False
) -> dict:
    rng = np.random.default_rng(seed)
    true, f = case["true"], case["freqs"]
    p = drawn(case, rng, case["log"]) if random else case["p"]
    data = lpvid.testing.noisy_data(true, p, f, rng, NOISE)
    val = lpvid.testing.noisy_data(true, case["p_val"], f, rng, NOISE)
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lpvid.ConvergenceWarning)
        sel = lpvid.select(data, orders, degrees, validation=val)
    seconds = time.perf_counter() - t0

    def error(row: Any) -> float:
        return lpvid.testing.worst_relative_error(row.result.model, true, f, case["p_test"])

    out = {"sel": sel, "seconds": seconds}
    for scale in ("linear", "log"):
        rows = [r for r in sel.grid if r.basis.scales[0] == scale]
        k, _ = choose_pair(rows, sel.rule, sel.tolerance)
        out[scale] = (rows[k], error(rows[k]))
    out["select"] = (sel.row, error(sel.row))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--truth", nargs="+", default=["rod", "poly"], choices=["rod", "poly"])
    parser.add_argument("--states", type=int, default=101, help="cells of the heat rod")
    parser.add_argument("--orders", type=int, nargs="+", default=[4, 6, 8, 10])
    parser.add_argument("--degrees", type=int, nargs="+", default=[2, 3])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4])
    parser.add_argument("--random", action="store_true", help="draw the points (module notes)")
    parser.add_argument("--table", action="store_true", help="print select's table too")
    args = parser.parse_args()
    ratios: dict[str, list[float]] = {}
    for name, seed in ((n, s) for n in args.truth for s in args.seeds):
        case = {"rod": rod, "poly": poly}[name](args.states)
        out = run(case, args.orders, args.degrees, seed, args.random)
        sel = out["sel"]
        print(f"{case['name']}: orders {args.orders}, degrees {args.degrees}, seed {seed}")
        print(f"  select: {len(sel.grid)} pairs in {out['seconds']:.1f} s ({sel.rule} rule)")
        for what in ("linear", "log", "select"):
            row, err = out[what]
            label = {"linear": "linear scale only", "log": "log scale only"}.get(what, "select")
            print(f"  {label:<18} {row.label:<22} worst relative error {err:.4f}")
        best = min(out["linear"][1], out["log"][1])
        ratio = out["select"][1] / best
        ratios.setdefault(name, []).append(ratio)
        verdict = "met" if ratio <= GOAL else "NOT met"
        print(f"  select / better scale: {ratio:.3f} (goal <= {GOAL}: {verdict})")
        print(f"  scale: {sel.scale_note}")
        if args.table:
            print(sel.table())
        print()
    for name, values in ratios.items():
        met = sum(r <= GOAL for r in values)
        print(
            f"{name}: select's error / the better scale's: worst {max(values):.3f} over "
            f"{len(values)} seeds; goal met in {met} of {len(values)}"
        )


if __name__ == "__main__":
    main()
