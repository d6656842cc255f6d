"""Where the time of ``lpvid demo`` goes: import, identify, the report and each figure.

Runs what ``lpvid demo`` runs (identify on the built-in gantry with its
validation data, then the report with its figures) in this process, and
prints the seconds of each part: importing lpvid, identify and its stages,
then for each figure the time to build it and the time to save it (layout,
drawing and PNG encoding), and the rest of the report (the trust section's
stability check, the model and result files). The first figure also pays
for importing matplotlib.pyplot. With ``--repeat`` the report is written
again that many times and the medians are printed (a warm process: what the
figures cost without the imports). Last, the whole report as ``lpvid demo``
writes it: the figures drawn by a :class:`lpvid.report.markdown.FigurePool` whose
workers started while identify ran (a pause as long as identify stands in).

Run: python benches/bench_demo.py [--repeat 3] [--data gantry|stage]
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time
import warnings
from collections import defaultdict
from pathlib import Path

t_import = time.perf_counter()
import lpvid  # noqa: E402
from lpvid import plots, report  # noqa: E402

IMPORT_S = time.perf_counter() - t_import

#: The figure builders the report calls (lpvid.report.markdown._figures).
BUILDERS = (
    "frf_fit",
    "magnitude_surface",
    "frf_band",
    "frf_std_map",
    "group_norms",
    "accuracy_path",
)


def timed_report(result: lpvid.IdentifyResult, ds: object, folder: Path) -> dict[str, float]:
    """Write the report once; seconds per part (builders and saves by name)."""
    times: dict[str, float] = defaultdict(float)
    originals = {name: getattr(plots, name) for name in (*BUILDERS, "save")}

    def wrap(name: str):
        def call(*args, **kwargs):
            t = time.perf_counter()
            out = originals[name](*args, **kwargs)
            key = f"save {Path(args[1]).name}" if name == "save" else f"build {name}"
            while key in times:  # the same builder for another figure
                key += "'"
            times[key] = time.perf_counter() - t
            return out

        return call

    try:
        for name in originals:
            setattr(plots, name, wrap(name))
        t = time.perf_counter()
        report.write_report(
            result,
            folder,
            title="bench",
            description=None,
            figures=True,
            inputs=ds.inputs,
            outputs=ds.outputs,
            p_label=ds.scheduling,
        )
        total = time.perf_counter() - t
    finally:
        for name, fn in originals.items():
            setattr(plots, name, fn)
    times["rest of the report (trust section, files)"] = total - sum(times.values())
    times["report total"] = total
    return dict(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=1, help="reports written (medians)")
    parser.add_argument("--data", choices=("gantry", "stage"), default="gantry")
    args = parser.parse_args()
    if args.repeat < 1:
        parser.error("--repeat: expected a positive integer")
    ds = lpvid.datasets.gantry() if args.data == "gantry" else lpvid.datasets.positioning_stage()
    print(f"import lpvid: {IMPORT_S:.2f} s")
    t = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lpvid.ConvergenceWarning)
        result = lpvid.identify(
            ds.identification, ds.order, ds.basis, validation=ds.validation, fixed=ds.fixed
        )
    print(f"identify: {time.perf_counter() - t:.2f} s")
    for stage, seconds in result.timings.items():
        print(f"  {stage}: {seconds:.2f} s")
    runs = []
    pooled = []
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(args.repeat):
            runs.append(timed_report(result, ds, Path(tmp) / f"report{k}"))
        # As lpvid demo writes it: the figures in worker processes, started
        # (and warmed up) while identify ran; here they start before the wait.
        with report.FigurePool(max(1, min(4, os.cpu_count() or 1))) as pool:
            time.sleep(result.timings["total_s"])
            for k in range(args.repeat):
                t = time.perf_counter()
                report.write_report(
                    result,
                    Path(tmp) / f"pooled{k}",
                    title="bench",
                    inputs=ds.inputs,
                    outputs=ds.outputs,
                    p_label=ds.scheduling,
                    pool=pool,
                )
                pooled.append(time.perf_counter() - t)
    first = runs[0]
    print("report, first in this process" + (" | median of the others" if len(runs) > 1 else ""))
    for key in first:
        later = [r[key] for r in runs[1:] if key in r]
        med = f" | {statistics.median(later):.2f} s" if later else ""
        print(f"  {key}: {first[key]:.2f} s{med}")
    later = f" | {statistics.median(pooled[1:]):.2f} s" if len(pooled) > 1 else ""
    print(f"report with the figures in {pool.workers} worker processes: {pooled[0]:.2f} s{later}")


if __name__ == "__main__":
    main()
