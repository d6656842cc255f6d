"""How many parameters a data set can determine: the order check of :func:`lpvid.identify`."""

from __future__ import annotations

from typing import Any

import numpy as np

from lpvid.data.basis import Basis
from lpvid.data.frf import FrfData
from lpvid.model.layout import free_mask
from lpvid.model.lpv import LpvModel

__all__ = ["check_order", "zero_model"]


def zero_model(n: int, basis: Basis, data: FrfData) -> LpvModel:
    """The all-zero LPV model of order ``n`` over ``basis`` with the data's inputs and outputs.

    Its layout is what masks such as :func:`lpvid.fixed_mask` need.
    """
    k, r, l = len(basis) + 1, data.n_inputs, data.n_outputs
    return LpvModel(
        np.zeros((k, n, n)), np.zeros((k, n, r)), np.zeros((k, l, n)), basis=basis, Ts=data.Ts
    )


def check_order(n: int, basis: Basis, data: FrfData, fixed: Any) -> None:
    """Refuse an order whose LPV model has more parameters than the data can determine.

    Parameters
    ----------
    n : int
        Number of states.
    basis : Basis
    data : FrfData
    fixed : optional
        Fixed parameters, as in :func:`lpvid.fixed_mask`.

    Raises
    ------
    ValueError
        Naming ``order``, the count and the largest order the data allow.

    Notes
    -----
    The free parameters less the ``n^2`` of the state coordinates must not
    exceed the ``2 M`` real equations of the ``M`` complex residuals: beyond
    that the fit is undetermined (and would take long to find out).
    """

    def excess(order: int) -> tuple[int, int]:
        free = int(free_mask(zero_model(order, basis, data), fixed).sum())
        return free, free - order * order - 2 * data.n_residuals

    free, over = excess(n)
    if over > 0:
        # the excess grows with the order: bisect for the largest order without one
        limit, above = 0, n
        while above - limit > 1:
            mid = (limit + above) // 2
            limit, above = (mid, above) if excess(mid)[1] <= 0 else (limit, mid)
        raise ValueError(
            f"order: {n} states with {len(basis)} basis functions give {free} free parameters; "
            f"less the {n * n} of the state coordinates that is more than the "
            f"{2 * data.n_residuals} real equations of the data's {data.n_residuals} complex "
            f"residuals (at most order {limit})"
        )
