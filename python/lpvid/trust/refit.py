"""Refit on the support: undo the l2,1 shrinkage of the groups a regularised fit kept.

The l2,1 penalty pulls every group towards zero, the kept ones too, so the
regularised estimate is biased. Refitting V_NLS by Levenberg-Marquardt
with the dropped groups fixed at exactly zero keeps the structure the path
found and removes the bias; its first-order covariance
(:func:`lpvid.covariance`) is then that of an ordinary least-squares fit.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from lpvid._checks import positive_float
from lpvid.data import FrfData
from lpvid.fit import fit_nls
from lpvid.layout import MATRICES, fixed_mask
from lpvid.model import LpvModel
from lpvid.results import FitResult

__all__ = ["dropped_mask", "refit"]


def dropped_mask(model: LpvModel, threshold: float = 1e-6, p_range: Any = None) -> NDArray:
    """The entries of theta in groups whose relative magnitude is at most ``threshold``.

    Relative magnitudes as in :meth:`lpvid.LpvModel.group_norms` (the
    count of groups kept by the l2,1 fit uses the same rule).

    Returns
    -------
    ndarray of bool, shape (len(theta),)
    """
    th = positive_float(threshold, "threshold")
    if model.n_basis == 0:
        return np.zeros(model.theta.size, dtype=bool)
    rel = model.group_norms(p_range).relative
    spec = {x: [i + 1 for i in np.flatnonzero(rel[k] <= th)] for k, x in enumerate(MATRICES)}
    return fixed_mask(model, {x: v for x, v in spec.items() if v})


def refit(
    model: LpvModel,
    data: FrfData,
    fixed: Any = None,
    *,
    threshold: float = 1e-6,
    p_range: Any = None,
    stable: bool = False,
    **options: Any,
) -> tuple[FitResult, NDArray[np.bool_]]:
    """Levenberg-Marquardt on V_NLS with the dropped groups fixed at zero.

    Parameters
    ----------
    model : LpvModel
        Usually the result of :func:`lpvid.fit_l21`.
    data : FrfData
        The identification data.
    fixed : optional
        Parameters that were fixed in the fit (as in :func:`lpvid.fixed_mask`);
        they stay fixed.
    threshold : float
        Relative magnitude at or below which a group counts as dropped.
    p_range : optional
        Scheduling range for the group magnitudes and for ``stable``;
        default the model's.
    stable : bool
        Keep every frozen model on the range stable (see :func:`lpvid.fit_nls`).
    **options
        Further keywords of :func:`lpvid.fit_nls` (``max_iter``, ``xtol``, ...).

    Returns
    -------
    fit : FitResult
        The refitted model and its history.
    fixed : ndarray of bool
        The parameters held fixed: the given ones and the dropped groups (pass
        it to :func:`lpvid.covariance`).

    Examples
    --------
    >>> import numpy as np, lpvid
    >>> basis = lpvid.Polynomial(1, domain=(0.0, 1.0))
    >>> true = lpvid.LpvModel([[[0.5]], [[0.2]]], [[[1.0]], [[0.0]]], [[[1.0]], [[0.0]]],
    ...                       basis=basis, Ts=1.0)
    >>> f = np.linspace(0.01, 0.4, 30)
    >>> data = lpvid.FrfData([0.0, 0.5, 1.0], f, true.frf(f, [0.0, 0.5, 1.0]), sigma=1e-3, Ts=1.0)
    >>> shrunk = true.with_theta(true.theta * [1, 0.9, 1, 1, 1, 1, 1, 1])  # A(1) shrunk
    >>> fit, held = lpvid.refit(shrunk, data)   # B(1), C(1), D(1) are zero: held there
    >>> round(float(fit.model.A[1, 0, 0]), 6), int(held.sum())
    (0.2, 3)

    """
    free_given = ~fixed_mask(model, fixed)
    held = ~free_given | dropped_mask(model, threshold, p_range)
    start = model.with_theta(np.where(dropped_mask(model, threshold, p_range), 0.0, model.theta))
    fit = fit_nls(start, data, held, stable=stable, p_range=p_range, **options)
    return fit, held
