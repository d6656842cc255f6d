"""Local models by continuation along the scheduling axes, from the best-determined point."""

from __future__ import annotations

from concurrent.futures import Executor
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lpvid._checks import positive_float, positive_int, real_array
from lpvid._spread import Spread, side_by_side
from lpvid._threads import single_blas
from lpvid.data.frf import FrfData
from lpvid.data.schedule import subtrees, unit_scaled
from lpvid.fit.fits import fit_nls, raise_if_interrupted
from lpvid.fit.memory import covariance_memory
from lpvid.initial.coherent import propagation_order
from lpvid.initial.diagnosis import Consistency, consistency
from lpvid.initial.localmodels import LocalModels
from lpvid.initial.poles import pole_distance, pole_uncertainty
from lpvid.model.lpv import LpvModel

__all__ = ["best_determined", "continuation_order", "continue_local"]


def best_determined(
    local_models: LocalModels,
    data: FrfData,
    diagnosis: Consistency | None = None,
    fixed: Any = None,
) -> int:
    """The point to start a continuation from: the best-determined local model.

    Among the points that the diagnosis does not flag, whose model is
    stable and whose V_NLS relative to the noise floor is within two
    standard deviations of the best (``2 / sqrt(F l r)``), the one whose
    least certain pole is the most certain (:func:`pole_uncertainty`).

    Parameters
    ----------
    local_models : LocalModels
    data : FrfData
        The data the models were identified from.
    diagnosis : Consistency, optional
        Default :func:`consistency` of ``local_models``.
    fixed : optional
        Fixed parameters of the local models (``{"D": True}`` when strictly proper).

    Returns
    -------
    int

    """
    diag = consistency(local_models) if diagnosis is None else diagnosis
    N = len(local_models)
    floor = np.maximum(np.asarray(local_models.noise_floor, dtype=float), 1.0)
    rel = np.asarray(local_models.vnls, dtype=float) / floor
    rel = np.where(np.isfinite(rel), rel, np.inf)
    tol = 2.0 / np.sqrt(floor)
    ok = [q for q in range(N) if q not in diag.inconsistent and not local_models.unstable[q]]
    ok = ok or list(range(N))
    ok = [q for q in ok if rel[q] <= np.min(rel[ok]) + tol[q]] or ok
    # One covariance of a local model each (numpy's), side by side.
    P = local_models[ok[0]].theta.size
    values = side_by_side(
        _least_certain,
        [(local_models, data, q, fixed) for q in ok],
        flops=20.0 * P**3,
        each=covariance_memory(P, P),
    )
    spread = dict(zip(ok, values, strict=True))
    return min(ok, key=lambda q: (spread[q], rel[q]))


def _least_certain(local_models: LocalModels, data: FrfData, q: int, fixed: Any) -> float:
    """The largest pole uncertainty of local model ``q`` (inf when it cannot be had).

    Kept on ``local_models`` for ``data`` and a ``fixed`` given as None or a
    dict of flags: :func:`lpvid.identify` asks for it for the continuation
    and again for the blocks route's start points.
    """
    flags = fixed is None or (
        isinstance(fixed, dict) and all(isinstance(v, bool) for v in fixed.values())
    )
    key = ("least certain pole", q, None if fixed is None else tuple(sorted(fixed.items())))
    kept = local_models._derived.get(key) if flags else None
    if kept is not None and kept[0] is data:
        return float(kept[1])
    try:
        value = float(np.max(pole_uncertainty(local_models[q], data.subset([q]), fixed)))
    except (np.linalg.LinAlgError, ValueError):
        value = np.inf
    if flags:
        local_models._derived[key] = (data, value)
    return value


def continuation_order(p: ArrayLike, root: int) -> tuple[NDArray[np.int_], NDArray[np.int_]]:
    """The walk of a continuation: points in visiting order and their parents.

    Along the minimum spanning tree of the points (scaled scheduling space),
    breadth first from ``root``: in one dimension outwards along the sorted
    points, for several parameters along a nearest-neighbour tree
    (:func:`lpvid.data.schedule.propagation_order`).

    Parameters
    ----------
    p : array_like, shape (N,) or (N, Np)
    root : int

    Returns
    -------
    order : ndarray of int
        The root first; every point after its parent.
    parent : ndarray of int
        ``parent[q]``: the visited neighbour point q starts from (-1 for the root).

    """
    arr = real_array(p, "p", ndim=(1, 2))
    arr = arr.reshape(arr.shape[0], -1)
    root = positive_int(root, "root", minimum=0)
    return propagation_order(arr, root)


