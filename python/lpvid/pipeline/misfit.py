"""A model far above its noise floor while the local models fit: tried harder, then said.

The local models fit each point with the most freedom an LTI model of the
order has; an LPV model that fits every point sits near their total, a
little above (it has fewer parameters per point). One more than
:data:`MISFIT` times above the larger of that total and the floor did not
find the fit the data hold (a start in the wrong basin, a structure the
points do not support), or, on validation data, does not hold between the
points. :func:`lpvid.identify` then tries harder (the blocks route from
every point and global starts from every point, :func:`global_everywhere`;
see :func:`lpvid.pipeline.opening.open_routes`) and, when the model returned
is still that far, warns with the figures and what to try; its summary
says so.
"""

from __future__ import annotations

import time
from concurrent.futures import Executor
from typing import Any

import numpy as np

from lpvid._spread import Spread
from lpvid._threads import single_blas
from lpvid.data.frf import FrfData
from lpvid.initial.candidates import Candidate, fitted_candidate
from lpvid.initial.globalstart import constant_start, free_groups
from lpvid.initial.localmodels import LocalModels

__all__ = ["FAR", "MISFIT", "advice", "far_fit", "global_everywhere", "local_level", "misfit"]

#: A model whose V_NLS is more than this many times the larger of its noise
#: floor and the local models' total is a misfit (on validation data: more
#: than this many times its floor).
MISFIT = 2.0

#: Without validation data, a chosen model whose V_NLS is more than this
#: many times the larger of its noise floor and the local models' total
#: (but no misfit) may come from a start in another basin than the data's fit:
#: :func:`lpvid.pipeline.opening.open_routes` then grows starts over the
#: points (:mod:`lpvid.initial.grown`) and follows those within the noise.
#: The models returned on ``bench_few.py``'s draws 0-39 (the synthetic
#: system and ``one_group_lpv`` at 3-6 points) sat at most 1.10 times above
#: their floor; the draw of the module notes of :mod:`lpvid.initial.grown`
#: 1.43 times (1.27 times the local models' 1.13).
FAR = 1.2


def local_level(local: LocalModels) -> float:
    """The local models' V_NLS over their noise floor, all points together (nan if unknown)."""
    floor = float(np.sum(local.noise_floor))
    total = float(np.sum(local.vnls))
    return total / floor if floor > 0 and np.isfinite(total) else float("nan")


def misfit(
    vnls: float,
    floor: int,
    local: LocalModels,
    validation_vnls: float | None = None,
    validation_floor: int | None = None,
) -> str | None:
    """What is wrong, in words, when a model is a misfit (module notes); None when it is not."""
    level = local_level(local)
    reference = _reference(level)
    ratio = vnls / floor
    if ratio > MISFIT * reference:
        return (
            f"V_NLS is {ratio:.3g} times its noise floor on the identification data, where "
            f"the local models fit at {level:.3g}"
        )
    if validation_vnls is not None and validation_floor:
        vratio = validation_vnls / validation_floor
        if vratio > MISFIT * reference:
            return (
                f"V_NLS is {vratio:.3g} times its noise floor on the validation data "
                f"({ratio:.3g} on the identification data, the local models {level:.3g})"
            )
    return None


def _reference(level: float) -> float:
    """The level a fit is judged against: the local models' (over the floor), at least 1."""
    return max(1.0, level) if np.isfinite(level) else 1.0


def far_fit(vnls: float, floor: int, local: LocalModels) -> str | None:
    """Why a fit sits in another basin than the data's (:data:`FAR`), in words; None when not."""
    level = local_level(local)
    ratio = vnls / floor
    if ratio <= FAR * _reference(level):
        return None
    return f"the model sat at {ratio:.3g} times its noise floor, the local models at {level:.3g}"


def advice(local: LocalModels) -> str:
    """What to try, in words, after a misfit the pipeline could not cure."""
    tips = []
    diag = local.consistency
    if diag is not None and diag.inconsistent:
        pts = ", ".join(str(q) for q in diag.inconsistent)
        tips.append(
            f"the local models at point(s) {pts} have another pole structure than their "
            "neighbours (lpvid.consistency): a measurement between them, or local models "
            "by continuation (lpvid.initial.continue_local), would tell which is right"
        )
    tips.append(
        "more measured points where the spread is largest (lpvid.next_points), a higher "
        "basis degree or order (lpvid.select), or validation data"
    )
    return "; ".join(tips)


def global_everywhere(
    problem: Any, local: LocalModels, executor: Executor | None = None
) -> list[Candidate]:
    """The global start with every group freed at once, from the local model of every point.

    The points side by side on ``executor`` (default here, one after the other).
    """
    data, starts = problem.data, problem.settings.starts
    how = (data, problem.order, problem.basis, problem.fixed, problem.validation, local)
    calls = [(*how, q, starts.max_iter, starts.ftol) for q in range(data.n_points)]
    return Spread(executor).map(_global_all, calls)


@single_blas
def _global_all(
    data: FrfData,
    order: int,
    basis: Any,
    fixed: Any,
    validation: FrfData | None,
    local: LocalModels,
    point: int,
    max_iter: int,
    ftol: float,
) -> Candidate:
    """:func:`global_everywhere`'s candidate from the local model at ``point``."""
    t0 = time.perf_counter()
    const = constant_start(
        data, order, basis, fixed, local=local, point=point, max_iter=max_iter, ftol=ftol
    )
    _, fit, start = free_groups(const, data, fixed, "all", max_iter=max_iter, ftol=ftol)
    note = f"constant model from local model {point}, then every group freed"
    seconds = time.perf_counter() - t0
    return fitted_candidate(
        f"global:all@{point}", fit, start, data, validation, seconds=seconds, note=note
    )
