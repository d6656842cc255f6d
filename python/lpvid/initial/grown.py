"""Starts grown over the points: fitted where a root's neighbours lie, then one point at a time.

Every other start is built from all the local models at once. Where the
local models at some points missed a mode (two close modes seen as one, a
pole out of the band in its place: the data there hardly see it), every
start built from them may end in another basin than the data's fit. On
``one_group_lpv(20)`` at eight points (``benches/bench_plan.py``'s loop,
draw 20, its fifth added point) every start of
:func:`lpvid.initial_candidates` ended at 1.40 times the noise floor (the
truth: 1.00) and the model returned was 0.033 off between the points;
the start grown from ``p = 0`` ended at 0.94 of the floor, and the model
from it 0.0067 off. :func:`lpvid.pipeline.opening.open_routes` grows them
when the chosen model sits far above the local models
(:data:`lpvid.pipeline.misfit.FAR`).

A grown start from point ``q``: the points in the order of
:func:`lpvid.data.schedule.propagation_order` from ``q`` (the chain walked
outwards in one dimension, the spanning tree breadth first in more); the
constant model of ``q``'s local model fitted on the first ``Nb + 1`` of them
with every group freed (:func:`lpvid.initial.globalstart.constant_start`,
:func:`~lpvid.initial.globalstart.free_groups` with ``"all"``), then
Levenberg-Marquardt on one point more at a time, from the fit before,
until every point is in. On the draw above one root of eight (``p = 0``)
found the basin; fitting every point at once after the seed, instead of one
more at a time, ended higher from six of the eight roots (0.945 against
0.935 of the floor from ``p = 0``, 1.33 against 1.24 from ``p = 1``) and
lower from two (by under 1 %).
"""

from __future__ import annotations

import time
from concurrent.futures import Executor
from typing import Any

import numpy as np

from lpvid._spread import Spread
from lpvid._threads import single_blas
from lpvid.data.basis import Basis
from lpvid.data.frf import FrfData
from lpvid.data.schedule import model_range, propagation_order
from lpvid.fit.cost import vnls_value
from lpvid.fit.fits import fit_nls, raise_if_interrupted
from lpvid.initial.candidates import Candidate, fitted_candidate
from lpvid.initial.globalstart import constant_start, free_groups
from lpvid.initial.localmodels import LocalModels
from lpvid.model.lpv import LpvModel

__all__ = ["GROWN", "grown_everywhere", "grown_start"]

#: The names of the grown starts: ``grown@q``, ``q`` the root.
GROWN = "grown@"


def grown_everywhere(
    data: FrfData,
    order: int,
    basis: Basis,
    fixed: Any,
    local: LocalModels,
    *,
    validation: FrfData | None = None,
    max_iter: int = 100,
    ftol: float,
    executor: Executor | None = None,
) -> list[Candidate]:
    """A grown start from every point (module notes), side by side on ``executor``.

    None at all (an empty list) when the points are no more than the basis
    functions plus one: the first fit then has every point already. A root
    whose walk meets a point where its model cannot be evaluated gives none.
    """
    if data.n_points <= len(basis) + 1:
        return []
    how = (data, order, basis, fixed, local, validation, max_iter, ftol)
    grown = Spread(executor).map(grown_start, [(*how, q) for q in range(data.n_points)])
    return [c for c in grown if c is not None]


@single_blas
def grown_start(
    data: FrfData,
    order: int,
    basis: Basis,
    fixed: Any,
    local: LocalModels,
    validation: FrfData | None,
    max_iter: int,
    ftol: float,
    root: int,
) -> Candidate | None:
    """The grown start from point ``root`` (module notes), refined on every point.

    None when a point joins where the model so far has no finite V_NLS (a
    pole on a measured line): no fit can start there.
    """
    t0 = time.perf_counter()
    walk = [int(q) for q in propagation_order(data.p_rows, root)[0]]
    first = len(basis) + 1
    seed = sorted(walk[:first])
    seeded = data.subset(seed)
    const = constant_start(
        seeded,
        order,
        basis,
        fixed,
        local=local.subset(seed),
        point=seed.index(root),
        max_iter=max_iter,
        ftol=ftol,
    )
    _, fit, start = free_groups(const, seeded, fixed, "all", max_iter=max_iter, ftol=ftol)
    # the seed's model knows the seed's range only: the whole data's from here on
    model = LpvModel(
        *fit.model.matrices().values(), basis=basis, Ts=data.Ts, p_range=model_range(data.p)
    )
    have = seed
    for q in walk[first:]:
        have = sorted([*have, q])
        points = data.subset(have)
        if not np.isfinite(vnls_value(model, points)):
            return None
        start = model
        fit = raise_if_interrupted(
            fit_nls(model, points, fixed, max_iter=max_iter, ftol=ftol, warn=False)
        )
        model = fit.model
    note = (
        f"constant model from local model {root} fitted at points {seed} with every group "
        f"freed, then refitted as points {walk[first:]} joined one at a time"
    )
    return fitted_candidate(
        f"{GROWN}{root}", fit, start, data, validation, seconds=time.perf_counter() - t0, note=note
    )
