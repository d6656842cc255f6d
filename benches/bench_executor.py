"""identify() without an executor against identify(..., executor=threads).

Without an executor a large run takes its pieces one after the other, and
since 2026-11-29 a small one (peak estimate at most 256 MiB: the gantry,
n = 10) spreads them over threads of its own (``lpvid._spread.own_threads``).
For each rung of ``benches/bench_scale.py`` (its data, order and basis), runs
``lpvid.identify`` alternately without an executor and with a
``ThreadPoolExecutor`` of ``--threads`` workers, ``--repeat`` times each
after one warm-up run of each, checks that both choose the same entry with
the same theta to the last bit, and prints the median time of every stage
for both and their ratio. The core already spreads one fit over the cores
(rayon), so this measures what running independent fits side by side adds
on top. Alternating keeps slow phases of a shared machine from favouring
one side; the load average is printed before and after.

Run: python benches/bench_executor.py [--rungs gantry n10 n16] [--repeat 3] [--threads 2]
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
import warnings
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from bench_scale import RUNGS, problem

import lpvid

STAGES = ("local_s", "smile_s", "path_s", "finish_s", "total_s")


def run(name: str, repeat: int, threads: int) -> None:
    data, validation, n, basis, note = problem(name)
    times: dict[str, list[dict[str, float]]] = {"here": [], "threads": []}
    reference = None
    for k in range(repeat + 1):  # the first round warms up
        for side in ("here", "threads") if k % 2 == 0 else ("threads", "here"):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                if side == "here":
                    res = lpvid.identify(data, n, basis, validation=validation)
                else:
                    with ThreadPoolExecutor(threads) as pool:
                        res = lpvid.identify(data, n, basis, validation=validation, executor=pool)
            key = (res.chosen, res.model.theta.tobytes())
            if reference is None:
                reference = key
            elif key != reference:
                raise AssertionError(f"{name}: the {side} run chose another model")
            if k > 0:
                times[side].append(res.timings)
    print(f"\n== {name}: {note}; {repeat} alternating pairs, {threads} threads")
    print(f"{'stage':10s} {'here':>8s} {'threads':>8s} {'ratio':>6s}")
    for stage in STAGES:
        a = statistics.median(t[stage] for t in times["here"])
        b = statistics.median(t[stage] for t in times["threads"])
        print(f"{stage:10s} {a:8.2f} {b:8.2f} {b / a if a else np.nan:6.2f}")
    print("same chosen entry and theta to the last bit in every run")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rungs", nargs="+", default=["gantry", "n10", "n16"], choices=list(RUNGS))
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args()
    print(f"load average before: {os.getloadavg()}")
    t0 = time.perf_counter()
    for name in args.rungs:
        run(name, args.repeat, args.threads)
    print(f"\nload average after: {os.getloadavg()} ({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
