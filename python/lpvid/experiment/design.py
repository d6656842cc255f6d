"""The information algebra behind :mod:`lpvid.experiment.nextpoints`.

Every quantity here lives on the frozen parameters ``[vec A; vec B; vec C;
vec D]`` of one frozen model (``L`` of them) and reaches theta through the
coefficient weights ``w = [1, psi(p)]`` (:func:`lpvid.trust.uncertainty.frozen_blocks`):
the information one FRF at ``p`` adds is ``P^T K P`` with ``K`` of size
``L x L``, so a candidate costs work of the size of one frozen model.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from lpvid.trust.relative import chunks
from lpvid.trust.uncertainty import frozen_blocks

__all__ = ["TIE", "factor", "greedy_update", "updated"]

#: Relative margin within which the criterion after two candidates ties:
#: predicted mean variances within 0.1 % of the lowest (bands within 0.05 %)
#: promise the same. The update agrees with an exact recomputation to about
#: 1e-7 of that variance on the benchmark's systems.
TIE = 1e-3


def factor(K: NDArray[np.float64]) -> NDArray[np.float64]:
    """``R`` (M, L, r) with ``R R^T = K`` for every (L, L) block, to working precision.

    The information of one frozen FRF has rank at most about ``L - n^2``
    (the frozen model's own state transformations leave its FRF unchanged):
    eigenvalues at or below ``L eps`` times a block's largest are dropped,
    the same number from every block.
    """
    lam, V = np.linalg.eigh(K)
    top = np.maximum(lam[:, -1:], np.finfo(float).tiny)
    keep = np.sum(lam > K.shape[1] * np.finfo(float).eps * top, axis=1)
    rank = max(1, int(np.max(keep)))
    lam, V = lam[:, -rank:], V[:, :, -rank:]
    return V * np.sqrt(np.maximum(lam, 0.0))[:, None, :]


def _reductions(
    C: NDArray, Q: NDArray, index: NDArray, w: NDArray, R: NDArray
) -> NDArray[np.float64]:
    """``tr(C W) - tr(C' W)`` for every candidate (``Q = C W C``).

    With ``C_c``, ``Q_c`` the frozen blocks of ``C``, ``Q`` at the candidate
    and ``R_c R_c^T`` its frozen information, Woodbury's identity gives the
    reduction ``tr((I/2 + R_c^T C_c R_c)^-1 R_c^T Q_c R_c)``.
    """
    m, L, r = R.shape
    red = np.empty(m)
    for sl in chunks(m, L * L):
        Rt = R[sl].transpose(0, 2, 1)
        S = 0.5 * np.eye(r) + Rt @ frozen_blocks(C, index, w[sl]) @ R[sl]
        T = Rt @ frozen_blocks(Q, index, w[sl]) @ R[sl]
        red[sl] = np.trace(np.linalg.solve(S, T), axis1=1, axis2=2)
    return red


def updated(
    C: NDArray[np.float64], index: NDArray[np.int_], w: NDArray[np.float64], R: NDArray
) -> NDArray[np.float64]:
    """The covariance once the information ``R R^T`` of a frozen FRF at weights ``w`` is added.

    ``C' = C - C_r (I/2 + R^T P C P^T R)^-1 C_r^T``, ``C_r = C P^T R`` with
    ``P`` taking theta to the frozen parameters: Woodbury's identity for
    ``C = (J^T J)^+ / 2`` and ``J^T J + P^T R R^T P``.
    """
    Cr = np.einsum("piu,i->pu", C[:, index], w) @ R
    Rpr = 0.5 * np.eye(R.shape[1]) + R.T @ frozen_blocks(C, index, w[None])[0] @ R
    out = C - Cr @ np.linalg.solve(Rpr, Cr.T)
    return 0.5 * (out + out.T)


def greedy_update(
    C: NDArray[np.float64],
    W: NDArray[np.float64],
    index: NDArray[np.int_],
    w: NDArray[np.float64],
    R: NDArray[np.float64],
    k: int,
    where: NDArray[np.float64],
    measured: NDArray[np.float64],
) -> tuple[list[int], NDArray[np.float64], NDArray[np.float64]]:
    """Choose ``k`` candidates greedily, each the one that lowers ``tr(C W)`` most.

    Candidates whose ``tr(C' W)`` lies within :data:`TIE` (relative) of
    the lowest tie: of those, the one farthest from every measured and every
    chosen point is taken (the first of equally far ones).

    Parameters
    ----------
    C : ndarray, shape (P, P)
        Covariance of theta.
    W : ndarray, shape (P, P)
        The form whose trace against ``C`` is the criterion.
    index : ndarray, shape (Nb+1, L)
        Where the frozen parameters sit in theta.
    w : ndarray, shape (M, Nb+1)
        Coefficient weights of the candidates.
    R : ndarray, shape (M, L, r)
        Factors ``R R^T`` of the information of one FRF at each candidate
        on its frozen parameters (:func:`factor`).
    k : int
        Points to choose (at most M).
    where : ndarray, shape (M, Np)
        The candidates' scheduling values, scaled (for the tie-break).
    measured : ndarray, shape (N, Np)
        The measured scheduling values, scaled alike.

    Returns
    -------
    picks : list of int
        Candidate indices, in the order chosen.
    variance : ndarray, shape (k + 1,)
        ``tr(C W)`` before and after each pick.
    C : ndarray, shape (P, P)
        The covariance after the last pick.
    """
    available = np.ones(len(w), dtype=bool)
    picks: list[int] = []
    values = [float(np.sum(C * W))]
    gap = np.min(np.linalg.norm(where[:, None, :] - measured[None, :, :], axis=2), axis=1)
    for _ in range(k):
        after = values[-1] - _reductions(C, C @ W @ C, index, w, R)
        after = np.where(available, after, np.inf)
        best = float(after.min())
        tied = np.flatnonzero(after <= best + TIE * abs(best))
        c = int(tied[np.argmax(gap[tied])])
        C = updated(C, index, w[c], R[c])
        gap = np.minimum(gap, np.linalg.norm(where - where[c], axis=1))
        available[c] = False
        picks.append(c)
        values.append(float(np.sum(C * W)))
    return picks, np.array(values), C
