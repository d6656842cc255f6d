"""Is the spread's band right beyond first order? The band before and after its check.

The spread between the points (``result.between.spread``) adds a 95 %
band of the directions the points see to the committee's part. First
order, that band was ten or more times the actual error on many draws of
few points while the model was right (``benches/bench_few.py``): along its
leading directions V_NLS rises far faster than first order says.
:func:`lpvid.trust.profile.checked_band` narrows it there to where a
profile of V_NLS allows (its module notes). This script measures both on
the draws of ``bench_few.py`` (the same systems, placements and noise;
identify's defaults with D fixed, no validation data).

Printed per draw: the worst error, the first-order and the checked band's
worst relative width over the error, the factor on each leading direction
(:attr:`lpvid.pipeline.between.Between.check`) and the check's seconds;
per (case, points): the share of draws whose spread covers the truth at
nine in ten (line, point) pairs and the share within ten times the actual
worst error (as ``bench_few.py``), first order and checked, and the
median seconds of the check.

Run: python benches/bench_band.py [--cases mor onegroup cross2] [--points 4 5]
     [--draws 20]
"""

from __future__ import annotations

import argparse
import time
import types
import warnings
from dataclasses import replace

import numpy as np
from bench_few import CASES, FIXED, coverage, measured, unseen

import lpvid
from lpvid.testing import worst_relative_error
from lpvid.trust.uncertainty import band_radius


def first_order(between):
    """A copy of ``between`` whose band is the first-order one (the check undone)."""
    other = replace(between)
    other.__dict__.update(_open=between._open, _checked=(between._seen, None))
    return other


def main() -> None:
    """Run the draws and print the rows and summaries."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="+", choices=sorted(CASES), default=["mor"])
    parser.add_argument("--points", nargs="+", type=int, default=None)
    parser.add_argument("--draws", type=int, default=20)
    args = parser.parse_args()
    lines = []
    for name in args.cases:
        case = CASES[name]
        for n_points in args.points or case.default_points:
            seen = {"first order": [], "checked": []}
            times = []
            for draw in range(args.draws):
                true, data, lo, hi = measured(case, n_points, draw)
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    res = lpvid.identify(data, case.n, true.basis, fixed=FIXED)
                at, f = unseen(case, lo, hi), case.freqs_hz
                err = worst_relative_error(res.model, true, f, at)
                b = res.between
                t0 = time.perf_counter()
                check = b.check
                times.append(time.perf_counter() - t0)
                if check is None:
                    print(f"  {name} N={n_points} draw {draw}: no band ({b.note})", flush=True)
                    continue
                before = first_order(b)
                for key, between in (("first order", before), ("checked", b)):
                    view = types.SimpleNamespace(model=res.model, between=between)
                    seen[key].append(coverage(view, true, f, at))
                width = [
                    np.max(
                        np.linalg.norm(
                            (band_radius(0.95) * c.frf_std(f, at)).reshape(len(at), -1),
                            axis=1,
                        )
                        / np.linalg.norm(true.frf(f, at).reshape(len(at), -1), axis=1)
                    )
                    / err
                    for c in (before.band, b.band)
                ]
                print(
                    f"  {name} N={n_points} draw {draw}: error {err:.4f}, band/error "
                    f"{width[0]:.3g} -> {width[1]:.3g}; leading directions scaled by "
                    f"{' '.join(f'{r:.2g}' for r in check.scales)}; {times[-1]:.2f} s",
                    flush=True,
                )
            parts = []
            for key, rows in seen.items():
                cover = np.mean([inside >= 0.9 for inside, _ in rows])
                within = np.mean([1 <= ratio <= 10 for _, ratio in rows])
                median = np.median([ratio for _, ratio in rows])
                parts.append(
                    f"{key}: covers {cover:.0%}, within 10x {within:.0%}, spread/error "
                    f"median {median:.3g}"
                )
            head = f"## {name} N={n_points} ({len(seen['checked'])} draws): "
            tail = f"; the check's median {np.median(times):.2f} s"
            lines.append(head + "; ".join(parts) + tail)
            print(lines[-1], flush=True)
    print("\n".join(lines))


if __name__ == "__main__":
    main()
