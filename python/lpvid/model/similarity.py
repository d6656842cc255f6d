"""The directions in which a state-space realisation can move without changing its response.

A realisation is only defined up to a state transformation ``T``: ``(T A
T^-1, T B, C T^-1, D)`` has the same frequency response. For
``T = I + X`` with ``X`` small the parameters move along ``dA(i) = X A(i) -
A(i) X``, ``dB(i) = X B(i)``, ``dC(i) = -C(i) X``, ``dD(i) = 0`` (every
coefficient matrix ``i`` of an LPV model with a constant ``T``), to first
order. ``J^T J`` is singular along these directions; uncertainty figures are
computed on their complement.

With as many scheduling points as coefficient matrices (``N = Nb + 1``) the
coefficients are the unique interpolation of the frozen models at the
points, so a transformation applied at one point alone also leaves every
frozen response at the data unchanged
(:func:`pointwise_similarity_directions`): those directions are flat at the
data but change the model between the points.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

if TYPE_CHECKING:
    from lpvid.model.lpv import LpvModel

__all__ = [
    "similarity_directions",
    "free_similarity_directions",
    "pointwise_similarity_directions",
    "flat_at_points",
    "complement_basis",
]


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
    return _directions(model.A, model.B, model.C, model.D)


def _directions(
    A: NDArray[np.float64], B: NDArray[np.float64], C: NDArray[np.float64], D: NDArray[np.float64]
) -> NDArray[np.float64]:
    """The directions of :func:`similarity_directions` for coefficient stacks ``A``..``D``."""
    n = A.shape[1]
    out = np.zeros((A.size + B.size + C.size + D.size, n * n))
    for a in range(n):
        for b in range(n):
            X = np.zeros((n, n))
            X[a, b] = 1.0
            moved = [X[None] @ A - A @ X[None], X[None] @ B, -(C @ X[None]), np.zeros_like(D)]
            out[:, a + b * n] = np.concatenate([x.transpose(0, 2, 1).ravel() for x in moved])
    return out


def _point_weights(model: LpvModel, p: ArrayLike) -> NDArray[np.float64] | None:
    """``inv([1, psi(p)])`` when the points determine the coefficients, else None.

    Column ``k`` holds the coefficients of a change of the frozen model at
    point ``k`` alone; there is one only with ``N = Nb + 1`` well-placed points.
    """
    psi = model.basis_values(p)
    Psi = np.hstack([np.ones((psi.shape[0], 1)), psi])
    if Psi.shape[0] != Psi.shape[1] or np.linalg.cond(Psi) > 1e12:
        return None
    return np.linalg.inv(Psi)


def flat_at_points(model: LpvModel, p: ArrayLike) -> bool:
    """Whether :func:`pointwise_similarity_directions` has any direction at ``p``.

    True when the ``N`` scheduling points determine the ``Nb + 1``
    coefficient matrices (``N = Nb + 1``, the points apart); the directions
    themselves are not computed.
    """
    return _point_weights(model, p) is not None


def pointwise_similarity_directions(model: LpvModel, p: ArrayLike) -> NDArray[np.float64]:
    """The theta-directions of state transformations applied at one scheduling point alone.

    With ``N = Nb + 1`` scheduling points the coefficient matrices are the
    unique interpolation of the frozen models at the points; moving the
    frozen model at point ``k`` along ``X A(p_k) - A(p_k) X``, ``X B(p_k)``,
    ``-C(p_k) X`` and nowhere else is then a direction of theta along which
    every frozen response at the points stays the same to first order,
    while the model between the points changes. Their sum over the points
    is the transformation common to all points (:func:`similarity_directions`).

    Parameters
    ----------
    model : LpvModel
    p : array_like, shape (N,) or (N, Np)
        The scheduling points (usually ``data.p``).

    Returns
    -------
    ndarray, shape (len(theta), N * n * n)
        Column ``k n^2 + a + b n`` moves point ``k`` by ``X = e_a e_b^T``; no
        columns when ``N`` differs from ``Nb + 1`` or the points do not
        determine the coefficients (then no such direction is flat).
    """
    weights = _point_weights(model, p)
    if weights is None:
        return np.zeros((model.theta.size, 0))
    pts = np.asarray(p, dtype=float).reshape(weights.shape[0], -1)
    cols = []
    for k in range(weights.shape[0]):
        w = weights[:, k, None, None]
        frozen = model.at(pts[k] if pts.shape[1] > 1 else pts[k, 0])
        cols.append(_directions(*(w * x[None] for x in frozen)))
    return np.hstack(cols)


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
        held = T[~free]
        # Only ``vt`` is read: the full ``U`` (held x held) is made only
        # where ``vt`` needs it to be square (fewer held rows than
        # directions); else the thin one gives the same ``vt`` to the bit
        # (LAPACK's gesdd finds it the same way both ways).
        _, sv, vt = np.linalg.svd(held, full_matrices=held.shape[0] < held.shape[1])
        top = float(sv[0]) if sv.size else 0.0
        rank = int(np.sum(sv > 1e-10 * max(top, 1e-300)))
        T = T @ vt[rank:].T
    return T[free]


def complement_basis(T: NDArray[np.float64]) -> tuple[NDArray[np.float64], int]:
    """An orthonormal basis of the orthogonal complement of the columns of ``T``.

    Parameters
    ----------
    T : ndarray, shape (f, k)
        Directions (as from :func:`free_similarity_directions`).

    Returns
    -------
    Z : ndarray, shape (f, f - rank)
        Orthonormal columns orthogonal to every column of ``T``: the left
        singular vectors past its rank (no columns of ``T``: the identity).
    rank : int
        The rank of ``T``: its singular values above ``1e-10`` times the largest.
    """
    if not T.shape[1]:
        return np.eye(T.shape[0]), 0
    U, sv, _ = np.linalg.svd(T, full_matrices=True)
    rank = int(np.sum(sv > 1e-10 * sv[0])) if sv.size and sv[0] > 0 else 0
    return U[:, rank:], rank
