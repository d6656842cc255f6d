"""The container of local LTI models, one per scheduling point, and its checks.

Also :class:`Consistency`, the result of :func:`lpvid.consistency`
(computed in :mod:`lpvid.initial.diagnosis`), because a :class:`LocalModels`
carries one: defined here, the diagnosis depends on the container and not
the other way round.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any, overload

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lpvid._checks import real_array, same_sample_time
from lpvid.model.frozen import stable_poles
from lpvid.model.lpv import LpvModel

__all__ = ["Consistency", "LocalModels", "is_stable", "local_p", "lti_models"]

Arr = NDArray[np.float64]


@dataclass
class Consistency:
    """How consistent local models are along the scheduling axes.

    Each point is compared with its nearest points: the poles of the two
    models are paired by the best matching (Hungarian algorithm on the
    distance between :func:`pole_coordinates`, i.e. log-frequency and
    damping angle), and the worst pair's distance, divided by the distance
    between the two points in the scaled scheduling space, is that pair of
    points' *rate*. Each point's smallest rate says how far its model is
    from the nearest agreeing neighbour; the reference is the median of
    these over the points (how fast the poles move in a typical step), and
    a point's *score* is its smallest rate divided by the reference, so that
    one odd model spoils the score of no point but its own.

    Attributes
    ----------
    p : ndarray, shape (N, Np)
        Scheduling values.
    scores : ndarray, shape (N,)
        Smallest rate of each point relative to the reference (about 1 for
        a consistent set).
    distances : ndarray, shape (N,)
        The worst pole distance along each point's best pair.
    pairs : list of (int, int, float, float)
        ``(a, b, distance, rate)`` for every pair of neighbouring points.
    reference : float
        Median over the points of their smallest rate.
    threshold, min_distance : float
        A point is inconsistent when its score exceeds ``threshold`` and its
        distance exceeds ``min_distance``.
    inconsistent : list of int
        The inconsistent points.
    details : dict of int to str
        For every inconsistent point, the worst pole pairing in words.
    """

    p: Arr
    scores: Arr
    distances: Arr
    pairs: list[tuple[int, int, float, float]]
    reference: float
    threshold: float
    min_distance: float
    inconsistent: list[int]
    details: dict[int, str] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        """True when no point looks inconsistent."""
        return not self.inconsistent

    @property
    def worst(self) -> int:
        """Index of the point with the highest score."""
        return int(np.argmax(self.scores))

    def __str__(self) -> str:
        head = (
            "local models consistent along the scheduling axis"
            if self.ok
            else f"local models inconsistent at point(s) {self.inconsistent}"
        )
        lines = [
            f"{head} (reference pole rate {self.reference:.3g} per unit of scaled p; "
            f"flag: score > {self.threshold:g} and distance > {self.min_distance:g})",
            "  q  p                  score  distance",
        ]
        for q in range(self.scores.size):
            ps = ", ".join(f"{v:.4g}" for v in self.p[q])
            mark = "  <- " + self.details.get(q, "") if q in self.inconsistent else ""
            lines.append(f"{q:3d}  {ps:<16s} {self.scores[q]:7.2f} {self.distances[q]:9.3g}{mark}")
        return "\n".join(lines)


def is_stable(model: LpvModel) -> bool:
    """Whether an LTI model's poles lie strictly inside the stability region."""
    return bool(np.all(stable_poles(np.linalg.eigvals(model.A[0]), model.Ts)))


