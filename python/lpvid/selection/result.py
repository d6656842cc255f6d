"""What :func:`lpvid.select` returns: the grid of (order, basis) pairs and the choice among them."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from lpvid.data.basis import Basis
from lpvid.initial.orders import OrderHints
from lpvid.model.layout import MATRICES, fixed_mask, free_mask
from lpvid.model.lpv import LpvModel
from lpvid.pipeline.result import IdentifyResult
from lpvid.selection.scales import scale_label

__all__ = [
    "GridRow",
    "SelectResult",
    "basis_label",
    "choose_pair",
    "free_in_use",
    "scale_choice",
]

#: The rules of the choice, by what judges the pairs.
RULES = ("validation", "held-out", "noise floor")


def basis_label(basis: Basis) -> str:
    """A short name of a basis for tables: ``poly:3``, ``poly:3 log``, ``custom(f1, f2)``.

    A basis with a parameter on the log scale says so: ``poly:2 log``, or
    one scale per parameter, ``poly:2 log/linear``.
    """
    kind = getattr(basis, "kind", "")
    if kind in ("polynomial", "legendre"):
        label = f"{'poly' if kind == 'polynomial' else kind}:{basis.degree}"  # type: ignore[attr-defined]
        return label if "log" not in basis.scales else f"{label} {scale_label(basis)}"
    return f"{kind or type(basis).__name__}({', '.join(basis.names)})"


def free_in_use(model: LpvModel, nonzero: dict[str, list[int]], fixed: Any = None) -> int:
    """Free parameters in use: the free entries of the constant parts and of the groups kept.

    Parameters
    ----------
    model : LpvModel
    nonzero : dict
        Basis indices (1-based) kept per matrix, as ``PathEntry.nonzero_groups``.
    fixed : optional
        Fixed parameters, as in :func:`lpvid.fixed_mask` (not counted).

    Returns
    -------
    int
    """
    used = fixed_mask(model, {x: [0, *nonzero.get(x, [])] for x in MATRICES})
    return int(np.sum(used & free_mask(model, fixed)))


@dataclass
class GridRow:
    """One (order, basis) pair of :func:`lpvid.select`.

    Attributes
    ----------
    order : int
    basis : Basis
    vnls, noise_floor : float or None, int or None
        V_NLS of the pair's model (``result.model``) on the identification
        data and its noise floor.
    validation_vnls, validation_floor : float or None, int or None
        V_NLS on the validation data, or (rule ``"held-out"``) summed over
        the held-out scheduling points of the rotation, and its noise floor.
    n_groups : int or None
        Groups kept.
    n_free : int or None
        Free parameters in use (see :func:`free_in_use`).
    seconds : float
        Time of its identify runs (the held-out ones included).
    error : str or None
        Why the pair has no model (or no held-out V_NLS): the exception's
        type and message, or ``"cancelled"``.
    warnings : list of (category, str)
        The warnings its runs raised.
    result : IdentifyResult or None
        What :func:`lpvid.identify` returned for the pair.
    """

    order: int
    basis: Basis
    vnls: float | None = None
    noise_floor: int | None = None
    validation_vnls: float | None = None
    validation_floor: int | None = None
    n_groups: int | None = None
    n_free: int | None = None
    seconds: float = 0.0
    error: str | None = None
    warnings: list[tuple[type[Warning], str]] = field(default_factory=list)
    result: IdentifyResult | None = None

    @property
    def label(self) -> str:
        """``"order 6, poly:3"``."""
        return f"order {self.order}, {basis_label(self.basis)}"

    @property
    def ok(self) -> bool:
        """Whether the pair has a model."""
        return self.result is not None


def _judged(rows: list[GridRow]) -> list[int]:
    return [k for k, r in enumerate(rows) if r.ok and r.validation_vnls is not None]


def choose_pair(rows: list[GridRow], rule: str, tolerance: float) -> tuple[int, str]:
    """The chosen pair of the grid and why.

    With ``rule`` ``"validation"`` or ``"held-out"``: among the pairs whose
    validation (or held-out) V_NLS is within ``tolerance`` of the best, the
    one with the fewest free parameters in use, then the fewest basis
    functions, then the lowest validation V_NLS. With ``"noise floor"``:
    the smallest order, then the fewest basis functions, whose V_NLS
    reaches the noise floor, ``V_NLS <= M + 2 sqrt(M)``; when none does, the
    lowest ``V_NLS / M``.

    Raises
    ------
    ValueError
        When no pair has what the rule needs (every pair failed).
    """
    if rule not in RULES:
        raise ValueError(f"rule: expected one of {RULES}, got {rule!r}")
    if rule != "noise floor":
        ks = _judged(rows)
        if not ks:
            raise ValueError(f"no pair of the grid has a {rule} V_NLS")
        vals = {k: float(rows[k].validation_vnls) for k in ks}  # type: ignore[arg-type]
        best = min(vals.values())
        ok = [k for k in ks if vals[k] <= (1 + tolerance) * best]
        k = min(ok, key=lambda i: (rows[i].n_free, len(rows[i].basis), vals[i]))
        what = "validation" if rule == "validation" else "held-out"
        return k, (
            f"the simplest pair (fewest free parameters in use: {rows[k].n_free}) whose "
            f"{what} V_NLS ({vals[k]:.5g}) is within {tolerance:.0%} of the best ({best:.5g}); "
            f"{len(ok)} of {len(ks)} pairs are within"
        )
    ks = [k for k, r in enumerate(rows) if r.ok]
    if not ks:
        raise ValueError("no pair of the grid has a model")

    def reaches(r: GridRow) -> bool:
        m = float(r.noise_floor)  # type: ignore[arg-type]
        return float(r.vnls) <= m + 2 * math.sqrt(m)  # type: ignore[arg-type]

    at_floor = [k for k in ks if reaches(rows[k])]
    if at_floor:
        k = min(at_floor, key=lambda i: (rows[i].order, len(rows[i].basis), rows[i].n_free))
        return k, (
            "no validation data and too few scheduling points to hold one out; the smallest "
            "order and basis whose V_NLS reaches the noise floor (V_NLS <= M + 2 sqrt(M))"
        )
    k = min(ks, key=lambda i: float(rows[i].vnls) / float(rows[i].noise_floor))  # type: ignore[arg-type]
    return k, (
        "no validation data and too few scheduling points to hold one out; no pair reaches "
        "the noise floor (V_NLS <= M + 2 sqrt(M)), so the lowest V_NLS / M is kept: try "
        "higher orders or degrees"
    )


def scale_choice(rows: list[GridRow], chosen: int, rule: str, tolerance: float) -> str:
    """Which scale the chosen pair is on, against the choice among the other scale's pairs.

    The other choice is :func:`choose_pair` over the pairs on the other
    scale(s) alone: what ``select(..., log_scale=False)`` returns when the
    chosen pair is on the log scale. Empty when the grid holds one scale.
    """
    mine = scale_label(rows[chosen].basis)
    others = [r for r in rows if scale_label(r.basis) != mine]
    try:
        other = others[choose_pair(others, rule, tolerance)[0]]
    except ValueError:  # no other scale, or none of its pairs done
        return ""
    what = {"validation": "validation", "held-out": "held-out"}.get(rule, "identification")

    def numbers(r: GridRow) -> str:
        v, m = (
            (r.validation_vnls, r.validation_floor)
            if rule in RULES[:2]
            else (r.vnls, r.noise_floor)
        )
        ratio = "-" if v is None or not m else f"{float(v) / float(m):.4g}"
        return f"{r.n_free} free parameters in use, {what} V/floor {ratio}"

    return (
        f"chosen on the {mine} scale: {rows[chosen].label} ({numbers(rows[chosen])}); "
        f"among the pairs on the {scale_label(other.basis)} scale alone the rule chooses "
        f"{other.label} ({numbers(other)})"
    )


def _number(x: float | None, width: int, fmt: str = ".5g") -> str:
    return f"{'-':>{width}}" if x is None else f"{x:{width}{fmt}}"


@dataclass
class SelectResult:
    """Outcome of :func:`lpvid.select`.

    Attributes
    ----------
    grid : list of GridRow
        Every (order, basis) pair, by order then by basis as given.
    chosen : int
        Index of the chosen pair in :attr:`grid`.
    reason : str
        Why it was chosen.
    rule : str
        What judged the pairs: ``"validation"`` (the validation data),
        ``"held-out"`` (a rotation over held-out scheduling points) or
        ``"noise floor"``.
    tolerance : float
        The relative slack of the choice.
    hints : OrderHints
        What the subspace singular values of the data say about the order.
    interrupted : bool
        Ctrl-C stopped the run: the pairs not done are ``"cancelled"`` and
        the choice is among those done.
    timings : dict
        ``"total_s"``: the wall time of the run.
    scales : str
        Which scale the grid tried for each scheduling parameter and why
        (:func:`lpvid.selection.scales.log_axes`); :attr:`scale_note` adds
        which scale the chosen pair is on.
    """

    grid: list[GridRow]
    chosen: int
    reason: str
    rule: str
    tolerance: float
    hints: OrderHints
    interrupted: bool = False
    timings: dict[str, float] = field(default_factory=dict)
    scales: str = ""

    @property
    def scale_note(self) -> str:
        """What the grid tried on which scale and why, and the scale of the chosen pair.

        The table's and the summary's last line: :attr:`scales`, then (when
        the grid holds more than one scale) :func:`scale_choice`.
        """
        choice = scale_choice(self.grid, self.chosen, self.rule, self.tolerance)
        return "; ".join(x for x in (self.scales, choice) if x)

    @property
    def row(self) -> GridRow:
        """The chosen row of the grid."""
        return self.grid[self.chosen]

    @property
    def best(self) -> IdentifyResult:
        """The :class:`IdentifyResult` of the chosen pair."""
        result = self.row.result
        assert result is not None
        return result

    @property
    def model(self) -> LpvModel:
        """The chosen model (``best.model``)."""
        return self.best.model

    @property
    def order(self) -> int:
        """Order of the chosen pair."""
        return self.row.order

    @property
    def basis(self) -> Basis:
        """Basis of the chosen pair."""
        return self.row.basis

    def table(self) -> str:
        """The grid, one line per pair, the chosen one marked."""
        val = {"validation": "val V/floor", "held-out": "held-out V/fl"}.get(self.rule)
        head = f"{'':2}{'order':>5} {'basis':<14} {'V_NLS':>11} {'V/floor':>9}"
        head += f" {val:>13}" if val else ""
        head += f" {'groups':>6} {'free':>5} {'seconds':>8}"
        lines = [head]
        for k, r in enumerate(self.grid):
            mark = "->" if k == self.chosen else ""
            ratio = None if r.vnls is None or not r.noise_floor else r.vnls / r.noise_floor
            line = f"{mark:2}{r.order:5d} {basis_label(r.basis):<14} {_number(r.vnls, 11)}"
            line += f" {_number(ratio, 9, '.4g')}"
            if val:
                vr = (
                    None
                    if r.validation_vnls is None or not r.validation_floor
                    else r.validation_vnls / r.validation_floor
                )
                line += f" {_number(vr, 13, '.4g')}"
            groups = "-" if r.n_groups is None else str(r.n_groups)
            free = "-" if r.n_free is None else str(r.n_free)
            line += f" {groups:>6} {free:>5} {r.seconds:8.2f}"
            if r.error:
                line += f"  {' '.join(r.error.split())}"
            elif r.warnings:
                line += f"  ({len(r.warnings)} warning(s))"
            lines.append(line)
        if self.scale_note:
            lines.append(f"scale: {self.scale_note}")
        return "\n".join(lines)

    def summary(self) -> str:
        """A few lines for people: what was chosen and why."""
        r = self.row
        done = sum(1 for row in self.grid if row.error != "cancelled")
        failed = sum(1 for row in self.grid if row.error and row.error != "cancelled")
        lines = []
        if self.interrupted:
            lines.append(
                f"interrupted (Ctrl-C): {done} of {len(self.grid)} pairs done, the others "
                "cancelled; the choice is among those done"
            )
        lines += [
            f"chosen: {r.label} ({self.rule} rule); {self.reason}",
            str(self.hints),
            f"V_NLS = {r.vnls:.6g} on identification data (noise floor {r.noise_floor}, "
            f"ratio {float(r.vnls) / float(r.noise_floor):.3f}); {r.n_groups} groups kept, "  # type: ignore[arg-type]
            f"{r.n_free} free parameters in use",
        ]
        if r.validation_vnls is not None and r.validation_floor:
            what = "validation data" if self.rule == "validation" else "held-out points"
            lines.append(
                f"V_NLS = {r.validation_vnls:.6g} on {what} (noise floor {r.validation_floor}, "
                f"ratio {r.validation_vnls / r.validation_floor:.3f})"
            )
        if failed:
            lines.append(f"{failed} pair(s) failed: see the table")
        if self.scale_note:
            lines.append(f"scale: {self.scale_note}")
        lines.append(
            f"time: {self.timings.get('total_s', float('nan')):.2f} s for {len(self.grid)} pairs"
        )
        return "\n".join(lines)

    def __repr__(self) -> str:
        return f"SelectResult({self.row.label}, rule={self.rule!r}, pairs={len(self.grid)})"
