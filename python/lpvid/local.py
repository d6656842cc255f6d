"""One LTI model per scheduling point: the local estimates SMILE interpolates."""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from typing import Any, overload

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lpvid._checks import positive_int, real_array
from lpvid.basis import Polynomial
from lpvid.coherent import balance
from lpvid.cost import vnls
from lpvid.data import FrfData
from lpvid.model import LpvModel
from lpvid.subspace import fd_subspace, max_order

__all__ = ["LocalModels", "identify_lti", "is_stable"]


def is_stable(model: LpvModel) -> bool:
    """Whether an LTI model's poles lie strictly inside the stability region."""
    lam = np.linalg.eigvals(model.A[0])
    if model.Ts is None:
        return bool(np.all(lam.real < 0))
    return bool(np.all(np.abs(lam) < 1))


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
        (:func:`lpvid.robust.continue_local`).

    Attributes
    ----------
    p, freqs_hz, vnls, noise_floor, converged, initial, starts
        As given.
    unstable : ndarray of bool
        True for a model with a pole outside the stability region.
    consistency : lpvid.robust.Consistency or None
        The diagnosis of the plain local models, when continuation was
        considered (see :func:`identify_lti`).

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
        self.unstable: NDArray[np.bool_] = np.array([not is_stable(m) for m in self._models])
        self.initial = None if initial is None else tuple(initial)
        self.starts: tuple[str, ...] = ("plain",) * N if starts is None else tuple(starts)
        if len(self.starts) != N:
            raise ValueError(f"starts: expected one label per model ({N}), got {len(self.starts)}")
        #: The diagnosis of :func:`lpvid.robust.consistency`, when it was run.
        self.consistency: Any = None
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


def identify_lti(
    data: FrfData,
    order: int,
    *,
    strictly_proper: bool = False,
    stable: bool = True,
    refine: bool = True,
    n_rows: int | None = None,
    max_iter: int = 100,
    continuation: bool | str = False,
) -> LocalModels:
    """Identify one LTI state-space model per scheduling point from its FRF.

    Each point gets frequency-domain subspace estimates weighted by sigma
    (:func:`lpvid.subspace.fd_subspace` with 3n, 2n and n + 1 block rows;
    unstable poles mirrored into the stable region when ``stable``), each
    as found and balanced; every one is refined by Levenberg-Marquardt on
    that point's V_NLS (:func:`lpvid.fit_nls`) and the best refined model is
    kept: the lowest V_NLS among the stable ones when ``stable`` (among all
    when none is stable), else the lowest V_NLS.

    Parameters
    ----------
    data : FrfData
        FRFs at N scheduling points.
    order : int
        State dimension n of every model.
    strictly_proper : bool
        Fix D to zero (``fixed={"D": True}`` in the refinement).
    stable : bool
        Mirror unstable poles of the subspace estimate before refinement
        (default True). The refinement may still move a pole out when the
        data demand it; ``result.unstable`` says which models are unstable.
    refine : bool
        Run the Levenberg-Marquardt refinement (default True).
    n_rows : int, optional
        Block rows of the subspace step (see :func:`~lpvid.subspace.fd_subspace`);
        default: try 3n, 2n and n + 1.
    max_iter : int
        Most Levenberg-Marquardt steps per point.
    continuation : bool or "auto"
        After the plain identification, walk from the best-determined point
        outwards and refine each point's model from its neighbour's
        (:func:`lpvid.robust.continue_local`), so that the models stay on
        one branch: always (True), never (False, the default), or when
        :func:`lpvid.robust.consistency` flags a point (``"auto"``).

    Returns
    -------
    LocalModels
        The models with per-point V_NLS, noise floor (``F l r``), unstable
        flags, the subspace estimates the kept models started from
        (``.initial``) and ``p``. Each model's ``info`` says which start it
        came from (``n_rows``, ``balanced_start``) and how many steps it took;
        ``.starts`` says per point whether the plain or the continuation
        start was kept, and ``.consistency`` holds the diagnosis of the plain
        models when continuation was considered.

    Raises
    ------
    ValueError, TypeError
        When ``order`` is not a positive integer or exceeds what the data
        support (the subspace step needs ``2 F r >= (n + 1) r + n``).

    """
    if not isinstance(data, FrfData):
        raise TypeError(f"data: expected an FrfData, got {type(data).__name__}")
    n = positive_int(order, "order")
    F, l, r = data.n_lines, data.n_outputs, data.n_inputs
    limit = max_order(F, l, r)
    if n > limit:
        raise ValueError(
            f"order: {n} exceeds what the data support ({F} lines per point, {l} outputs x "
            f"{r} inputs allow at most order {limit})"
        )
    max_iter = positive_int(max_iter, "max_iter")
    if not (isinstance(continuation, bool) or continuation == "auto"):
        raise ValueError(f"continuation: expected True, False or 'auto', got {continuation!r}")
    if continuation is not False and not refine:
        raise ValueError("continuation: a continuation refines the models; it needs refine=True")
    rows = _row_choices(n, F, r, n_rows)
    basis = Polynomial(0, n_params=data.n_params)
    fixed = {"D": True} if strictly_proper else None
    models, initial, costs, conv = [], [], [], []
    for q in range(data.n_points):
        point = data.subset([q])
        best = None
        for start in _starts(point, n, rows, basis, stable, strictly_proper):
            model, ok = _refine(start, point, fixed, max_iter) if refine else (start, True)
            # Prefer stable models when asked, then the lowest V_NLS.
            key = (stable and not is_stable(model), vnls(model, point))
            if best is None or key < best[0]:
                best = (key, model, ok, start)
        assert best is not None
        (_, cost), model, ok, start = best
        models.append(model)
        costs.append(cost)
        conv.append(ok)
        initial.append(start)
    floor = np.full(data.n_points, F * l * r)
    plain = LocalModels(models, data.p, data.freqs_hz, costs, floor, conv, initial)
    if continuation is False or data.n_points < 2:
        return plain
    from lpvid.robust import consistency, continue_local

    diagnosis = consistency(plain)
    if continuation == "auto" and diagnosis.ok:
        plain.consistency = diagnosis
        return plain
    return continue_local(data, plain, strictly_proper=strictly_proper, max_iter=max_iter)