class LocalModels(Sequence[LpvModel]):
    """LTI models identified at the scheduling points, one per point.

    Behaves as a read-only sequence of :class:`~lpvid.LpvModel` (each with
    no basis, Nb = 0, and the data's ``Ts``) and carries per-point figures of
    merit. :func:`lpvid.smile` accepts it directly.

    Parameters
    ----------
    models : sequence of LpvModel
        The LTI models.
    p : array_like, shape (N,) or (N, Np)
        Scheduling value of each model.
    freqs_hz : array_like, optional
        The data's frequency lines.
    vnls : array_like, optional
        V_NLS of each model on its own point's data.
    noise_floor : array_like of int, optional
        Number of complex residuals of each point (``F l r``), the expected
        V_NLS at the noise floor.
    converged : array_like of bool, optional
        Whether the refinement of each model converged.
    initial : sequence of LpvModel, optional
        The subspace estimates the refinement started from.
    starts : sequence of str, optional
        Per point, which start the kept model came from: ``"plain"`` (the
        subspace estimates, the default) or ``"continuation from q"``
        (:func:`lpvid.initial.continue_local`).
    consistency : Consistency, optional
        The diagnosis of the plain local models
        (:func:`lpvid.consistency`), when it was run.

    Attributes
    ----------
    p, freqs_hz, vnls, noise_floor, converged, initial, starts
        As given.
    unstable : ndarray of bool
        True for a model with a pole outside the stability region.
    consistency : Consistency or None
        As given.

    """

    def __init__(
        self,
        models: Sequence[LpvModel],
        p: ArrayLike,
        freqs_hz: ArrayLike | None = None,
        vnls: ArrayLike | None = None,
        noise_floor: ArrayLike | None = None,
        converged: ArrayLike | None = None,
        initial: Sequence[LpvModel] | None = None,
        starts: Sequence[str] | None = None,
        consistency: Consistency | None = None,
    ) -> None:
        self._models = tuple(models)
        for k, m in enumerate(self._models):
            if not isinstance(m, LpvModel) or m.n_basis != 0:
                raise TypeError(f"models[{k}]: expected an LTI LpvModel (Nb = 0)")
        N = len(self._models)
        self.p: NDArray[np.float64] = real_array(p, "p", ndim=(1, 2))
        if self.p.shape[0] != N:
            raise ValueError(f"p: {self.p.shape[0]} scheduling values for {N} models")
        self.freqs_hz = None if freqs_hz is None else real_array(freqs_hz, "freqs_hz", ndim=1)
        nan = np.full(N, np.nan)
        self.vnls: NDArray[np.float64] = nan if vnls is None else real_array(vnls, "vnls", ndim=1)
        self.noise_floor: NDArray[np.int_] = (
            np.zeros(N, dtype=int) if noise_floor is None else np.asarray(noise_floor, dtype=int)
        )
        self.converged: NDArray[np.bool_] = (
            np.ones(N, dtype=bool) if converged is None else np.asarray(converged, dtype=bool)
        )
        self.unstable: NDArray[np.bool_] = np.array(
            [not is_stable(m) for m in self._models], dtype=bool
        )
        self.initial = None if initial is None else tuple(initial)
        self.starts: tuple[str, ...] = ("plain",) * N if starts is None else tuple(starts)
        if len(self.starts) != N:
            raise ValueError(f"starts: expected one label per model ({N}), got {len(self.starts)}")
        self.consistency = consistency
        # figures derived from one model and its point's data, computed once
        # (lpvid.initial.continuation's pole spreads)
        self._derived: dict[Any, tuple[Any, Any]] = {}
        for arr in (self.p, self.vnls, self.noise_floor, self.converged, self.unstable):
            if arr.shape[0] != N:
                raise ValueError(f"expected one value per model ({N}), got shape {arr.shape}")
            arr.setflags(write=False)

    @overload
    def __getitem__(self, index: int) -> LpvModel: ...
    @overload
    def __getitem__(self, index: slice) -> tuple[LpvModel, ...]: ...
    def __getitem__(self, index: int | slice) -> LpvModel | tuple[LpvModel, ...]:
        return self._models[index]

    def __len__(self) -> int:
        return len(self._models)

    def __iter__(self) -> Iterator[LpvModel]:
        return iter(self._models)

    def subset(self, points: Sequence[int]) -> LocalModels:
        """The models of some points (in the order given) with their figures.

        The diagnosis (``consistency``) is of the whole set and is not carried.
        """
        idx = [int(q) for q in points]
        for q in idx:
            if not 0 <= q < len(self):
                raise ValueError(f"points: expected indices in 0..{len(self) - 1}, got {q}")
        return LocalModels(
            [self._models[q] for q in idx],
            self.p[idx],
            self.freqs_hz,
            self.vnls[idx],
            self.noise_floor[idx],
            self.converged[idx],
            None if self.initial is None else [self.initial[q] for q in idx],
            [self.starts[q] for q in idx],
        )

    @property
    def Ts(self) -> float | None:
        """Sample time of the models (None: continuous time)."""
        return self._models[0].Ts if self._models else None

    @property
    def order(self) -> int:
        """State dimension n of the models."""
        return self._models[0].n_states

    def table(self) -> str:
        """One line per point: p, V_NLS, noise floor, their ratio, stability, start."""
        lines = ["  q  p                     V_NLS   floor   ratio  stable  start"]
        for q in range(len(self)):
            pq = np.atleast_1d(self.p[q])
            ps = ", ".join(f"{v:.4g}" for v in pq)
            ratio = self.vnls[q] / self.noise_floor[q] if self.noise_floor[q] else np.nan
            lines.append(
                f"{q:3d}  {ps:<18s} {self.vnls[q]:9.4g} {self.noise_floor[q]:7d} {ratio:7.3f}"
                f"  {'no' if self.unstable[q] else 'yes':6s}  {self.starts[q]}"
            )
        return "\n".join(lines)

    def __repr__(self) -> str:
        kind = "continuous time" if self.Ts is None else f"Ts={self.Ts:g} s"
        n_bad = int(self.unstable.sum())
        return f"LocalModels(N={len(self)}, n={self.order}, {kind}, {n_bad} unstable)"


