"""The ``lpvid`` command line: ``lpvid demo``, ``lpvid fit`` and ``lpvid select``."""

from __future__ import annotations

import argparse
import contextlib
import importlib.util
import os
import sys
import warnings
from collections.abc import Iterator, Sequence
from concurrent.futures import Executor
from pathlib import Path
from typing import Any

import lpvid
from lpvid.cli import select_command
from lpvid.cli._common import (
    EXIT_MISUSE,
    Misuse,
    Parser,
    add_domain,
    add_outputs,
    add_scale,
    basis_of,
    fixed_of,
    labels_of,
    load_data,
    misuse,
    one_line,
    out_dir,
    printer,
    suggest_count,
)
from lpvid.report.figures import FigurePool

__all__ = ["main"]

FIT_EPILOG = """\
The data file holds FRFs measured at frozen scheduling values:
  .npz or .mat with p (N,) scheduling values, freqs_hz (F,) frequency lines,
  G (N, F, l, r) complex FRFs (outputs x inputs), optionally sigma (same shape,
  standard deviations; default 1) and Ts (sample time; absent or empty for
  continuous time). lpvid.FrfData.save writes such files.
  Or a TOML manifest (.toml) listing the measured files per scheduling value:
  UFF 58 (ASCII or binary), CSV or MATLAB frd/idfrd structs, with sigma from
  coherence, variance records or a relative level (see lpvid.FrfData.from_files
  and docs/data.md); --lines common keeps the lines all files share.

The pipeline: one LTI model per point (frequency-domain subspace + Levenberg-
Marquardt), SMILE interpolation over the basis in every coherent form, an
unregularised fit, then the reweighted l2,1 path over gamma; the chosen model
is the simplest whose validation error stays within --tolerance of the best
(with --validation), else the knee of accuracy against the number of groups.

gamma is normalised: a group of parameters (one basis function in one of A,
B, C, D) is kept only when it lowers V_NLS by more than about gamma times the
number of data points; 1e-3 keeps almost everything, 1e-1 keeps only what
matters a lot.

example, on the demo's gantry (its two files made first):
  python -c "import lpvid; lpvid.datasets.gantry().identification.save('gantry.npz')"
  python -c "import lpvid; lpvid.datasets.gantry().validation.save('gantry-val.npz')"
  lpvid fit gantry.npz --order 6 --basis poly:4 --validation gantry-val.npz --out fit1
  lpvid fit gantry.toml --order 6 --basis poly:4 --out fit2   (a manifest, docs/data.md)
"""


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``lpvid`` command."""
    parser = Parser(
        prog="lpvid",
        description="Identify LPV state-space models from FRF data at frozen operating points.",
    )
    parser.add_argument("--version", action="version", version=f"lpvid {lpvid.__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=Parser)

    demo = sub.add_parser(
        "demo",
        help="run the whole pipeline on a built-in data set and write a report",
        description="Run the whole pipeline on a built-in data set (a flexible gantry by "
        "default), print the results and write a report with figures and the model files.",
    )
    demo.add_argument("--out", default="lpvid-demo", help="output folder (default: lpvid-demo)")
    demo.add_argument(
        "--data",
        choices=("gantry", "stage"),
        default="gantry",
        help="built-in data set: the flexible gantry (default) or the positioning stage",
    )
    demo.add_argument("--no-figures", action="store_true", help="skip the figures")
    demo.add_argument("--quiet", action="store_true", help="print only the results")

    fit = sub.add_parser(
        "fit",
        help="identify an LPV model from your FRF data file",
        description="Identify an LPV state-space model from FRF data measured at frozen "
        "scheduling values, and write a report, the model (JSON and MATLAB) and figures.",
        epilog=FIT_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    fit.add_argument(
        "data", help="FRF data file (.npz or .mat) or manifest of measured files (.toml)"
    )
    fit.add_argument("--order", type=int, required=True, help="number of states n")
    fit.add_argument(
        "--basis",
        default="poly:2",
        help="scheduling dependency: poly:D (the constant and the powers s, ..., s^D of the "
        "scheduling s mapped to [-1, 1] by --domain: D + 1 functions) or legendre:D "
        "(Legendre polynomials of degree 0 to D); default poly:2 (the demo's gantry uses poly:4)",
    )
    add_domain(fit)
    add_scale(fit, ("linear", "log"), "linear")
    fit.add_argument(
        "--gamma",
        nargs="+",
        type=float,
        metavar="G",
        help="regularisation weights to sweep (default: 0.1 0.03 0.01 0.003 0.001)",
    )
    fit.add_argument(
        "--fix",
        action="append",
        choices=("A", "B", "C", "D"),
        default=[],
        help="keep a matrix fixed; --fix D identifies strictly proper models (D = 0)",
    )
    fit.add_argument("--validation", help="FRF data at other scheduling values, same format")
    fit.add_argument(
        "--tolerance",
        type=float,
        help="with --validation: relative slack on the best validation error for the choice "
        "(default 0.1)",
    )
    fit.add_argument(
        "--lines",
        choices=("same", "common"),
        help="with a manifest: files must share their frequency lines (same, default) or "
        "only the lines all files have are kept (common)",
    )
    fit.add_argument(
        "--suggest",
        type=int,
        metavar="K",
        help="also print the K scheduling values where one more FRF measurement would shrink "
        "the model's uncertainty bands most (lpvid.next_points), with a figure",
    )
    fit.add_argument(
        "--resample",
        type=int,
        metavar="N",
        help="measure the spread between the points by identifying again on N data sets "
        "simulated from the model returned (lpvid.resampled; about N times the fit's time)",
    )
    add_outputs(fit)
    select_command.add_parser(sub)
    return parser


def _print_result(result: lpvid.IdentifyResult) -> None:
    print()
    print("Group magnitudes of the SMILE model (left ||theta_X(i)||, right relative to X(0)):")
    print(result.initial.group_norms())
    print()
    print("Group magnitudes of the chosen model:")
    print(result.model.group_norms())
    print()
    print("Accuracy against simplicity (-> the chosen model):")
    print(result.table())
    print()
    print(result.summary())


@contextlib.contextmanager
def _figure_pool(figures: bool, say: Any) -> Iterator[Executor | None]:
    """Worker processes for the report's figures, or None (no figures, no matplotlib)."""
    if not figures or importlib.util.find_spec("matplotlib") is None:
        yield None
        return
    try:
        pool = FigurePool(max(1, min(4, os.cpu_count() or 1)))
    except OSError as exc:  # no process pools here (no semaphores, say)
        say(f"figures drawn in this process ({one_line(exc)})")
        yield None
        return
    try:
        yield pool
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def _suggest(result: lpvid.IdentifyResult, k: int, out: str, figures: bool, p_label: Any) -> None:
    """Print where to measure next and, with figures, draw ``figures/suggested.png``."""
    suggestion = lpvid.suggest_points(result, k=k)
    print()
    print(suggestion.summary())
    drawable = result.data.n_params <= 2 and importlib.util.find_spec("matplotlib") is not None
    if figures and drawable:
        path = Path(out) / "figures" / "suggested.png"
        path.parent.mkdir(parents=True, exist_ok=True)
        label = p_label or "scheduling p"
        lpvid.plots.save(lpvid.plots.suggested_points(suggestion, p_label=label), path)
        print(f"figure: {path}")


