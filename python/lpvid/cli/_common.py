"""The pieces the ``lpvid`` commands share: one-line misuse errors, data files, bases, folders."""

from __future__ import annotations

import argparse
import math
import os
import time
from pathlib import Path
from typing import Any, NoReturn

import lpvid
from lpvid._files import check_replaceable
from lpvid.report.markdown import REPORT_ENTRIES

__all__ = [
    "EXIT_MISUSE",
    "OPTIONS",
    "Misuse",
    "Parser",
    "add_scale",
    "basis_of",
    "fixed_of",
    "labels_of",
    "load",
    "misuse",
    "one_line",
    "out_dir",
    "printer",
    "suggest_count",
]

EXIT_MISUSE = 2


class Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line and exit code 2."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_MISUSE, f"{self.prog}: error: {message}\n")


class Misuse(Exception):
    """A user error found after parsing (a file that cannot be read, bad values)."""


#: The command-line option behind each argument name lpvid's errors start with.
OPTIONS = {
    "order": "--order",
    "gammas": "--gamma",
    "validation": "--validation",
    "tolerance": "--tolerance",
    "basis": "--basis",
    "degree": "--basis",
    "domain": "--domain",
    "fixed": "--fix",
}


def add_domain(parser: argparse.ArgumentParser) -> None:
    """The ``--domain LO HI`` option of ``lpvid fit`` and ``lpvid select``."""
    parser.add_argument(
        "--domain",
        nargs=2,
        type=float,
        metavar=("LO", "HI"),
        help="scheduling range mapped to [-1, 1] (default: the range of the data)",
    )


def add_scale(parser: argparse.ArgumentParser, choices: tuple[str, ...], default: str) -> None:
    """The ``--scale`` option: the scale every scheduling parameter is taken on."""
    more = (
        "; auto: the data's range on both scales where it is above zero and spans more "
        "than a decade, else linear"
        if "auto" in choices
        else ""
    )
    parser.add_argument(
        "--scale",
        choices=choices,
        default=default,
        help=f"scale of the scheduling in the basis: log follows log10(p), for a variable that "
        f"spans decades{more} (default {default})",
    )


def add_outputs(parser: argparse.ArgumentParser) -> None:
    """``--out`` (required), ``--no-figures`` and ``--quiet`` of ``fit`` and ``select``."""
    parser.add_argument("--out", required=True, help="output folder")
    parser.add_argument("--no-figures", action="store_true", help="skip the figures")
    parser.add_argument("--quiet", action="store_true", help="print only the results")


def misuse(exc: Exception, options: dict[str, str] | None = None) -> Misuse:
    """A library error about an argument as a misuse of the option behind it.

    ``options`` maps argument names to options (default :data:`OPTIONS`).
    """
    table = OPTIONS if options is None else options
    name, sep, rest = str(exc).partition(": ")
    if sep and name in table:
        return Misuse(f"{table[name]}: {rest}")
    return Misuse(str(exc))


def printer(quiet: bool) -> Any:
    start = time.perf_counter()

    def say(message: str) -> None:
        if not quiet:
            print(f"[{time.perf_counter() - start:6.2f} s] {message}", flush=True)

    return say


def basis_of(
    spec: str,
    domain: Any,
    data: lpvid.FrfData,
    validation: lpvid.FrfData | None,
    scale: str = "linear",
) -> lpvid.Basis:
    kind, _, text = spec.partition(":")
    if kind not in ("poly", "legendre") or not text.isdigit():
        raise Misuse(f"--basis: expected poly:D or legendre:D with D = 0, 1, 2, ..., got {spec!r}")
    degree = int(text)
    # Counted before the basis is built: a huge degree would take long to build.
    n_functions = math.comb(degree + data.n_params, data.n_params) - 1
    if n_functions + 1 > data.n_points:
        raise Misuse(
            f"--basis: {spec} has {n_functions} basis functions; they need at least "
            f"{n_functions + 1} scheduling points, the data have {data.n_points}"
        )
    if domain is None:
        pairs = [data.p_range] if data.n_params == 1 else data.p_range
        if any(hi <= lo for lo, hi in pairs):
            raise Misuse(
                "--domain: the data's scheduling values do not span a range; give --domain LO HI"
            )
        domain = data.p_range
    else:
        if data.n_params != 1:
            raise Misuse(
                f"--domain: sets the range of one scheduling parameter; the data have "
                f"{data.n_params} (leave --domain out to use the range of the data)"
            )
        if not all(math.isfinite(x) for x in domain) or domain[0] >= domain[1]:
            raise Misuse(f"--domain: expected finite LO < HI, got {domain[0]:g} {domain[1]:g}")
        for name, frf in (("data", data), ("--validation", validation)):
            if frf is not None and (frf.p.min() < domain[0] or frf.p.max() > domain[1]):
                raise Misuse(
                    f"--domain: [{domain[0]:g}, {domain[1]:g}] does not contain the scheduling "
                    f"values of {name} ({frf.p.min():g} to {frf.p.max():g})"
                )
        domain = (domain[0], domain[1])
    low = min(lo for lo, _ in ([domain] if data.n_params == 1 else domain))
    if scale == "log" and low <= 0:
        raise Misuse(
            f"--scale: log needs scheduling values above zero; the range reaches {low:g} "
            "(leave --scale out)"
        )
    try:
        if kind == "poly":
            return lpvid.Polynomial(degree, domain=domain, scale=scale)
        return lpvid.Legendre(degree, domain=domain, scale=scale)
    except (ValueError, TypeError) as exc:
        raise misuse(exc) from exc


