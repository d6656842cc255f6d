"""How lpvid tells models apart: near-ties by the noise, then simplicity.

Models that fit the same data can differ only in their last bits, or by less
than the noise in V_NLS; a choice that followed such a difference would
follow the processor, not the data. Every choice among models in lpvid
(the race of the starts, the start, the model on the l2,1 path, the refit)
counts two costs as tied when they differ by less than :data:`NOISE_SIGMAS`
standard deviations of the noise in V_NLS (``sqrt(M)`` for ``M`` complex
residuals: V_NLS at the true system has mean ``M`` and standard deviation
``sqrt(M)``), and decides a tie by simplicity: the scheduling dependence of
:meth:`lpvid.model.groups.GroupNorms.dependence`, then the cost, where
costs within :data:`COST_TIE` of each other are equal too and the order
in which the models were made decides (:func:`by_simplicity`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from lpvid.fit.settings import START_FTOL

if TYPE_CHECKING:
    from lpvid.data.frf import FrfData
    from lpvid.model.lpv import LpvModel

__all__ = [
    "COST_TIE",
    "DEPENDENCE_TIE",
    "NOISE_SIGMAS",
    "VALIDATION_TIE",
    "by_simplicity",
    "dependence",
    "identify_range",
    "noise_slack",
    "simplest",
    "tied",
]

#: Costs within this many standard deviations of the noise in V_NLS of the
#: best count as equal.
NOISE_SIGMAS = 2.0

#: Scheduling dependences within this fraction of the least count as equal
#: (then the cost decides).
DEPENDENCE_TIE = 0.05

#: Costs of equally simple models within this fraction of the lowest count
#: as equal, and the first of them in the order given wins. Ten times the
#: starts' stopping rule (:data:`lpvid.fit.settings.START_FTOL`: a fit ends
#: when a step buys less than 3e-4 of V_NLS): starts that reach the same
#: minimum by different routes stop short of it at different places, and a
#: 1e-12 change of the data moves where. With the rule at 1e-4 they ended up
#: to 3e-4 apart in validation V_NLS; at 3e-4 the twins smile:pairwise and
#: continuation+smile:pairwise of ``lpvid.testing.one_group_lpv`` (five
#: points) ended 2.4e-3 apart on one draw of three, and a tie of 1e-3 let
#: that draw choose the other (``docs/performance.md``).
COST_TIE = 10 * START_FTOL

#: Validation V_NLS within this fraction of the best counts as equal when
#: starts are compared (:func:`lpvid.initial.choose` and the race of the
#: starts).
VALIDATION_TIE = 0.02


def noise_slack(floor: float) -> float:
    """``NOISE_SIGMAS * sqrt(floor)``: the V_NLS difference within which two models tie."""
    return NOISE_SIGMAS * float(np.sqrt(max(float(floor), 0.0)))


def tied(costs: Sequence[float], floor: float, tolerance: float | None = None) -> list[bool]:
    """Which of ``costs`` tie with the best.

    By default a cost ties when it is within :func:`noise_slack` of the best
    (V_NLS on data with ``floor`` complex residuals); with ``tolerance``,
    when it is within that fraction of the best. Not finite costs never
    tie; when none is finite, none ties.

    Examples
    --------
    >>> tied([100.0, 115.0, 125.0, float("nan")], floor=100)
    [True, True, False, False]
    >>> tied([100.0, 101.0, 103.0], floor=100, tolerance=0.02)
    [True, True, False]

    """
    vals = np.asarray(costs, dtype=float)
    finite = np.isfinite(vals)
    if not finite.any():
        return [False] * vals.size
    best = float(vals[finite].min())
    limit = best + noise_slack(floor) if tolerance is None else (1.0 + tolerance) * best
    return [bool(f and v <= limit) for v, f in zip(vals, finite, strict=True)]


def identify_range(model: LpvModel, data: FrfData) -> Any:
    """The scheduling range a model is judged on: its basis domain, else the data's range."""
    return model.p_range if model.p_range is not None else data.p_range


def dependence(model: LpvModel, data: FrfData) -> float:
    """The scheduling dependence of ``model`` over :func:`identify_range`.

    See :meth:`lpvid.model.groups.GroupNorms.dependence`; 0 for an LTI model.
    """
    if model.n_basis == 0:
        return 0.0
    return model.group_norms(identify_range(model, data)).dependence()


def simplest(dependences: Sequence[float], costs: Sequence[float]) -> int:
    """The index of the simplest of tied models: the least dependence, then the lowest cost.

    Dependences within :data:`DEPENDENCE_TIE` of the least count as equal;
    among those, costs within :data:`COST_TIE` of the lowest count as equal
    and the first such model in the order given wins.

    Examples
    --------
    >>> simplest([0.50, 0.51, 2.0], [10.0, 9.0, 1.0])
    1
    >>> simplest([0.50, 0.51, 2.0], [10.005, 10.0, 1.0])
    0

    """
    return by_simplicity(dependences, costs)[0]


def by_simplicity(dependences: Sequence[float], costs: Sequence[float]) -> list[int]:
    """Indices of tied models from the simplest on: :func:`simplest` of all, then of the rest.

    Dependences and costs that are not finite count as infinite.

    Examples
    --------
    >>> by_simplicity([0.50, 0.51, 2.0, 0.2], [10.0, 9.0, 1.0, 50.0])
    [3, 1, 0, 2]

    """
    deps = [float(d) if np.isfinite(d) else math.inf for d in dependences]
    vals = [float(c) if np.isfinite(c) else math.inf for c in costs]
    if len(deps) != len(vals) or not deps:
        raise ValueError("dependences, costs: need the same length, at least one")
    left = list(range(len(deps)))
    order = []
    while left:
        least = min(deps[k] for k in left)
        near = [k for k in left if deps[k] <= least * (1 + DEPENDENCE_TIE) or deps[k] == least]
        lowest = min(vals[k] for k in near)
        limit = lowest + COST_TIE * abs(lowest)  # inf when no cost is finite
        pick = next(k for k in near if vals[k] <= limit)
        order.append(pick)
        left.remove(pick)
    return order
