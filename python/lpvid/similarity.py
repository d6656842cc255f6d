"""The directions in which a state-space realisation can move without changing its response.

A realisation is only defined up to a state transformation ``T``: ``(T A
T^-1, T B, C T^-1, D)`` has the same frequency response. For
``T = I + X`` with ``X`` small the parameters move along ``dA(i) = X A(i) -
A(i) X``, ``dB(i) = X B(i)``, ``dC(i) = -C(i) X``, ``dD(i) = 0`` (every
coefficient matrix ``i`` of an LPV model with a constant ``T``), to first
order. ``J^T J`` is singular along these directions; uncertainty figures are
computed on their complement.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from lpvid.model import LpvModel

__all__ = ["similarity_directions", "free_similarity_directions"]


def similarity_directions(model: LpvModel) -> NDArray[np.float64]:
    """The theta-directions of the ``n^2`` elementary state transformations.

    Parameters
    ----------
    model : LpvModel

    Returns
    -------
    ndarray, shape (len(theta), n * n)
        Column ``a + b n`` is the direction of ``X = e_a e_b^T`` in the layout
        of :attr:`lpvid.LpvModel.theta`.
    """
    n = model.n_states
    out = np.zeros((model.theta.size, n * n))
    for a in range(n):
        for b in range(n):
            X = np.zeros((n, n))
            X[a, b] = 1.0
            dA = X[None] @ model.A - model.A @ X[None]
            dB = X[None] @ model.B
            dC = -(model.C @ X[None])
            dD = np.zeros_like(model.D)
            moved = [x.transpose(0, 2, 1).ravel() for x in (dA, dB, dC, dD)]
            out[:, a + b * n] = np.concatenate(moved)
    return out


def free_similarity_directions(model: LpvModel, free: NDArray[np.bool_]) -> NDArray[np.float64]:
    """Similarity directions that leave the fixed parameters alone, over the free ones.

    Parameters
    ----------
    model : LpvModel
    free : ndarray of bool, shape (len(theta),)
        The free parameters (see :func:`lpvid.free_mask`).

    Returns
    -------
    ndarray, shape (free.sum(), k)
        Directions (on the free parameters) spanning the transformations that
        keep every fixed parameter unchanged; not orthonormalised, so that a
        caller can scale them first.
    """
    T = similarity_directions(model)
    if np.any(~free):
        _, sv, vt = np.linalg.svd(T[~free])
        top = float(sv[0]) if sv.size else 0.0
        rank = int(np.sum(sv > 1e-10 * max(top, 1e-300)))
        T = T @ vt[rank:].T
    return T[free]