#: What ``lpvid fit`` and ``lpvid select`` read: data files and manifests.
DATA_SUFFIXES = (".npz", ".mat", ".toml")


def load(path: str, what: str, lines: str = "same") -> lpvid.FrfData:
    """``path`` read as FRF data (a ``.npz``/``.mat`` file or a ``.toml`` manifest).

    Every failure is a :class:`Misuse` naming ``what``.
    """
    if not Path(path).exists():
        raise Misuse(f"{what}: no such file: {path}")
    if not Path(path).is_file():
        raise Misuse(f"{what}: not a file: {path}")
    if Path(path).suffix.lower() not in DATA_SUFFIXES:
        raise Misuse(
            f"{what}: expected a .npz or .mat data file or a .toml manifest of measured "
            f"files, got {Path(path).name!r}"
        )
    try:
        if Path(path).suffix.lower() == ".toml":
            return lpvid.FrfData.from_files(path, lines=lines)
        return lpvid.FrfData.load(path)
    except (ValueError, TypeError, OSError) as exc:
        raise Misuse(f"{what}: {str(exc).removeprefix('path: ')}") from exc


def load_data(args: argparse.Namespace) -> tuple[lpvid.FrfData, lpvid.FrfData | None]:
    """The identification and validation data of ``args.data``/``args.validation``.

    ``--lines`` applies to manifests (.toml) only and is refused otherwise.
    """
    manifests = [f for f in (args.data, args.validation) if f and f.lower().endswith(".toml")]
    if args.lines is not None and not manifests:
        raise Misuse("--lines: applies to a manifest (.toml) of measured files only")
    lines = args.lines or "same"
    data = load(args.data, "data", lines)
    validation = load(args.validation, "--validation", lines) if args.validation else None
    return data, validation


def out_dir(out: str) -> None:
    """Refuse an output folder that cannot be written, before any computation."""
    if not out.strip():
        raise Misuse("--out: expected a folder name, got an empty one")
    path = Path(out)
    if path.exists() and not path.is_dir():
        raise Misuse(f"--out: {out} exists and is not a folder")
    existing = path
    while not existing.exists():
        existing = existing.parent
    if not existing.is_dir():
        raise Misuse(f"--out: cannot create {out}: {existing} is not a folder")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise Misuse(f"--out: cannot write into {existing} (permission denied)")
    # The report replaces an earlier one whole; a folder with other files is kept.
    try:
        check_replaceable(path, REPORT_ENTRIES)
    except FileExistsError as exc:
        raise Misuse(f"--out: {exc}") from exc


def fixed_of(names: list[str]) -> dict[str, bool] | None:
    twice = sorted({x for x in names if names.count(x) > 1})
    if twice:
        raise Misuse(f"--fix: {', '.join(twice)} given more than once")
    if set(names) == {"A", "B", "C", "D"}:
        raise Misuse("--fix: A, B, C and D all fixed leave nothing to identify")
    return {x: True for x in names} or None


def labels_of(data: lpvid.FrfData) -> dict[str, Any]:
    """Report labels from a manifest's names (none for .npz/.mat data)."""
    prov = data.provenance or {}
    params = prov.get("parameters")
    return {
        "inputs": prov.get("inputs"),
        "outputs": prov.get("outputs"),
        "p_label": ", ".join(params) if params else None,
    }


def one_line(exc: Exception) -> str:
    return " ".join(str(exc).split())


def suggest_count(k: int, basis: lpvid.Basis, data: lpvid.FrfData) -> None:
    """Refuse ``--suggest K`` with K < 1 or more than the candidates not measured yet."""
    if k < 1:
        raise Misuse(f"--suggest: expected a positive number of points, got {k}")
    p_range = getattr(basis, "domain", None) or data.p_range
    free = len(lpvid.experiment.nextpoints.default_candidates(p_range, data.p))
    if k > free:
        raise Misuse(
            f"--suggest: {k} points asked for, but the grid over the scheduling range has "
            f"{free} values that are not measured yet"
        )
