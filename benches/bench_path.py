"""The l2,1 path of identify on the built-in sets: groups, accuracy and interpolation.

For each set, with and without its validation data, runs
``lpvid.identify(..., refit=False)`` and prints every entry of the path:
groups kept, V_NLS over its floor, validation V_NLS over its floor (judged
afterwards when the run had no validation data), whether the fit was
pinned (its steps kept off the directions that are flat at the data,
:mod:`lpvid.pipeline.path`), cone steps and seconds; then the chosen entry and the
time of the path and of the whole run.

Run: python benches/bench_path.py [--sets stage gantry]
"""

from __future__ import annotations

import argparse
import time
import warnings

import lpvid

SETS = {"stage": lpvid.datasets.positioning_stage, "gantry": lpvid.datasets.gantry}


def run(name: str, with_validation: bool) -> None:
    """One identify run and its table."""
    ds = SETS[name]()
    val = ds.validation
    t = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lpvid.ConvergenceWarning)
        res = lpvid.identify(
            ds.identification,
            ds.order,
            ds.basis,
            validation=val if with_validation else None,
            fixed=ds.fixed,
            refit=False,
        )
    total = time.perf_counter() - t
    steps = [0] + [r.n_iter for r in res.path.results]
    print(f"\n{name}, {'with' if with_validation else 'without'} validation data")
    print(f"  {'gamma':>7} {'groups':>6} {'V/floor':>8} {'val/floor':>9} {'steps':>5} {'s':>6}")
    for k, e in enumerate(res.entries):
        v = lpvid.vnls(e.model, val) / val.n_residuals
        mark = "->" if k == res.chosen else "  "
        print(
            f"{mark}{e.gamma:7.3g} {e.n_groups:6d} {e.vnls / e.noise_floor:8.4f} {v:9.4f} "
            f"{steps[k]:5d} {e.seconds:6.2f}" + ("  pinned" if e.pinned else "")
        )
    print(f"  chosen: {res.reason}")
    print(f"  path {res.timings['path_s']:.2f} s, identify {total:.2f} s")


def main() -> None:
    """Every set, with and without validation data."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--sets", nargs="+", choices=sorted(SETS), default=["stage", "gantry"])
    args = parser.parse_args()
    for name in args.sets:
        for with_validation in (True, False):
            run(name, with_validation)


if __name__ == "__main__":
    main()
