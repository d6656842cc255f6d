"""Directions of a model that the measured points hardly see: what the points leave open.

A model structure (its free parameters: the groups it keeps, less what is
fixed) is determined between the points when every change of its
parameters that alters its frozen FRF somewhere on the scheduling range
also alters it at the measured points. The information of the frozen FRFs
(their sensitivity to the parameters on the data's lines, weighted by
``1 / sigma^2``) is taken twice: averaged over the measured points
(``I_p``) and over a grid on the whole range (``I_r``); changes of the
state coordinates, which no frozen FRF sees, are left out of both. For
every direction ``v`` the range sees, ``v^T I_p v / v^T I_r v`` is the share
of its effect that the points see (the generalised eigenvalues of the
pair; 1 for a direction seen alike everywhere). A direction whose share is
below :data:`SEEN` (0.01 %: its effect at the points is under 1 % of its
effect over the range, in RMS) is *silent*: the data cannot pin it down,
yet the model between the points moves along it. A count above zero means
that the measured points leave a family of models that fit them equally
well and differ between them, and that the choice among them is the
prior's (the path's simplicity, the start), not the data's.

Directions that the range itself hardly sees (information below
:data:`VISIBLE` times the largest, on the Jacobi-scaled matrix) are not
counted either way. One more point adds at most as many seen directions
as one measured point sees on its own (``per_point``, the median over the
points), so at least ``ceil(silent / per_point)`` more points are needed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from lpvid.data.frf import FrfData
from lpvid.data.schedule import range_pairs, scale_grid
from lpvid.fit.judge import identify_range
from lpvid.model.layout import fixed_mask
from lpvid.model.lpv import LpvModel
from lpvid.model.similarity import complement_basis, free_similarity_directions
from lpvid.trust.uncertainty import _lti_index, coefficient_weights, frozen_grams, projected

__all__ = [
    "SilentCount",
    "least_seen",
    "openness",
    "range_grid",
    "seen_covariance",
    "silent_directions",
]

#: Scheduling values per axis of the grid over the range, by the number of
#: scheduling parameters (3 per axis beyond three).
GRID = {1: 41, 2: 9, 3: 5}

#: A direction is seen by the points when their mean information along it
#: is at least this share of the range's mean (0.01 %, 1 % in RMS).
SEEN = 1e-4

#: Directions whose information over the range is below this share of the
#: largest (Jacobi-scaled) are left out: hardly any frozen FRF on the range
#: shows them, and the shares are computed on directions scaled by up to
#: ``VISIBLE ** -0.5``: below it rounding would make them up (at 1e-12 a
#: direction no FRF sees to first order came out as silent).
VISIBLE = 1e-9


@dataclass(frozen=True)
class SilentCount:
    """How many directions of a model structure the measured points leave open.

    Attributes
    ----------
    silent : int
        Directions the range sees and the points hardly do (see the module notes).
    at_points : int
        Directions the points see.
    over_range : int
        Directions the frozen FRFs over the range see (less the state coordinates').
    per_point : int
        Directions one measured point sees on its own (the median over the points).
    n_free : int
        Free parameters of the structure.
    seen : ndarray
        The share of each direction's effect that the points see, ascending.
    """

    silent: int
    at_points: int
    over_range: int
    per_point: int
    n_free: int
    seen: NDArray[np.float64] = field(repr=False, default_factory=lambda: np.zeros(0))

    @property
    def determined(self) -> bool:
        """Whether the measured points determine the structure between them."""
        return self.silent == 0

    @property
    def points_needed(self) -> int:
        """At least this many more points are needed to determine the structure."""
        if self.silent == 0:
            return 0
        return math.ceil(self.silent / max(self.per_point, 1))

    def describe(self) -> str:
        """One sentence."""
        if self.determined:
            return (
                f"the measured points determine the chosen structure between them "
                f"(all {self.over_range} directions seen)"
            )
        return (
            f"the measured points leave {self.silent} of the {self.over_range} directions of "
            f"the chosen structure open between them (one point sees at most "
            f"{self.per_point}): at least {self.points_needed} more point(s) to determine it"
        )


def range_grid(model: LpvModel, data: FrfData) -> NDArray[np.float64]:
    """A grid over the scheduling range the model is judged on: (Q, Np).

    41 values for one parameter, 9 per axis for two, 5 for three, 3 beyond,
    evenly on every parameter's scale (``log10(p)`` for a basis on the log
    scale).
    """
    pairs = range_pairs(identify_range(model, data), model.basis.n_params)
    return scale_grid(pairs, GRID.get(len(pairs), 3), model.basis.scales)


def _sym(M: NDArray[np.float64]) -> NDArray[np.float64]:
    return 0.5 * (M + M.T)


def _whitening(I_range: NDArray[np.float64]) -> NDArray[np.float64]:
    """``W`` with ``W^T I_range W = I`` on the directions the range sees (see :data:`VISIBLE`)."""
    S = _sym(I_range)
    d = np.sqrt(np.maximum(np.diag(S), 1e-300))
    lam, V = np.linalg.eigh(S / d[:, None] / d[None, :])
    keep = lam > VISIBLE * max(float(lam[-1]) if lam.size else 0.0, 0.0)
    return (V[:, keep] / np.sqrt(lam[keep])) / d[:, None]


@dataclass(frozen=True, eq=False)
class _Pair:
    """The information at the points and over the range, on the structure's directions."""

    at_points: NDArray[np.float64]  # (K, K): mean over the points
    each: NDArray[np.float64]  # (N, K, K): every point alone
    whiten: NDArray[np.float64]  # (K, R): W^T I_range W = I on the directions the range sees
    to_free: NDArray[np.float64]  # (F, K): directions in the free parameters
    free: NDArray[np.bool_]


