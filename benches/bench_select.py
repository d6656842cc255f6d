"""Wall time of lpvid.select on the gantry: a 5 x 3 grid on 1 and 2 threads and on Dask.

The grid: orders 4..8 and polynomial degrees 2..4 on the built-in gantry
(5 identification points, validation at 4 more), each pair a whole
``lpvid.identify`` run. Runs once per executor (the grid takes minutes):

- a thread pool with 1 worker (the pairs one after the other; each fit
  still spreads over the cores),
- a thread pool with 2 workers (lpvid's default on a 2-core machine),
- a Dask ``LocalCluster`` of 2 worker processes with 1 thread each.

Prints the wall times, the chosen pair and whether every executor gave the
same grid to the last bit. The machines are shared and noisy.

Run: python benches/bench_select.py [--lines 300] [--skip-dask]
"""

from __future__ import annotations

import argparse
import time
import warnings
from concurrent.futures import ThreadPoolExecutor

import lpvid


def run(data, val, executor) -> tuple[float, lpvid.SelectResult]:
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lpvid.ConvergenceWarning)
        sel = lpvid.select(data, range(4, 9), range(2, 5), validation=val, executor=executor)
    return time.perf_counter() - t0, sel


def grid_numbers(sel: lpvid.SelectResult) -> list[tuple]:
    return [(r.order, len(r.basis), r.vnls, r.validation_vnls, r.error) for r in sel.grid]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--lines", type=int, default=300, help="frequency lines of the gantry")
    parser.add_argument("--skip-dask", action="store_true", help="threads only")
    args = parser.parse_args()
    ds = lpvid.datasets.gantry(n_lines=args.lines)
    data, val = ds.identification, ds.validation
    results = {}
    for workers in (1, 2):
        with ThreadPoolExecutor(workers) as pool:
            results[f"threads x {workers}"] = run(data, val, pool)
    if not args.skip_dask:
        from distributed import Client, LocalCluster

        with (
            LocalCluster(
                n_workers=2, processes=True, threads_per_worker=1, dashboard_address=":0"
            ) as cluster,
            Client(cluster) as client,
        ):
            results["Dask LocalCluster 2 x 1"] = run(data, val, client.get_executor())
    first = next(iter(results.values()))[1]
    print(f"gantry, {args.lines} lines, orders 4..8 x degrees 2..4 (15 identify runs)")
    for name, (seconds, sel) in results.items():
        same = grid_numbers(sel) == grid_numbers(first)
        print(f"  {name:<24} {seconds:7.1f} s   chosen {sel.row.label}   same grid: {same}")
    print()
    print(first.table())


if __name__ == "__main__":
    main()
