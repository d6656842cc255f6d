"""Global starts: one good local model made constant, fitted to all points, then freed."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from lpvid._checks import positive_int
from lpvid._threads import single_blas
from lpvid.data.basis import Basis
from lpvid.data.frf import FrfData
from lpvid.data.schedule import model_range
from lpvid.fit.cost import check_compatible
from lpvid.fit.fits import fit_nls, raise_if_interrupted
from lpvid.fit.results import FitResult
from lpvid.fit.settings import START_FTOL
from lpvid.initial.continuation import best_determined
from lpvid.initial.local import identify_lti
from lpvid.initial.localmodels import LocalModels
from lpvid.initial.race import Runner, Stage
from lpvid.model.layout import fixed_mask, strictly_proper
from lpvid.model.lpv import LpvModel

__all__ = [
    "STAGES",
    "ConstantStart",
    "constant_start",
    "degree_levels",
    "finish_global",
    "free_groups",
    "global_runner",
    "global_start",
    "group_stages",
]


STAGES = ("all", "degree")


def degree_levels(basis: Basis) -> list[int]:
    """Degree level of every basis function: total degree for polynomial bases, else 1..Nb."""
    exps = getattr(basis, "exponents", None)
    if exps is not None and len(exps) == len(basis):
        return [int(sum(e)) for e in exps]
    return list(range(1, len(basis) + 1))


def _group_mask(model: LpvModel, indices: Sequence[int]) -> NDArray[np.bool_]:
    """True for every parameter of the coefficient matrices X(i), i in ``indices``."""
    idx = [int(i) for i in indices]
    return fixed_mask(model, {x: idx for x in "ABCD"}) if idx else fixed_mask(model, None)


@single_blas
def global_start(
    data: FrfData,
    order: int,
    basis: Basis,
    fixed: Any = None,
    *,
    local: LocalModels | None = None,
    point: int | None = None,
    stages: str = "all",
    max_iter: int = 100,
    ftol: float = START_FTOL,
) -> LpvModel:
    """An LPV start from one good local model: constant first, then the basis groups.

    1. The best-determined local model (:func:`lpvid.initial.best_determined`, or the one
       at ``point``) becomes a constant LPV model (every group ``X(i)``,
       ``i >= 1``, zero).
    2. :func:`lpvid.fit_nls` on all the data with only the constant part
       ``X(0)`` free: the LTI model that best fits every point.
    3. The groups are freed and refined with :func:`lpvid.fit_nls`: all at
       once (``stages="all"``) or one degree at a time (``stages="degree"``:
       first the degree-1 functions, then up to degree 2, ...; for a basis
       without degrees, one function at a time).

    The l2,1 path later removes what is not needed.

    Parameters
    ----------
    data : FrfData
        Identification data.
    order : int
        Number of states.
    basis : Basis
        Basis functions of the LPV model.
    fixed : optional
        Parameters kept fixed throughout (see :func:`lpvid.fixed_mask`);
        ``{"D": True}`` also makes the local models strictly proper.
    local : LocalModels, optional
        Local models to start from; default :func:`lpvid.identify_lti`.
    point : int, optional
        The local model to start from; default :func:`lpvid.initial.best_determined`.
    stages : {"all", "degree"}
        How the groups are freed.
    max_iter : int
        Most Levenberg-Marquardt steps per stage.
    ftol : float
        A stage ends when a step lowers V_NLS by less than ``ftol`` times it
        (default :data:`lpvid.fit.settings.START_FTOL`; see :func:`lpvid.fit_nls`).

    Returns
    -------
    LpvModel
        With ``info``: ``method`` ("global_start"), ``point``, ``stages``,
        and ``history``, one entry per stage (groups free, V_NLS after it,
        steps taken).

    """
    if stages not in STAGES:
        raise ValueError(f"stages: expected one of {STAGES}, got {stages!r}")
    const = constant_start(
        data, order, basis, fixed, local=local, point=point, max_iter=max_iter, ftol=ftol
    )
    return free_groups(const, data, fixed, stages, max_iter=max_iter, ftol=ftol)[0]


@dataclass
class ConstantStart:
    """A constant LPV model fitted to all the data: the first stage of a global start.

    Attributes
    ----------
    model : LpvModel
        Every group ``X(i)``, ``i >= 1``, zero; ``X(0)`` fitted to all points.
    point : int
        The local model it started from.
    history : list of dict
        One entry: groups free, V_NLS, steps taken.
    fit : FitResult
        The fit of the constant part.
    start : LpvModel
        The model that fit started from (the local model made constant).
    """

    model: LpvModel
    point: int
    history: list[dict[str, Any]]
    fit: FitResult
    start: LpvModel


def constant_start(
    data: FrfData,
    order: int,
    basis: Basis,
    fixed: Any = None,
    *,
    local: LocalModels | None = None,
    point: int | None = None,
    max_iter: int = 100,
    ftol: float = START_FTOL,
) -> ConstantStart:
    """Steps 1 and 2 of :func:`global_start`: the constant model that best fits every point.

    Arguments as in :func:`global_start`.
    """
    if not isinstance(data, FrfData):
        raise TypeError(f"data: expected an FrfData, got {type(data).__name__}")
    if not isinstance(basis, Basis):
        raise TypeError(f"basis: expected an lpvid basis, got {type(basis).__name__}")
    n = positive_int(order, "order")
    max_iter = positive_int(max_iter, "max_iter")
    proper = strictly_proper(fixed)
    if local is None:
        local = identify_lti(data, n, strictly_proper=proper)
    if len(local) != data.n_points or local.order != n:
        raise ValueError(
            f"local: expected {data.n_points} local models of order {n}, got {len(local)} "
            f"of order {local.order}"
        )
    if point is None:
        fixed_lti = {"D": True} if proper else None
        point = best_determined(local, data, fixed=fixed_lti) if len(local) > 1 else 0
    point = positive_int(point, "point", minimum=0)
    if point >= len(local):
        raise ValueError(f"point: expected an index below {len(local)}, got {point}")
    nb = len(basis)
    mats = [
        np.concatenate([x, np.zeros((nb, *x.shape[1:]))]) for x in local[point].matrices().values()
    ]
    model = LpvModel(*mats, basis=basis, Ts=data.Ts, p_range=model_range(data.p))
    check_compatible(model, data)
    mask = fixed_mask(model, fixed) | _group_mask(model, range(1, nb + 1))
    fit = raise_if_interrupted(fit_nls(model, data, mask, max_iter=max_iter, ftol=ftol, warn=False))
    history = [{"free_groups": "constant only", "vnls": float(fit.vnls), "n_iter": fit.n_iter}]
    return ConstantStart(fit.model, int(point), history, fit, model)


def group_stages(const: ConstantStart, fixed: Any, stages: str) -> list[Stage]:
    """The fits that free the groups of a constant start: all at once or degree by degree."""
    model = const.model
    user = fixed_mask(model, fixed)
    degrees = degree_levels(model.basis)
    levels = sorted(set(degrees)) if stages == "degree" else ([max(degrees)] if degrees else [])
    out = []
    for level in levels:
        frozen = [i + 1 for i, d in enumerate(degrees) if d > level]
        out.append(Stage(f"degree <= {level}", user | _group_mask(model, frozen)))
    return out


def global_runner(
    const: ConstantStart, fixed: Any, stages: str, max_iter: int = 100, ftol: float = START_FTOL
) -> Runner:
    """A :class:`~lpvid.initial.race.Runner` that frees the groups of a constant start."""
    stage_list = group_stages(const, fixed, stages)
    runner = Runner(f"global:{stages}", const.model, stage_list, max_iter=max_iter, ftol=ftol)
    if not runner.stages:  # no basis function: the constant model is the start
        runner.done, runner.fit, runner.start = True, const.fit, const.start
    return runner


def finish_global(runner: Runner, const: ConstantStart, stages: str) -> LpvModel:
    """Label a finished global runner's models (``info`` as in :func:`global_start`)."""
    history = list(const.history) + runner.history
    info = {"method": "global_start", "point": const.point, "stages": stages, "history": history}
    runner.model.info.update(info)
    # The start may be shared with other global starts: label a copy.
    base = runner.start if runner.start is not None else const.model
    start = base.with_theta(base.theta)
    start.info.update({**base.info, **info})
    runner.start = start
    return runner.model


def free_groups(
    const: ConstantStart,
    data: FrfData,
    fixed: Any,
    stages: str,
    *,
    max_iter: int = 100,
    ftol: float = START_FTOL,
) -> tuple[LpvModel, FitResult, LpvModel]:
    """Step 3 of :func:`global_start`: free the groups of a constant start.

    Returns
    -------
    model : LpvModel
        The global start (``info`` as in :func:`global_start`).
    fit : FitResult
        The last stage's fit.
    stage_start : LpvModel
        The model the last stage started from.
    """
    runner = global_runner(const, fixed, stages, max_iter, ftol)
    while not runner.done:
        runner.advance(data, max_iter)
    model = finish_global(runner, const, stages)
    assert runner.fit is not None and runner.start is not None
    return model, runner.fit, runner.start