def _structure(model: LpvModel, data: FrfData, fixed: Any, threshold: float) -> NDArray[np.bool_]:
    """The free parameters: not fixed, not in a group at or below ``threshold``."""
    held = fixed_mask(model, fixed)
    if model.n_basis:
        keep = model.group_norms(identify_range(model, data)).nonzero(threshold)
        nb = model.n_basis
        drop = {x: [i for i in range(1, nb + 1) if i not in keep.get(x, [])] for x in "ABCD"}
        held = held | fixed_mask(model, drop)
    return ~held


def _pair(model: LpvModel, data: FrfData, fixed: Any, threshold: float) -> _Pair:
    free = _structure(model, data, fixed, threshold)
    index = _lti_index(model)
    grid = range_grid(model, data)
    # The measured points with their own sigma; the grid with the data's
    # sigma at the nearest measured point (each parameter scaled to the range).
    pairs = range_pairs(identify_range(model, data), model.basis.n_params)
    lo = np.array([a for a, _ in pairs])
    span = np.array([b - a for a, b in pairs])
    measured = (data.p_rows - lo) / span
    at = (grid - lo) / span
    nearest = np.argmin(((at[:, None, :] - measured[None, :, :]) ** 2).sum(axis=2), axis=1)
    K_data = frozen_grams(model, data.freqs_hz, data.p, 1.0 / data.sigma**2)
    K_grid = frozen_grams(model, data.freqs_hz, grid, 1.0 / data.sigma[nearest] ** 2)
    Z, _ = complement_basis(free_similarity_directions(model, free))
    P = model.theta.size

    def on_z(K: NDArray, w: NDArray) -> NDArray:
        """``Z^T (sum_m (w_m w_m^T) (x) K_m) Z`` on the free parameters."""
        blocks = np.einsum("mi,muv,mj->iujv", w, K, w, optimize=True)
        full = np.zeros((P, P))
        full[index[:, :, None, None], index[None, None, :, :]] = blocks
        return projected(full[np.ix_(free, free)], Z)

    w_data = coefficient_weights(model, data.p)
    each = np.array([on_z(K_data[m : m + 1], w_data[m : m + 1]) for m in range(data.n_points)])
    W = _whitening(on_z(K_grid, coefficient_weights(model, grid)) / len(grid))
    return _Pair(each.mean(axis=0), each, W, Z, free)


