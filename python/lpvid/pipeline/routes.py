"""A route through the pipeline: a refined start, its l2,1 path and the choice on that path.

:func:`follow` runs the path of :func:`lpvid.pipeline.path.run_path` from one
refined start and chooses an entry on it (:func:`path_choice`). The
pipeline follows the chosen start's route; when the measured points leave
the chosen structure open it follows other routes too
(:mod:`lpvid.pipeline.opening`), and :func:`count_silent` counts the
directions a route's choice leaves open (:mod:`lpvid.trust.silent`).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from lpvid._capture import collected
from lpvid.data.frf import FrfData
from lpvid.fit.judge import noise_slack, tied
from lpvid.fit.results import FitResult, L21Result
from lpvid.model.layout import fixed_mask
from lpvid.model.lpv import LpvModel
from lpvid.pipeline.path import Along, run_path
from lpvid.pipeline.result import PathEntry
from lpvid.trust.silent import SilentCount, silent_directions
from lpvid.trust.steps import stable_fit

__all__ = ["MAX_COUNTED", "Route", "count_silent", "follow", "knee", "path_choice", "uncounted"]


@dataclass
class Route:
    """A start followed through the path, and the entry chosen on it.

    Attributes
    ----------
    name : str
        The start's name (see :class:`lpvid.initial.Candidate`).
    nls : FitResult
        The refined start (the unregularised fit).
    results : list of L21Result
        The path's fits, largest gamma first.
    entries : list of PathEntry
        The unregularised model and the path's (what ``IdentifyResult.entries`` holds).
    chosen : int
        The entry chosen on this path (:func:`path_choice`).
    reason : str
        Why.
    fixed : object
        What the route holds fixed: the problem's ``fixed``, or the start's
        structure mask (:attr:`lpvid.initial.Candidate.structure`).
    warned : list of (type, str)
        What its fits warned, category and message (held back: only the
        route returned says it, :meth:`say_warnings`).
    counted : SilentCount or None
        The count of the chosen entry's structure
        (:func:`count_silent`), once made.
    """

    name: str
    nls: FitResult
    results: list[L21Result]
    entries: list[PathEntry]
    chosen: int
    reason: str
    fixed: Any
    warned: list[tuple[type[Warning], str]] = field(default_factory=list)
    counted: SilentCount | None = None

    def say_warnings(self) -> None:
        """Warn what the route's fits warned."""
        for category, message in self.warned:
            warnings.warn(message, category, stacklevel=4)

    @property
    def entry(self) -> PathEntry:
        """The chosen entry."""
        return self.entries[self.chosen]


def follow(
    name: str, nls: FitResult, gammas: Sequence[float], data: FrfData, fixed: Any, along: Along
) -> Route:
    """The path from the refined start ``nls`` and the choice on it.

    Its fits' warnings are held in :attr:`Route.warned`, for the route returned to say
    (collected in this thread, :func:`lpvid._capture.collected`: the pieces of
    the run on other threads collect theirs at the same time).
    """
    with collected() as warned:
        if along.stable:
            threshold = along.settings.threshold
            nls = stable_fit(nls, data, fixed, threshold, along.p_range, along.time_cost)
        results, entries = run_path(nls, sorted(gammas, reverse=True), data, fixed, along)
    chosen, reason = path_choice(entries, along.tolerance)
    return Route(name, nls, results, entries, chosen, reason, fixed, list(warned))


def knee(entries: list[PathEntry]) -> tuple[int, str]:
    """The knee of V_NLS against the number of groups (no validation data).

    Each number of groups is represented by its most regularised entry
    among those whose V_NLS ties with the lowest for that number
    (:func:`lpvid.fit.judge.tied`): further down the path, fits with the same
    groups differ by less than the noise at the data and by the slide of
    the groups' sizes between the points. With the curve normalised to the
    unit square (groups kept on x, V_NLS on y, falling from the simplest
    model to the richest), the knee is the point farthest below the chord
    between the two ends: where adding groups stops buying accuracy. When
    the whole curve lies within the noise (the spread of V_NLS is within
    :func:`lpvid.fit.judge.noise_slack`), the simplest model is as good as any.
    """
    floor = entries[0].noise_floor
    by_groups: dict[int, int] = {}
    for g in sorted({e.n_groups for e in entries}):
        same = [k for k, e in enumerate(entries) if e.n_groups == g]
        flags = tied([entries[k].vnls for k in same], floor)
        by_groups[g] = max(
            (k for k, f in zip(same, flags, strict=True) if f),
            key=lambda k: (entries[k].gamma, -k),
        )
    ks = [by_groups[g] for g in sorted(by_groups)]
    x = np.array([entries[k].n_groups for k in ks], dtype=float)
    y = np.array([entries[k].vnls for k in ks])
    if len(ks) == 1 or y.max() - y.min() <= noise_slack(floor):
        k = ks[0]
        return k, (
            "no validation data; every model on the path is within the noise of the best "
            "(spread of V_NLS below 2 sqrt(M)), so the simplest is kept"
        )
    xn = (x - x[0]) / (x[-1] - x[0])
    yn = (y - y[-1]) / (y[0] - y[-1]) if y[0] != y[-1] else np.zeros_like(y)
    depth = (1.0 - xn) - yn
    k = ks[int(np.argmax(depth))]
    return k, "no validation data; the knee of V_NLS against the number of groups kept"


def path_choice(entries: list[PathEntry], tolerance: float) -> tuple[int, str]:
    """The entry chosen on a path, and why.

    With validation data, the simplest entry whose validation V_NLS is
    within ``tolerance`` of the best on the path; without, :func:`knee`.
    """
    if entries[0].validation_vnls is None:
        return knee(entries)
    vals = np.array([e.validation_vnls for e in entries], dtype=float)
    best = float(vals.min())
    ok = [k for k in range(len(entries)) if vals[k] <= (1 + tolerance) * best]
    k = min(ok, key=lambda i: (entries[i].n_groups, vals[i]))
    return k, (
        f"the simplest model whose validation V_NLS ({vals[k]:.5g}) is within "
        f"{tolerance:.0%} of the best on the path ({best:.5g})"
    )


#: Free parameters beyond which the silent directions are not counted (the
#: count takes dense eigendecompositions of about that size).
MAX_COUNTED = 2500


def uncounted(free: int, time_cost: Any = None) -> str:
    """Why the silent directions of ``free`` parameters are not counted ("" when they are).

    Not with time records (they see the model between the points), nor
    beyond :data:`MAX_COUNTED` free parameters.
    """
    if time_cost is not None:
        return "the time records see the model between the points"
    if free > MAX_COUNTED:
        return f"{free} free parameters, more than {MAX_COUNTED} (the count is dense)"
    return ""


def count_silent(
    model: LpvModel, data: FrfData, fixed: Any, threshold: float
) -> tuple[SilentCount | None, str]:
    """:func:`lpvid.trust.silent.silent_directions`, or None and why it was not counted."""
    why = uncounted(int((~fixed_mask(model, fixed)).sum()))
    if why:
        return None, why
    return silent_directions(model, data, fixed, threshold=threshold), ""