def _row_choices(n: int, n_lines: int, n_inputs: int, n_rows: int | None) -> list[int | None]:
    """Block-row counts to try: the one given, else 3n, 2n and n + 1 where the data allow."""
    if n_rows is not None:
        return [n_rows]
    q_max = (2 * n_lines * n_inputs - n) // n_inputs
    return sorted({min(k, q_max) for k in (3 * n, 2 * n, n + 1) if n + 1 <= min(k, q_max)})


def _starts(
    point: FrfData,
    n: int,
    rows: list[int | None],
    basis: Polynomial,
    stable: bool,
    strictly_proper: bool,
) -> list[LpvModel]:
    """Subspace estimates of one point, each as found and (when stable) balanced.

    The refinement is cheap and its outcome depends on the start (a pole
    outside the band can run off to infinity from one start and settle from
    another), so a few starts are refined and the best result kept.
    """
    out = []
    for q in rows:
        A, B, C, D = fd_subspace(
            point.freqs_hz,
            point.G[0],
            n,
            point.sigma[0],
            point.Ts,
            n_rows=q,
            stable=stable,
            strictly_proper=strictly_proper,
        )
        info = {"method": "fd_subspace", "n_rows": q, "balanced": False}
        out.append(LpvModel(A, B, C, D, basis=basis, Ts=point.Ts, info=info))
        bal, done = balance([(A, B, C, D)], point.Ts)
        if done:
            info = {**info, "balanced": True}
            out.append(LpvModel(*bal[0], basis=basis, Ts=point.Ts, info=info))
    return out


def _refine(start: LpvModel, data: FrfData, fixed: Any, max_iter: int) -> tuple[LpvModel, bool]:
    from lpvid.fit import fit_nls

    result = fit_nls(start, data, fixed, max_iter=max_iter)
    info = {
        "method": "fd_subspace + fit_nls",
        "n_rows": start.info["n_rows"],
        "balanced_start": start.info["balanced"],
        "n_iter": int(result.n_iter),
    }
    model = LpvModel(*result.model.matrices().values(), basis=start.basis, Ts=start.Ts, info=info)
    return model, bool(result.converged)