@single_blas
def _walk(
    branch: list[int],
    data: FrfData,
    local: LocalModels,
    parent: NDArray[np.int_],
    fixed: Any,
    tol: float,
    max_iter: int,
    diag: Consistency,
) -> dict[int, tuple[LpvModel, float, LpvModel | None]]:
    """:func:`continue_local` along one branch of the tree, its points in order.

    Per point: its model, V_NLS, and the start it was continued from (None
    where the plain model was kept).
    """
    scaled = unit_scaled(data.p)
    kept: dict[int, LpvModel] = {}
    out = {}
    for q in branch:
        m = int(parent[q])
        start = kept.get(m, local[m])
        point = data.subset([q])
        floor = float(point.n_residuals)
        target = min(float(local.vnls[q]), floor) + tol * np.sqrt(floor)

        def stop(row: dict[str, Any], target: float = target) -> bool:
            return bool(row["vnls"] > target)  # False stops the fit

        fit = raise_if_interrupted(
            fit_nls(start, point, fixed, max_iter=max_iter, callback=stop, warn=False)
        )
        cont = LpvModel(
            *fit.model.matrices().values(),
            basis=start.basis,
            Ts=data.Ts,
            info={
                "method": "continuation + fit_nls",
                "start": f"point {m}",
                "n_iter": int(fit.n_iter),
            },
        )
        # Both starts are acceptable when they fit within the noise of the
        # better one; of those, the ones consistent with the parent's model
        # (pole distance within the diagnosis' allowance for this step) are
        # preferred, the continued one first (it also keeps the state
        # coordinates of its neighbour); else the one nearest the parent.
        best_v = min(fit.vnls, float(local.vnls[q]))
        options = {"continuation": (cont, fit.vnls), "plain": (local[q], float(local.vnls[q]))}
        fits_ok = [k for k, (_, v) in options.items() if v <= best_v + tol * np.sqrt(floor)]
        step = float(np.linalg.norm(scaled[q] - scaled[m]))
        allowed = max(diag.threshold * diag.reference * step, diag.min_distance)
        dist = {k: pole_distance(options[k][0], start) for k in fits_ok}
        near = [k for k in fits_ok if dist[k] <= allowed]
        choice = near[0] if near else min(fits_ok, key=lambda k: dist[k])
        kept[q], cost = options[choice]
        out[q] = (kept[q], float(cost), start if choice == "continuation" else None)
    return out


@single_blas
def continue_local(
    data: FrfData,
    local: LocalModels,
    *,
    root: int | None = None,
    strictly_proper: bool = False,
    tolerance: float = 1.0,
    max_iter: int = 100,
    diagnosis: Consistency | None = None,
    executor: Executor | None = None,
) -> LocalModels:
    """Local models by continuation along the scheduling axes.

    Starting from the best-determined point (:func:`best_determined`), each
    next point's model is refined by :func:`lpvid.fit_nls` on that point's
    data from the model of the point before it, walking outwards along a
    nearest-neighbour tree (:func:`continuation_order`). The refinement stops
    as soon as V_NLS comes within ``tolerance * sqrt(F l r)`` of the best
    that point allows (the lower of the plain model's V_NLS and the noise
    floor ``F l r``): the models then stay on one branch and in nearly the
    same state coordinates as their neighbours.

    Per point, of the continued and the plain model, those whose V_NLS is
    within ``tolerance * sqrt(F l r)`` of the better one fit equally well;
    of these, the ones whose poles stay near the parent's (worst matched
    pole distance within the diagnosis' allowance for the step,
    ``max(threshold * reference * step, min_distance)``, see
    :class:`Consistency`) are consistent, and the continued one is
    preferred among them; when none is consistent, the one nearest the
    parent is kept. The walk goes on from the kept model.

    Parameters
    ----------
    data : FrfData
        The data the plain local models were identified from.
    local : LocalModels
        Plain local models (:func:`lpvid.identify_lti`).
    root : int, optional
        The point to start from; default :func:`best_determined`.
    strictly_proper : bool
        Keep D at zero.
    tolerance : float
        Slack on V_NLS in standard deviations of the noise floor
        (``sqrt(F l r)``).
    max_iter : int
        Most Levenberg-Marquardt steps per point.
    diagnosis : Consistency, optional
        :func:`lpvid.consistency` of ``local``, when already computed.
    executor : concurrent.futures.Executor, optional
        Where the walks run: the tree below each neighbour of the root is
        one walk (in one dimension, the points on either side of it), side
        by side on ``executor`` (default here, one after the other). The
        models are the same either way.

    Returns
    -------
    LocalModels
        With ``starts`` saying, per point, which start the model came from
        (``"plain"`` for the root and for points that kept the plain model,
        ``"continuation from q"`` otherwise) and ``consistency``, the
        diagnosis of the plain models.

    """
    if not isinstance(data, FrfData):
        raise TypeError(f"data: expected an FrfData, got {type(data).__name__}")
    if not isinstance(local, LocalModels):
        raise TypeError(f"local: expected LocalModels, got {type(local).__name__}")
    if len(local) != data.n_points:
        raise ValueError(f"local: {len(local)} models for {data.n_points} data points")
    tol = positive_float(tolerance, "tolerance", allow_zero=True)
    max_iter = positive_int(max_iter, "max_iter")
    if len(local) < 2:
        raise ValueError("local: a continuation needs at least two points")
    diag = consistency(local) if diagnosis is None else diagnosis
    fixed = {"D": True} if strictly_proper else None
    if root is None:
        root = best_determined(local, data, diag, fixed)
    order, parent = continuation_order(data.p, root)
    models: list[LpvModel] = list(local)
    costs = np.array(local.vnls, dtype=float)
    conv = np.array(local.converged, dtype=bool)
    starts = ["plain"] * data.n_points
    initial: list[LpvModel] = list(local.initial) if local.initial is not None else list(local)
    how = (data, local, parent, fixed, tol, max_iter, diag)
    walks = [(branch, *how) for branch in subtrees(order, parent)]
    for walked in Spread(executor).map(_walk, walks):
        for q, (model, cost, start) in walked.items():
            models[q], costs[q] = model, cost
            if start is not None:  # the continued model was kept
                conv[q] = True
                starts[q] = f"continuation from {parent[q]}"
                initial[q] = start
    out = LocalModels(
        models,
        data.p,
        data.freqs_hz,
        costs,
        local.noise_floor,
        conv,
        initial,
        starts=starts,
        consistency=diag,
    )
    return out
