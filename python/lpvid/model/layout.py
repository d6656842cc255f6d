"""Free and fixed parameters of a model (the mask over theta)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from lpvid.model._protocol import ModelLike

__all__ = ["MATRICES", "fixed_mask", "free_mask", "strictly_proper"]

#: The four state-space matrices, in the order of theta.
MATRICES = ("A", "B", "C", "D")


def fixed_mask(model: ModelLike, fixed: Any = None) -> NDArray[np.bool_]:
    """Which entries of ``model.theta`` stay at their current value.

    Parameters
    ----------
    model : LpvModel
        The model whose layout is used.
    fixed : None, dict or array_like of bool
        None: everything free. A flat boolean array of the length of theta:
        True where fixed. A dict keyed by ``"A"``, ``"B"``, ``"C"``, ``"D"``
        whose values are

        - ``True`` / ``False``: fix all coefficients of that matrix (or none);
        - an int or a list of ints ``i``: fix the coefficient matrices X(i)
          (0 is the constant part);
        - a boolean array of shape (Nb+1, rows, cols), or (rows, cols) to fix
          the same entries in every coefficient matrix.

    Returns
    -------
    ndarray of bool
        True where the parameter is fixed.

    Examples
    --------
    >>> import numpy as np, lpvid
    >>> m = lpvid.LpvModel(np.zeros((1, 2, 2)), np.ones((1, 2, 1)), np.ones((1, 1, 2)))
    >>> int(lpvid.fixed_mask(m, {"D": True}).sum())
    1

    """
    size = model.theta.size
    if fixed is None:
        return np.zeros(size, dtype=bool)
    if not isinstance(fixed, Mapping):
        arr = np.asarray(fixed)
        if arr.dtype != bool or arr.shape != (size,):
            raise ValueError(
                f"fixed: expected a dict such as {{'D': True}} or a boolean array of "
                f"length {size}, got {type(fixed).__name__} of shape {arr.shape}"
            )
        return arr.copy()
    unknown = set(fixed) - set(MATRICES)
    if unknown:
        raise ValueError(f"fixed: unknown matrix name(s) {sorted(unknown)}; use A, B, C or D")
    parts = []
    for x, coef in model.matrices().items():
        spec = fixed.get(x, False)
        k, rows, cols = coef.shape
        mask = np.zeros((k, rows, cols), dtype=bool)
        if isinstance(spec, (bool, np.bool_)):
            mask[:] = bool(spec)
        elif isinstance(spec, (int, np.integer)) or (
            isinstance(spec, (list, tuple)) and all(isinstance(v, (int, np.integer)) for v in spec)
        ):
            idx = np.atleast_1d(np.asarray(spec, dtype=int))
            if np.any((idx < 0) | (idx >= k)):
                raise ValueError(
                    f"fixed[{x!r}]: coefficient indices must be in 0..{k - 1}, got {spec}"
                )
            mask[idx] = True
        else:
            arr = np.asarray(spec)
            if arr.dtype != bool:
                raise TypeError(f"fixed[{x!r}]: expected True/False, indices or a boolean array")
            if arr.shape == (rows, cols):
                arr = np.broadcast_to(arr, (k, rows, cols))
            if arr.shape != (k, rows, cols):
                raise ValueError(
                    f"fixed[{x!r}]: expected a boolean array of shape {(k, rows, cols)} "
                    f"or {(rows, cols)}, got {arr.shape}"
                )
            mask[:] = arr
        parts.append(mask.transpose(0, 2, 1).ravel())
    return np.concatenate(parts)


def free_mask(model: ModelLike, fixed: Any = None) -> NDArray[np.bool_]:
    """The complement of :func:`fixed_mask`: True where a parameter is free."""
    return ~fixed_mask(model, fixed)


def strictly_proper(fixed: Any) -> bool:
    """Whether ``fixed`` keeps all of D (``{"D": True}``): local models are then strictly proper."""
    return isinstance(fixed, dict) and fixed.get("D") is True