def lti_models(local_models: Any, *, minimum: int = 1) -> list[LpvModel]:
    """Check a set of local LTI models: LTI, of one size (n, r, l) and one sample time.

    Parameters
    ----------
    local_models : LocalModels or sequence of LpvModel
    minimum : int
        Fewest models accepted.

    Returns
    -------
    list of LpvModel

    Raises
    ------
    TypeError, ValueError
        Naming ``local_models`` (with the index of the offending model).
    """
    if isinstance(local_models, LpvModel) or not isinstance(local_models, Sequence):
        raise TypeError(
            "local_models: expected LocalModels or a list of LTI LpvModel, "
            f"got {type(local_models).__name__}"
        )
    models = list(local_models)
    if len(models) < minimum:
        raise ValueError(f"local_models: needs at least {minimum} model(s), got {len(models)}")
    for k, m in enumerate(models):
        if not isinstance(m, LpvModel):
            raise TypeError(f"local_models[{k}]: expected an LpvModel, got {type(m).__name__}")
        if m.n_basis != 0:
            raise ValueError(
                f"local_models[{k}]: expected an LTI model (Nb = 0), got Nb={m.n_basis}"
            )
        if m.shape[:3] != models[0].shape[:3]:
            raise ValueError(
                f"local_models[{k}]: (n, r, l) = {m.shape[:3]} differs from the first model's "
                f"{models[0].shape[:3]}"
            )
        if not same_sample_time(m.Ts, models[0].Ts):
            raise ValueError(f"local_models[{k}]: Ts={m.Ts} differs from the first model's")
    return models


def local_p(local_models: Any, p: ArrayLike | None) -> NDArray[np.float64]:
    """The scheduling values of local models: ``p`` checked, or those a LocalModels carries.

    Returns
    -------
    ndarray, shape (N,) or (N, Np)
        One row per model.
    """
    if p is None:
        if not isinstance(local_models, LocalModels):
            raise ValueError("p: required unless local_models is a LocalModels")
        p = local_models.p
    arr = real_array(p, "p", ndim=(1, 2))
    if arr.shape[0] != len(local_models):
        raise ValueError(f"p: {arr.shape[0]} scheduling values for {len(local_models)} models")
    return arr
