"""``lpvid select``: choose the order and the basis from a data file, locally or on Dask."""

from __future__ import annotations

import argparse
import math
import sys
from contextlib import ExitStack
from pathlib import Path
from typing import Any

import lpvid
from lpvid.cli._common import (
    OPTIONS,
    Misuse,
    add_domain,
    add_outputs,
    add_scale,
    basis_of,
    fixed_of,
    labels_of,
    load_data,
    misuse,
    out_dir,
    printer,
)

__all__ = ["EPILOG", "add_parser", "run"]

#: Exit code of a run that Ctrl-C stopped (the shell's 128 + SIGINT).
EXIT_INTERRUPTED = 130

EPILOG = """\
Every pair of an order from --orders and a basis of a degree from --degrees is
identified as by `lpvid fit` (the data file formats are those of `lpvid fit
--help`). The choice: with --validation, the simplest pair (fewest free
parameters in use) whose validation error is within --tolerance of the best;
without, the same on the error at held-out scheduling points (each interior
point left out in turn) when there are points to spare (more than the number
of basis functions + 2), else the smallest order and degree that fit the data
to the noise floor.

The runs go to threads on this machine, or with --scheduler to a Dask cluster
(pip install "lpvid[dask]"; the workers need lpvid installed).

Files in --out: select.md (the grid and why the pair was chosen), grid.json,
figures/select.png, and the chosen model's report.md, model.json, model.mat.

example:
  lpvid select gantry.npz --orders 4:8 --degrees 1:4 --validation gantry-val.npz --out sel
  lpvid select gantry.npz --orders 4:8 --degrees 1:4 --scheduler tcp://10.0.0.5:8786 --out sel
"""

#: The option behind each argument name of lpvid.select's errors.
SELECT_OPTIONS = {**OPTIONS, "orders": "--orders", "bases": "--degrees", "executor": "--scheduler"}


def add_parser(sub: Any) -> None:
    """Add the ``select`` command to the subcommands of the ``lpvid`` parser."""
    sel = sub.add_parser(
        "select",
        help="choose the model order and the basis degree over a grid, locally or on Dask",
        description="Identify an LPV model for every pair of order and basis degree, choose "
        "one, and write the grid, a figure and the chosen model's report.",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sel.add_argument("data", help="FRF data file (.npz or .mat) or manifest (.toml)")
    sel.add_argument(
        "--orders", required=True, help="orders to try: LO:HI (inclusive) or a list such as 4,6,8"
    )
    sel.add_argument(
        "--degrees", required=True, help="basis degrees to try: LO:HI (inclusive) or a list"
    )
    sel.add_argument(
        "--basis",
        choices=("poly", "legendre"),
        default="poly",
        help="kind of basis: powers (poly, default) or Legendre polynomials",
    )
    add_domain(sel)
    add_scale(sel, ("auto", "linear", "log"), "auto")
    sel.add_argument("--gamma", nargs="+", type=float, metavar="G", help="as in lpvid fit")
    sel.add_argument(
        "--fix", action="append", choices=("A", "B", "C", "D"), default=[], help="as in lpvid fit"
    )
    sel.add_argument("--validation", help="FRF data at other scheduling values, same format")
    sel.add_argument(
        "--tolerance",
        type=float,
        default=0.1,
        help="relative slack on the best validation (or held-out) error (default 0.1)",
    )
    sel.add_argument("--lines", choices=("same", "common"), help="with a manifest: as in lpvid fit")
    sel.add_argument(
        "--scheduler", metavar="ADDRESS", help="address of a Dask scheduler (tcp://host:8786)"
    )
    add_outputs(sel)


def _integers(text: str, option: str, minimum: int) -> list[int]:
    """``LO:HI`` (inclusive) or ``a,b,c`` as a list of integers >= ``minimum``."""
    expected = (
        f"{option}: expected LO:HI or a list such as 4,6,8 of integers >= {minimum}, got {text!r}"
    )
    lo, colon, hi = text.partition(":")
    parts = [lo, hi] if colon else text.split(",")
    if not all(p.strip().isdigit() for p in parts):
        raise Misuse(expected)
    values = [int(p) for p in parts]
    if colon:
        if values[0] > values[1]:
            raise Misuse(f"{option}: LO:HI needs LO <= HI, got {text!r}")
        values = list(range(values[0], values[1] + 1))
    if min(values) < minimum:
        raise Misuse(expected)
    if len(set(values)) < len(values):
        raise Misuse(f"{option}: a value is given twice in {text!r}")
    return values


def _bases(args: argparse.Namespace, data: Any, validation: Any) -> list[lpvid.Basis]:
    degrees = _integers(args.degrees, "--degrees", 0)
    out = []
    for d in degrees:
        n_functions = math.comb(d + data.n_params, data.n_params) - 1
        if n_functions + 1 > data.n_points:
            raise Misuse(
                f"--degrees: degree {d} has {n_functions} basis functions; they need at least "
                f"{n_functions + 1} scheduling points, the data have {data.n_points}"
            )
        scale = "linear" if args.scale == "auto" else args.scale  # auto: select adds the twins
        out.append(basis_of(f"{args.basis}:{d}", args.domain, data, validation, scale))
    return out


def _executor(address: str | None, stack: ExitStack) -> Any:
    """The executor of a Dask scheduler at ``address`` (None: lpvid's threads)."""
    if address is None:
        return None
    try:
        from distributed import Client
    except ImportError as exc:
        raise Misuse(
            f'--scheduler: needs dask and distributed: pip install "lpvid[dask]" ({exc})'
        ) from exc
    try:
        client = stack.enter_context(Client(address, timeout=10))
    except (OSError, ValueError, TypeError) as exc:
        raise Misuse(f"--scheduler: cannot connect to {address}: {exc}") from exc
    return client.get_executor()


def run(args: argparse.Namespace) -> int:
    """Run ``lpvid select`` with parsed arguments; returns the exit code."""
    say = printer(args.quiet)
    out_dir(args.out)
    orders = _integers(args.orders, "--orders", 1)
    fixed = fixed_of(args.fix)
    if not math.isfinite(args.tolerance) or args.tolerance < 0:
        raise Misuse(f"--tolerance: expected a finite number >= 0, got {args.tolerance}")
    data, validation = load_data(args)
    bases = _bases(args, data, validation)
    say(f"data: {data}")
    with ExitStack() as stack:
        executor = _executor(args.scheduler, stack)
        try:
            sel = lpvid.select(
                data,
                orders,
                bases,
                validation=validation,
                gammas=args.gamma,
                fixed=fixed,
                executor=executor,
                tolerance=args.tolerance,
                progress=say,
                log_scale="auto" if args.scale == "auto" else False,
            )
        except (ValueError, TypeError) as exc:
            raise misuse(exc, SELECT_OPTIONS) from exc
    say("writing the report")
    path = lpvid.report.markdown.write_select_report(
        sel,
        args.out,
        title=f"lpvid select: {args.data}",
        figures=not args.no_figures,
        **labels_of(data),
    )
    print()
    print("The grid (-> the chosen pair):")
    print(sel.table())
    print()
    print(sel.summary())
    print(f"grid: {path}")
    print(f"chosen model: {Path(args.out) / 'report.md'}, {Path(args.out) / 'model.json'}")
    if sel.interrupted:
        print(
            "lpvid select: interrupted: the report covers the pairs done before Ctrl-C",
            file=sys.stderr,
        )
        return EXIT_INTERRUPTED
    return 0