def _run(
    result_of: Any,
    out: str,
    figures: bool,
    say: Any,
    title: str,
    description: str | None,
    suggest: int | None = None,
    **labels: Any,
) -> int:
    # The figures' worker processes start now and import matplotlib while
    # identify computes.
    with _figure_pool(figures, say) as pool:
        result = result_of()
        say("writing the report")
        path = lpvid.report.markdown.write_report(
            result, out, title=title, description=description, figures=figures, pool=pool, **labels
        )
    _print_result(result)
    print(f"report: {path}")
    print(f"model: {Path(out) / 'model.json'} (and model.mat for MATLAB)")
    if suggest:
        _suggest(result, suggest, out, figures, labels.get("p_label"))
    return 0


def _demo(args: argparse.Namespace) -> int:
    say = printer(args.quiet)
    out_dir(args.out)
    ds = lpvid.datasets.gantry() if args.data == "gantry" else lpvid.datasets.positioning_stage()
    if not args.quiet:
        print(ds.description)
        print()
    return _run(
        lambda: lpvid.identify(
            ds.identification,
            ds.order,
            ds.basis,
            validation=ds.validation,
            fixed=ds.fixed,
            progress=say,
        ),
        args.out,
        not args.no_figures,
        say,
        f"lpvid demo: {ds.name}",
        ds.description,
        inputs=ds.inputs,
        outputs=ds.outputs,
        p_label=ds.scheduling,
    )


def _fit(args: argparse.Namespace) -> int:
    say = printer(args.quiet)
    out_dir(args.out)
    if args.order < 1:
        raise Misuse(f"--order: expected a positive integer, got {args.order}")
    fixed = fixed_of(args.fix)
    if args.tolerance is not None and not args.validation:
        raise Misuse(
            "--tolerance: applies to the choice by validation error; give --validation too"
        )
    data, validation = load_data(args)
    basis = basis_of(args.basis, args.domain, data, validation, args.scale)
    if args.suggest is not None:
        suggest_count(args.suggest, basis, data)
    if args.resample is not None and args.resample < 1:
        raise Misuse(f"--resample: expected a positive number of runs, got {args.resample}")
    say(f"data: {data}")

    def go() -> lpvid.IdentifyResult:
        try:
            result = lpvid.identify(
                data,
                args.order,
                basis,
                gammas=args.gamma,
                validation=validation,
                fixed=fixed,
                tolerance=0.1 if args.tolerance is None else args.tolerance,
                progress=say,
            )
        except (ValueError, TypeError) as exc:
            raise misuse(exc) from exc
        if args.resample:
            result = lpvid.resampled(result, args.resample, progress=say)
        return result

    return _run(
        go,
        args.out,
        not args.no_figures,
        say,
        f"lpvid fit: {args.data}",
        None,
        suggest=args.suggest,
        **labels_of(data),
    )


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:  # a usage error, as a missing argument is
        parser.print_help(sys.stderr)
        print("lpvid: error: a command is needed (demo, fit or select)", file=sys.stderr)
        return EXIT_MISUSE

    def say_warning(message: Any, category: Any, *rest: Any, **kw: Any) -> None:
        print(f"lpvid {args.command}: warning: {message}", file=sys.stderr, flush=True)

    try:
        # The command line shows lpvid's warnings as its own lines, whatever
        # the interpreter's warning filters (they are part of the results).
        with warnings.catch_warnings():
            warnings.simplefilter("always", lpvid.ConvergenceWarning)
            warnings.showwarning = say_warning
            commands = {"demo": _demo, "fit": _fit, "select": select_command.run}
            return commands[args.command](args)
    except Misuse as exc:
        print(f"lpvid {args.command}: error: {one_line(exc)}", file=sys.stderr)
        return EXIT_MISUSE
    except (OSError, MemoryError) as exc:
        print(f"lpvid {args.command}: error: {one_line(exc)}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"lpvid {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
