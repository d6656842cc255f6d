"""Which scale :func:`lpvid.select` tries for each scheduling parameter, and what it chose.

The rule (``log_scale="auto"``): a scheduling parameter whose values (the
identification data's and the validation data's) are all above zero and
span more than :data:`LOG_DECADES` decades is tried on the log scale too.
Every polynomial basis of the grid with a domain and every parameter on the
linear scale then gets a twin on the log scale of those parameters (the
same degree and domain), placed right after it; the pairs are judged
together by select's rule, so the log scale is chosen only where it
validates (or holds out, or fits) better. ``log_scale=True`` tries the log
scale on every parameter whose values are above zero, ``False`` keeps the
grid as given.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from lpvid.data.basis import Basis, Legendre, Polynomial
from lpvid.data.frf import FrfData
from lpvid.data.schedule import decades
from lpvid.pipeline.problem import check_scale

__all__ = [
    "LOG_DECADES",
    "check_log_bases",
    "log_axes",
    "log_grid",
    "scale_label",
    "with_log_twins",
]

#: A range above zero that spans more than this many decades is tried on the log scale.
LOG_DECADES = 1.0


def _check(log_scale: Any) -> Any:
    if isinstance(log_scale, str) and log_scale == "auto":
        return log_scale
    if isinstance(log_scale, (bool, np.bool_)):
        return bool(log_scale)
    raise ValueError(f"log_scale: expected 'auto', True or False, got {log_scale!r}")


def log_axes(data: FrfData, validation: FrfData | None, log_scale: Any) -> tuple[list[bool], str]:
    """Which scheduling parameters are tried on the log scale, and why, in a sentence.

    Parameters
    ----------
    data, validation : FrfData
        The scheduling values the rule looks at (validation may be None).
    log_scale : {"auto", True, False}
        The rule (module notes).

    Returns
    -------
    axes : list of bool
        One per scheduling parameter.
    why : str
        What the rule saw, for the table.
    """
    rule = _check(log_scale)
    p = [data.p_rows]
    if validation is not None:
        p.append(validation.p_rows)
    rows = np.concatenate(p)
    names = ["p"] if rows.shape[1] == 1 else [f"p{k + 1}" for k in range(rows.shape[1])]
    axes, parts = [], []
    for name, lo, hi in zip(names, rows.min(axis=0), rows.max(axis=0), strict=True):
        span = decades(float(lo), float(hi))
        where = f"{name} in [{lo:g}, {hi:g}]"
        if lo <= 0:
            axes.append(False)
            parts.append(f"{where} reaches zero or below")
        elif rule == "auto" and span <= LOG_DECADES:
            axes.append(False)
            parts.append(f"{where} spans {span:.2g} decades, not more than {LOG_DECADES:g}")
        else:
            axes.append(rule is not False)
            parts.append(f"{where} spans {span:.2g} decades")
    how = {
        "auto": (
            f"log_scale='auto' tries a range above zero that spans more than {LOG_DECADES:g} "
            "decade on the log scale"
        ),
        True: "log_scale=True tries every range above zero on the log scale",
        False: "log_scale=False keeps the bases as given",
    }[rule]
    tried = [n for n, a in zip(names, axes, strict=True) if a]
    verdict = (
        f"log scale tried for {', '.join(tried)}" if tried else "the bases as given (no log twin)"
    )
    return axes, f"{verdict}: {'; '.join(parts)} ({how})"


def with_log_twins(bases: list[Basis], axes: list[bool]) -> list[Basis]:
    """The bases, each polynomial one followed by its twin on the log scale of ``axes``.

    A twin is made for a :class:`lpvid.Polynomial` or :class:`lpvid.Legendre`
    with at least one basis function, a domain above zero on those axes and
    every parameter on the linear scale, unless the grid holds it already.
    """
    if not any(axes):
        return list(bases)
    out: list[Basis] = []
    for b in bases:
        out.append(b)
        if not isinstance(b, (Polynomial, Legendre)) or b.domain is None or len(b) == 0:
            continue
        if "log" in b.scales or any(
            a and lo <= 0 for a, (lo, _) in zip(axes, b.domain, strict=True)
        ):
            continue
        scale = ["log" if a else "linear" for a in axes]
        twin = type(b)(b.degree, b.domain, scale=scale)
        if twin not in bases and twin not in out:
            out.append(twin)
    return out


def scale_label(basis: Basis) -> str:
    """``"linear"``, ``"log"``, or one per parameter (``"log/linear"``)."""
    scales = basis.scales
    return scales[0] if len(set(scales)) == 1 else "/".join(scales)


def check_log_bases(bases: list[Basis], data: FrfData, validation: FrfData | None) -> None:
    """Refuse a basis on the log scale for scheduling values at or below zero (naming ``bases``)."""
    for b in bases:
        check_scale(b, data, validation, who=f"bases: {b!r}")


def log_grid(
    bases: list[Basis], data: FrfData, validation: FrfData | None, log_scale: Any
) -> tuple[list[Basis], str]:
    """Select's bases with their log twins (:func:`with_log_twins`) and why (:func:`log_axes`).

    Raises
    ------
    ValueError
        When a basis given on the log scale meets scheduling values at or
        below zero (:func:`check_log_bases`), or ``log_scale`` is unknown.
    """
    check_log_bases(bases, data, validation)
    axes, why = log_axes(data, validation, log_scale)
    return with_log_twins(bases, axes), why