def silent_directions(
    model: LpvModel, data: FrfData, fixed: Any = None, *, threshold: float = 1e-6
) -> SilentCount:
    """Count the directions of a model's structure that the measured points leave open.

    See the module notes.

    Parameters
    ----------
    model : LpvModel
        A fitted model; its structure is its free parameters less the
        groups whose relative magnitude is at or below ``threshold``.
    data : FrfData
        The identification data (points, lines and sigma).
    fixed : optional
        Parameters held fixed (as in :func:`lpvid.fixed_mask`).
    threshold : float
        Relative group magnitude at or below which a group counts as dropped.

    Returns
    -------
    SilentCount
    """
    return _count(_pair(model, data, fixed, threshold))


def _count(pair: _Pair) -> SilentCount:
    W = pair.whiten
    seen = np.linalg.eigvalsh(_sym(W.T @ pair.at_points @ W))
    per = [int(np.sum(np.linalg.eigvalsh(_sym(W.T @ K @ W)) >= SEEN)) for K in pair.each]
    silent = int(np.sum(seen < SEEN))
    return SilentCount(
        silent=silent,
        at_points=W.shape[1] - silent,
        over_range=W.shape[1],
        per_point=int(np.median(per)),
        n_free=int(pair.free.sum()),
        seen=np.sort(seen),
    )


def least_seen(
    model: LpvModel, data: FrfData, fixed: Any = None, *, threshold: float = 1e-6
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """The direction of the structure whose effect the points see least, and the free mask.

    The direction is in the free parameters (``theta[free]``), the
    generalised eigenvector of the smallest share (module notes).
    """
    pair = _pair(model, data, fixed, threshold)
    W = pair.whiten
    _, vecs = np.linalg.eigh(_sym(W.T @ pair.at_points @ W))
    return pair.to_free @ (W @ vecs[:, 0]), pair.free


def seen_covariance(
    model: LpvModel, data: FrfData, fixed: Any = None, *, threshold: float = 1e-6
) -> tuple[NDArray[np.float64], NDArray[np.bool_], int]:
    """The first-order covariance of theta on the directions the points see.

    ``(J^T J)^+ / 2`` as in :func:`lpvid.covariance`, but on the directions
    whose share (module notes) is at least :data:`SEEN` only: the silent
    directions, whose first-order variance is what the noise would do if
    the prior held nothing, are left to the committee
    (:class:`lpvid.pipeline.between.Between`). In the range-whitened
    coordinates of the module notes the points' information is diagonal,
    ``N s_k`` for a direction of share ``s_k``.

    Returns
    -------
    cov : ndarray, shape (P, P)
        Zero rows and columns for the parameters held.
    free : ndarray of bool
        The structure's free parameters.
    silent : int
        The directions left out.
    """
    pair = _pair(model, data, fixed, threshold)
    cov, silent = _seen_cov(pair, model.theta.size)
    return cov, pair.free, silent


def _seen_cov(pair: _Pair, P: int) -> tuple[NDArray[np.float64], int]:
    W = pair.whiten
    share, vecs = np.linalg.eigh(_sym(W.T @ pair.at_points @ W))
    seen = share >= SEEN
    X = pair.to_free @ (W @ vecs[:, seen])  # seen directions in the free parameters
    inner = X / (2.0 * len(pair.each) * share[seen])
    cov = np.zeros((P, P))
    cov[np.ix_(pair.free, pair.free)] = _sym(inner @ X.T)
    return cov, int(np.sum(~seen))


def openness(
    model: LpvModel, data: FrfData, fixed: Any = None, *, threshold: float = 1e-6
) -> tuple[SilentCount, NDArray[np.float64]]:
    """:func:`silent_directions` and :func:`seen_covariance`'s matrix, from one computation."""
    pair = _pair(model, data, fixed, threshold)
    return _count(pair), _seen_cov(pair, model.theta.size)[0]
