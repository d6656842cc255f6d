"""Cost laws: how each stage of identify() grows with n, l x r, N and F, one factor at a time.

Four series of ``benches/bench_scale.py`` problems (the same flexible
systems, noise and validation points), each varying one factor with the
others fixed:

- n = 6, 10, 16 at 2x2, Nb = 2, N = 7, F = 400 (n = 10 is the ladder's n10);
- l x r = 1x1, 2x2, 3x3 at n = 10, Nb = 2, N = 7, F = 400;
- N = 5, 9, 25 at the gantry's size (n = 6, 2x1, Nb = 4), F = 300 (N = 25 is points25);
- F = 300, 1000, 3000 at the gantry's size, N = 5 (F = 3000 is lines3000).

Each size runs ``--repeat`` times, each run in its own process; the medians
give, per series, the exponent ``a`` of ``time ~ factor^a`` (least squares
on the logarithms) for every stage (local models, the starts and their
race, the path, the refit and trust), for the time of one
Levenberg-Marquardt step of the starts and one cone step of the path, and
for the numbers of those steps. Then each stage is carried from the
largest size of a series to n = 64 and to N = 1000 by its law, to name the
term that will dominate there. Exponents from three sizes near the small
end are local slopes: a term whose cost is a higher power (the dense
factorisations, ~P^3 with P ~ n^2 parameters) takes over further out than
the fitted slope says, so the carried figures are a lower bound of the
growth, and the dominant term they name is the one already growing fastest.

Run: python benches/bench_laws.py [--repeat 3] [--json laws.json]
     python benches/bench_laws.py --from-json laws.json   (the report again)
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import time

import numpy as np
from bench_scale import Rung, run_one

SIZES = {
    "n6": Rung("n6", 6, 2, 2, 2, 7, 400, "n=6, 2x2, Nb=2, N=7, F=400"),
    "n10": Rung("n10", 10, 2, 2, 2, 7, 400, "n=10, 2x2, Nb=2, N=7, F=400"),
    "n16": Rung("n16", 16, 2, 2, 2, 7, 400, "n=16, 2x2, Nb=2, N=7, F=400"),
    "io1": Rung("io1", 10, 1, 1, 2, 7, 400, "n=10, 1x1, Nb=2, N=7, F=400"),
    "io3": Rung("io3", 10, 3, 3, 2, 7, 400, "n=10, 3x3, Nb=2, N=7, F=400"),
    "N5": Rung("N5", 6, 2, 1, 4, 5, 300, "n=6, 2x1, Nb=4, N=5, F=300"),
    "N9": Rung("N9", 6, 2, 1, 4, 9, 300, "n=6, 2x1, Nb=4, N=9, F=300"),
    "N25": Rung("N25", 6, 2, 1, 4, 25, 300, "n=6, 2x1, Nb=4, N=25, F=300"),
    "F1000": Rung("F1000", 6, 2, 1, 4, 5, 1000, "n=6, 2x1, Nb=4, N=5, F=1000"),
    "F3000": Rung("F3000", 6, 2, 1, 4, 5, 3000, "n=6, 2x1, Nb=4, N=5, F=3000"),
}

#: factor name -> (sizes of the series, the factor's value at each)
SERIES = {
    "n": (["n6", "n10", "n16"], [6, 10, 16]),
    "l x r": (["io1", "n10", "io3"], [1, 4, 9]),
    "N": (["N5", "N9", "N25"], [5, 9, 25]),
    "F": (["N5", "F1000", "F3000"], [300, 1000, 3000]),
}

#: row label -> how it is read from a run's figures
ROWS = {
    "local models": lambda r: r["timings"]["local_s"],
    "starts and race": lambda r: r["timings"]["smile_s"],
    "path": lambda r: r["timings"]["path_s"],
    "refit and trust": lambda r: r["timings"]["finish_s"],
    "identify": lambda r: r["timings"]["total_s"],
    "LM step": lambda r: r["lm_iter_s"],
    "cone step": lambda r: r["cone_step_s"],
    "LM steps (starts)": lambda r: r["lm_steps"],
    "cone steps (path)": lambda r: r["cone_steps"],
}
STAGES = ["local models", "starts and race", "path", "refit and trust"]


def slope(x: list[float], y: list[float]) -> float:
    """Least-squares slope of log y against log x."""
    lx, ly = np.log(x), np.log(y)
    return float(np.polyfit(lx, ly, 1)[0])


def measure(repeat: int) -> dict[str, list[dict]]:
    """``repeat`` runs of every size, each in its own process."""
    runs: dict[str, list[dict]] = {}
    for key in SIZES:
        runs[key] = []
        for _ in range(repeat):
            out = subprocess.run(
                [sys.executable, __file__, "--one", key],
                capture_output=True,
                text=True,
                check=True,
            )
            runs[key].append(json.loads(out.stdout.strip().splitlines()[-1]))
        r = runs[key]
        print(
            f"{key:6s} {SIZES[key].note:32s} identify "
            + ", ".join(f"{x['timings']['total_s']:.2f}" for x in r)
            + " s",
            flush=True,
        )
    return runs


def median(runs: list[dict], row: str) -> float:
    """Median of a row's figure over the runs of one size."""
    return statistics.median(ROWS[row](r) for r in runs)


def report(runs: dict[str, list[dict]]) -> None:
    """Medians per size, exponents per series, the stages carried to n = 64 and N = 1000."""
    print("\nmedian per size (s; steps as counts):")
    print(f"{'row':18s} " + " ".join(f"{k:>7s}" for k in SIZES))
    for row in ROWS:
        print(f"{row:18s} " + " ".join(f"{median(runs[k], row):7.3g}" for k in SIZES))
    print("\nexponent a of time ~ factor^a (one factor at a time):")
    print("| stage | " + " | ".join(SERIES) + " |")
    print("|---|" + "---|" * len(SERIES))
    for row in ROWS:
        cells = []
        for keys, values in SERIES.values():
            ys = [median(runs[k], row) for k in keys]
            ok = all(math.isfinite(y) and y > 0 for y in ys)
            cells.append(f"{slope(values, ys):.2f}" if ok else "-")
        print(f"| {row} | " + " | ".join(cells) + " |")
    for factor, target in (("n", 64), ("N", 1000)):
        keys, values = SERIES[factor]
        base = runs[keys[-1]]
        scale = target / values[-1]
        print(f"\ncarried by its law from {SIZES[keys[-1]].note} to {factor} = {target}:")
        guess = {}
        for row in STAGES:
            ys = [median(runs[k], row) for k in keys]
            if all(math.isfinite(y) and y > 0 for y in ys):
                guess[row] = median(base, row) * scale ** slope(values, ys)
        for row, t in sorted(guess.items(), key=lambda kv: -kv[1]):
            print(f"  {row:16s} {t:10.1f} s")
        print(f"  dominant: {max(guess, key=guess.get)}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--json", help="write every run's figures to this file")
    parser.add_argument("--from-json", help="report the runs of an earlier --json file")
    parser.add_argument("--one", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.one:
        print(json.dumps(run_one(SIZES[args.one])))
        return
    if args.from_json:
        with open(args.from_json) as fh:
            report(json.load(fh))
        return
    print(f"load average before: {os.getloadavg()}", flush=True)
    t0 = time.perf_counter()
    runs = measure(args.repeat)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(runs, fh, indent=1)
    report(runs)
    print(f"\nload average after: {os.getloadavg()} ({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
