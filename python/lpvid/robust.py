"""Initial estimates that survive poorly determined local models.

SMILE (:mod:`lpvid.smile`) trusts every local model. When modes are heavily
damped or close and the FRFs carry noise, a local model can fit its own
data at the noise floor and still have another pole structure than its
neighbours (a lightly damped pair split into two real poles, a pole far
outside the band). This module

- measures how consistent the local models are along the scheduling axis
  (:func:`consistency`),
- identifies the local models by continuation from the best-determined
  point, so that they stay on one branch (:func:`continue_local`, offered
  as ``identify_lti(..., continuation=True)``),
- builds an LPV start from one local model by fitting a constant model to
  all the data and then freeing the basis groups (:func:`global_start`),
- and gathers every route into refined candidates for
  :func:`lpvid.identify` (:func:`initial_candidates`, :func:`choose`).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lpvid._checks import positive_float, positive_int, real_array
from lpvid.basis import Basis
from lpvid.coherent import propagation_order
from lpvid.cost import check_compatible, vnls
from lpvid.data import FrfData
from lpvid.layout import fixed_mask
from lpvid.model import LpvModel
from lpvid.results import FitResult

if TYPE_CHECKING:
    from lpvid.local import LocalModels

__all__ = [
    "Candidate",
    "Consistency",
    "choose",
    "consistency",
    "continue_local",
    "global_start",
    "initial_candidates",
    "pole_coordinates",
    "pole_uncertainty",
    "between_points",
    "frozen_stable",
    "best_determined",
    "continuation_order",
]

Arr = NDArray[np.float64]


# ----------------------------------------------------------------------------- diagnosis
def pole_coordinates(model: LpvModel | Sequence[Any]) -> NDArray[np.complex128]:
    """Poles of an LTI model as ``log(-s)``: log-frequency and damping in one number.

    ``s`` is the continuous-time pole (``log(z) / Ts`` in discrete time). For
    a stable pole ``-s`` lies in the right half plane, so ``log(-s) =
    ln|s| + j phi`` has ``phi`` in (-pi/2, pi/2): the real part is the log
    natural frequency and ``|phi| = arccos(zeta)`` the damping angle (0 for
    a real pole). Distances between these coordinates compare poles of
    very different frequencies on one scale.

    Parameters
    ----------
    model : LpvModel or (A, B, C, D)
        An LTI model (an LpvModel with Nb = 0; its ``Ts`` is used).

    Returns
    -------
    ndarray of complex, shape (n,)

    """
    if isinstance(model, LpvModel):
        A, Ts = model.A[0], model.Ts
    else:
        A, Ts = np.asarray(model[0], dtype=float), None
    lam = np.linalg.eigvals(A)
    s = lam if Ts is None else np.log(lam.astype(complex)) / Ts
    u = -s
    mag = np.abs(u)
    top = float(mag.max()) if mag.size else 1.0
    mag = np.maximum(mag, 1e-12 * max(top, 1e-300))
    tol = 1e-9 * max(top, 1e-300)
    # Real poles sit exactly on the real axis (angle 0, or pi when unstable).
    phi = np.where(np.abs(u.imag) <= tol, np.where(u.real >= 0, 0.0, np.pi), np.angle(u))
    return np.log(mag) + 1j * phi


def _match(a: NDArray[np.complex128], b: NDArray[np.complex128]) -> tuple[float, int, int]:
    """Best pairing of two pole sets: the largest pair distance, and the worst pair."""
    from scipy.optimize import linear_sum_assignment

    cost = np.abs(a[:, None] - b[None, :])
    rows, cols = linear_sum_assignment(cost)
    k = int(np.argmax(cost[rows, cols]))
    return float(cost[rows[k], cols[k]]), int(rows[k]), int(cols[k])


def _scaled(p: Arr) -> Arr:
    """Scheduling values (N, Np) with every parameter mapped to [0, 1]."""
    span = np.ptp(p, axis=0)
    return (p - p.min(axis=0)) / np.where(span > 0, span, 1.0)


def _neighbours(s: Arr, k: int) -> list[tuple[int, int]]:
    """Unique pairs joining every point to its k nearest points."""
    dist = np.linalg.norm(s[:, None, :] - s[None, :, :], axis=2)
    np.fill_diagonal(dist, np.inf)
    pairs = set()
    for q in range(s.shape[0]):
        for m in np.argsort(dist[q], kind="stable")[:k]:
            pairs.add((min(q, int(m)), max(q, int(m))))
    return sorted(pairs)


def _is_real(u: NDArray[np.complex128]) -> NDArray[np.bool_]:
    """Which poles (in log(-s) coordinates) are real: angle exactly 0 or pi."""
    return (u.imag == 0.0) | (u.imag == np.pi)


def _describe_pole(u: complex) -> str:
    """A pole in log(-s) coordinates as 'f Hz zeta z' or 'f Hz real'."""
    f = float(np.exp(u.real)) / (2 * np.pi)
    if u.imag == 0.0:
        return f"{f:.4g} Hz real"
    if u.imag == np.pi:
        return f"{f:.4g} Hz real unstable"
    return f"{f:.4g} Hz zeta {np.cos(abs(u.imag)):.2f}"


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


def _models_and_p(local_models: Any, p: ArrayLike | None) -> tuple[list[LpvModel], Arr]:
    from lpvid.local import LocalModels

    if isinstance(local_models, LpvModel) or not isinstance(local_models, Sequence):
        raise TypeError(
            "local_models: expected LocalModels or a list of LTI LpvModel, "
            f"got {type(local_models).__name__}"
        )
    models = list(local_models)
    if len(models) < 2:
        raise ValueError("local_models: needs at least two models to compare")
    for k, m in enumerate(models):
        if not isinstance(m, LpvModel) or m.n_basis != 0:
            raise TypeError(f"local_models[{k}]: expected an LTI LpvModel (Nb = 0)")
        if m.n_states != models[0].n_states:
            raise ValueError(f"local_models[{k}]: order {m.n_states} differs from the first's")
    if p is None:
        if not isinstance(local_models, LocalModels):
            raise ValueError("p: required unless local_models is a LocalModels")
        p = local_models.p
    arr = real_array(p, "p", ndim=(1, 2))
    if arr.shape[0] != len(models):
        raise ValueError(f"p: {arr.shape[0]} scheduling values for {len(models)} models")
    return models, arr.reshape(len(models), -1)


def consistency(
    local_models: Any,
    p: ArrayLike | None = None,
    *,
    threshold: float = 3.0,
    min_distance: float = 0.2,
    neighbours: int | None = None,
) -> Consistency:
    """Diagnose how consistent local LTI models are along the scheduling axes.

    Parameters
    ----------
    local_models : LocalModels or sequence of LpvModel
        LTI models (Nb = 0) of one order, e.g. from :func:`lpvid.identify_lti`.
    p : array_like, shape (N,) or (N, Np), optional
        Scheduling values; default ``local_models.p``.
    threshold : float
        Score (rate relative to the median rate) above which a point is
        flagged.
    min_distance : float
        Smallest worst-pole distance worth flagging, in ``log(-s)`` units
        (0.2: a 20 % change of frequency or of about 0.2 rad in damping angle);
        keeps noise from flagging points of a nearly constant system.
    neighbours : int, optional
        Points compared with each point; default ``2 Np`` (two per
        parameter: along a line the neighbours on both sides, or the next
        point on the same side at an end).

    Returns
    -------
    Consistency

    Examples
    --------
    >>> import numpy as np, lpvid
    >>> ms = [lpvid.LpvModel([[-a]], [[1.0]], [[1.0]]) for a in (1.0, 1.1, 1.2, 50.0, 1.4)]
    >>> lpvid.robust.consistency(ms, [0, 1, 2, 3, 4]).inconsistent
    [3]

    """
    models, parr = _models_and_p(local_models, p)
    thr = positive_float(threshold, "threshold")
    dmin = positive_float(min_distance, "min_distance", allow_zero=True)
    N, n_par = parr.shape
    k = 2 * n_par if neighbours is None else positive_int(neighbours, "neighbours")
    k = min(k, N - 1)
    s = _scaled(parr)
    if np.unique(s, axis=0).shape[0] != N:
        raise ValueError("p: scheduling values must be distinct")
    coords = [pole_coordinates(m) for m in models]
    pairs = []
    worst_pair: dict[tuple[int, int], tuple[int, int]] = {}
    for a, b in _neighbours(s, k):
        d, i, j = _match(coords[a], coords[b])
        rate = d / float(np.linalg.norm(s[a] - s[b]))
        pairs.append((a, b, d, rate))
        worst_pair[(a, b)] = (i, j)
    # Each point's smallest rate; their median is the reference. (The median
    # over all pairs would not do: a point in the middle is among the nearest
    # of most others, so that one odd model can spoil most pairs.)
    low = np.full(N, np.inf)
    dists = np.zeros(N)
    best: dict[int, tuple[int, int, float, float]] = {}
    for pr in pairs:
        for q in pr[:2]:
            if pr[3] < low[q]:
                low[q], dists[q], best[q] = pr[3], pr[2], pr
    ref = float(np.median(low))
    scores = low / ref if ref > 0 else np.where(low > 0, np.inf, 1.0)
    # Real poles per model: a pair that splits into two real poles at one
    # point only is a change of structure whatever the distances say.
    n_real = np.array([int(np.sum(_is_real(c))) for c in coords])
    near: dict[int, set[int]] = {q: set() for q in range(N)}
    for a, b, _, _ in pairs:
        near[a].add(b)
        near[b].add(a)
    odd = [q for q in range(N) if all(n_real[m] != n_real[q] for m in near[q])]
    bad = [q for q in range(N) if (scores[q] > thr and dists[q] > dmin) or q in odd]
    details = {}
    for q in odd:
        others = sorted({int(n_real[m]) for m in near[q]})
        details[q] = (
            f"{n_real[q]} real pole(s), its nearest points have "
            f"{' or '.join(str(v) for v in others)}"
        )
    for q in set(bad) - set(odd):
        a, b, d, _ = best[q]
        i, j = worst_pair[(a, b)]
        mine, other = (i, j) if q == a else (j, i)
        m = b if q == a else a
        details[q] = (
            f"pole {_describe_pole(coords[q][mine])} pairs with "
            f"{_describe_pole(coords[m][other])} at point {m} (distance {d:.2f})"
        )
    return Consistency(parr, scores, dists, pairs, ref, thr, dmin, bad, details)


# ----------------------------------------------------------------------------- continuation
def _max_distance(a: LpvModel, b: LpvModel) -> float:
    return _match(pole_coordinates(a), pole_coordinates(b))[0]


def pole_uncertainty(model: LpvModel, data: FrfData, fixed: Any = None) -> NDArray[np.float64]:
    """Standard deviation of every pole of an LTI model in ``log(-s)`` units.

    First-order propagation of the parameter covariance ``(J^T J)^+ / 2``
    (each real residual of V_NLS has variance 1/2) through the pole
    sensitivities ``d lambda_i / d A_ab = W_ia V_bi`` (``V`` the right
    eigenvectors of A, ``W = V^-1``). ``J^T J`` is singular along the
    similarity transforms, which move no pole; the pseudo-inverse is taken
    exactly on their complement (a cut-off on small singular values would
    also drop the poorly determined directions this is meant to measure).
    0.1 means the pole's frequency (or its damping angle) is known to about
    10 %. Valid near a minimum of V_NLS, where the model fits within the noise.

    Parameters
    ----------
    model : LpvModel
        LTI model (Nb = 0).
    data : FrfData
        The data of its point (one scheduling value).
    fixed : optional
        Fixed parameters, as in :func:`lpvid.fixed_mask`.

    Returns
    -------
    ndarray, shape (n,)
        In the order of ``numpy.linalg.eigvals(model.A[0])``.

    """
    from lpvid.cost import gauss_newton

    if model.n_basis != 0:
        raise ValueError("model: expected an LTI model (Nb = 0)")
    n = model.n_states
    A, B, C = model.A[0], model.B[0], model.C[0]
    free = ~fixed_mask(model, fixed)
    _, _, jtj = gauss_newton(model, data, fixed)
    # The similarity directions dA = X A - A X, dB = X B, dC = -C X (D fixed)
    # leave the FRF unchanged: J^T J is singular along them. They do not move
    # the poles either, so the pole variance is g^T (J^T J)^+ g, computed
    # as g^T (H + S S^T)^-1 g on the Jacobi-scaled H with S spanning them.
    tangent = []
    for a in range(n):
        for b in range(n):
            X = np.zeros((n, n))
            X[a, b] = 1.0
            dm = [X @ A - A @ X, X @ B, -C @ X, np.zeros_like(model.D[0])]
            tangent.append(np.concatenate([x.ravel(order="F") for x in dm]))
    T = np.array(tangent).T
    if np.any(~free):
        # Only the transforms that leave the fixed parameters alone remain.
        _, sv, vt = np.linalg.svd(T[~free])
        rank = int(np.sum(sv > 1e-10 * max(float(sv[0]) if sv.size else 0.0, 1e-300)))
        T = T @ vt[rank:].T
    T = T[free]
    d = np.sqrt(np.maximum(np.diag(jtj), 1e-300))
    H = jtj / d[:, None] / d[None, :]
    if T.shape[1]:
        S, sv, _ = np.linalg.svd(T * d[:, None], full_matrices=False)
        S = S[:, sv > 1e-10 * sv[0]]
    else:
        S = np.zeros((H.shape[0], 0))
    lam, V = np.linalg.eig(A)
    W = np.linalg.inv(V)
    # theta_A is vec(A) column-major: index a + b n for A[a, b].
    g = np.zeros((n, model.theta.size), dtype=complex)
    g[:, : n * n] = np.einsum("ia,bi->iba", W, V).reshape(n, n * n)
    gs = g[:, free] / d[None, :]
    sol = np.linalg.solve(H + S @ S.T, gs.T)
    var = np.real(np.sum(gs.conj() * sol.T, axis=1)) / 2.0
    if model.Ts is None:
        scale = np.abs(lam)
    else:
        scale = np.abs(lam * np.log(lam.astype(complex)))
    return np.sqrt(np.maximum(var, 0.0)) / np.maximum(scale, 1e-300)


def best_determined(
    local_models: LocalModels,
    data: FrfData,
    diagnosis: Consistency | None = None,
    fixed: Any = None,
) -> int:
    """The point to start a continuation from: the best-determined local model.

    Among the points that the diagnosis does not flag, whose model is
    stable and whose V_NLS relative to the noise floor is within two
    standard deviations of the best (``2 / sqrt(F l r)``), the one whose
    least certain pole is the most certain (:func:`pole_uncertainty`).

    Parameters
    ----------
    local_models : LocalModels
    data : FrfData
        The data the models were identified from.
    diagnosis : Consistency, optional
        Default :func:`consistency` of ``local_models``.
    fixed : optional
        Fixed parameters of the local models (``{"D": True}`` when strictly proper).

    Returns
    -------
    int

    """
    diag = consistency(local_models) if diagnosis is None else diagnosis
    N = len(local_models)
    floor = np.maximum(np.asarray(local_models.noise_floor, dtype=float), 1.0)
    rel = np.asarray(local_models.vnls, dtype=float) / floor
    rel = np.where(np.isfinite(rel), rel, np.inf)
    tol = 2.0 / np.sqrt(floor)
    ok = [q for q in range(N) if q not in diag.inconsistent and not local_models.unstable[q]]
    ok = ok or list(range(N))
    ok = [q for q in ok if rel[q] <= np.min(rel[ok]) + tol[q]] or ok
    spread = {}
    for q in ok:
        try:
            spread[q] = float(np.max(pole_uncertainty(local_models[q], data.subset([q]), fixed)))
        except (np.linalg.LinAlgError, ValueError):
            spread[q] = np.inf
    return min(ok, key=lambda q: (spread[q], rel[q]))


def continuation_order(p: ArrayLike, root: int) -> tuple[NDArray[np.int_], NDArray[np.int_]]:
    """The walk of a continuation: points in visiting order and their parents.

    Along the minimum spanning tree of the points (scaled scheduling space),
    breadth first from ``root``: in one dimension outwards along the sorted
    points, for several parameters along a nearest-neighbour tree
    (:func:`lpvid.coherent.propagation_order`).

    Parameters
    ----------
    p : array_like, shape (N,) or (N, Np)
    root : int

    Returns
    -------
    order : ndarray of int
        The root first; every point after its parent.
    parent : ndarray of int
        ``parent[q]``: the visited neighbour point q starts from (-1 for the root).

    """
    arr = real_array(p, "p", ndim=(1, 2))
    arr = arr.reshape(arr.shape[0], -1)
    root = positive_int(root, "root", minimum=0)
    return propagation_order(arr, root)


def continue_local(
    data: FrfData,
    local: LocalModels,
    *,
    root: int | None = None,
    strictly_proper: bool = False,
    tolerance: float = 1.0,
    max_iter: int = 100,
) -> LocalModels:
    """Local models by continuation along the scheduling axes.

    Starting from the best-determined point (:func:`best_determined`), each
    next point's model is refined by :func:`lpvid.fit_nls` on that point's
    data from the model of the point before it, walking outwards along a
    nearest-neighbour tree (:func:`continuation_order`). The refinement stops
    as soon as V_NLS comes within ``tolerance * sqrt(F l r)`` of the best
    that point allows (the lower of the plain model's V_NLS and the noise
    floor ``F l r``): the models then stay on one branch and in nearly the
    same state coordinates as their neighbours.

    Per point, of the continued and the plain model, those whose V_NLS is
    within ``tolerance * sqrt(F l r)`` of the better one fit equally well;
    of these, the ones whose poles stay near the parent's (worst matched
    pole distance within the diagnosis' allowance for the step,
    ``max(threshold * reference * step, min_distance)``, see
    :class:`Consistency`) are consistent, and the continued one is
    preferred among them; when none is consistent, the one nearest the
    parent is kept. The walk goes on from the kept model.

    Parameters
    ----------
    data : FrfData
        The data the plain local models were identified from.
    local : LocalModels
        Plain local models (:func:`lpvid.identify_lti`).
    root : int, optional
        The point to start from; default :func:`best_determined`.
    strictly_proper : bool
        Keep D at zero.
    tolerance : float
        Slack on V_NLS in standard deviations of the noise floor
        (``sqrt(F l r)``).
    max_iter : int
        Most Levenberg-Marquardt steps per point.

    Returns
    -------
    LocalModels
        With ``starts`` saying, per point, which start the model came from
        (``"plain"`` for the root and for points that kept the plain model,
        ``"continuation from q"`` otherwise) and ``consistency``, the
        diagnosis of the plain models.

    """
    from lpvid.fit import fit_nls
    from lpvid.local import LocalModels

    if not isinstance(data, FrfData):
        raise TypeError(f"data: expected an FrfData, got {type(data).__name__}")
    if not isinstance(local, LocalModels):
        raise TypeError(f"local: expected LocalModels, got {type(local).__name__}")
    if len(local) != data.n_points:
        raise ValueError(f"local: {len(local)} models for {data.n_points} data points")
    tol = positive_float(tolerance, "tolerance", allow_zero=True)
    max_iter = positive_int(max_iter, "max_iter")
    if len(local) < 2:
        raise ValueError("local: a continuation needs at least two points")
    diag = consistency(local)
    fixed = {"D": True} if strictly_proper else None
    if root is None:
        root = best_determined(local, data, diag, fixed)
    order, parent = continuation_order(data.p, root)
    N = data.n_points
    models: list[LpvModel | None] = [None] * N
    costs = np.array(local.vnls, dtype=float)
    conv = np.array(local.converged, dtype=bool)
    starts = ["plain"] * N
    initial: list[LpvModel] = list(local.initial) if local.initial is not None else list(local)
    models[root] = local[root]
    scaled = _scaled(data.p.reshape(N, -1))
    for q in order[1:]:
        m = int(parent[q])
        start = models[m]
        assert start is not None
        point = data.subset([q])
        floor = float(point.n_residuals)
        target = min(float(local.vnls[q]), floor) + tol * np.sqrt(floor)

        def stop(row: dict[str, Any], target: float = target) -> bool:
            return bool(row["vnls"] > target)  # False stops the fit

        fit = fit_nls(start, point, fixed, max_iter=max_iter, callback=stop)
        cont = LpvModel(
            *fit.model.matrices().values(),
            basis=start.basis,
            Ts=data.Ts,
            info={
                "method": "continuation + fit_nls",
                "start": f"point {m}",
                "n_iter": int(fit.n_iter),
            },
        )
        # Both starts are acceptable when they fit within the noise of the
        # better one; of those, the ones consistent with the parent's model
        # (pole distance within the diagnosis' allowance for this step) are
        # preferred, the continued one first (it also keeps the state
        # coordinates of its neighbour); else the one nearest the parent.
        best_v = min(fit.vnls, float(local.vnls[q]))
        options = {"continuation": (cont, fit.vnls), "plain": (local[q], float(local.vnls[q]))}
        fits_ok = [k for k, (_, v) in options.items() if v <= best_v + tol * np.sqrt(floor)]
        step = float(np.linalg.norm(scaled[q] - scaled[m]))
        allowed = max(diag.threshold * diag.reference * step, diag.min_distance)
        dist = {k: _max_distance(options[k][0], start) for k in fits_ok}
        near = [k for k in fits_ok if dist[k] <= allowed]
        choice = near[0] if near else min(fits_ok, key=lambda k: dist[k])
        models[q], costs[q] = options[choice]
        if choice == "continuation":
            conv[q] = True
            starts[q] = f"continuation from {m}"
            initial[q] = start
    out = LocalModels(
        models,  # type: ignore[arg-type]
        data.p,
        data.freqs_hz,
        costs,
        local.noise_floor,
        conv,
        initial,
        starts=starts,
    )
    out.consistency = diag
    return out


# ----------------------------------------------------------------------------- global start
STAGES = ("all", "degree")


def _degrees(basis: Basis) -> list[int]:
    """Degree level of every basis function: total degree for polynomial bases, else 1..Nb."""
    exps = getattr(basis, "exponents", None)
    if exps is not None and len(exps) == len(basis):
        return [int(sum(e)) for e in exps]
    return list(range(1, len(basis) + 1))


def _group_mask(model: LpvModel, indices: Sequence[int]) -> NDArray[np.bool_]:
    """True for every parameter of the coefficient matrices X(i), i in ``indices``."""
    idx = [int(i) for i in indices]
    return fixed_mask(model, {x: idx for x in "ABCD"}) if idx else fixed_mask(model, None)


def global_start(
    data: FrfData,
    order: int,
    basis: Basis,
    fixed: Any = None,
    *,
    local: LocalModels | None = None,
    point: int | None = None,
    stages: str = "all",
    max_iter: int = 100,
) -> LpvModel:
    """An LPV start from one good local model: constant first, then the basis groups.

    1. The best-determined local model (:func:`best_determined`, or the one
       at ``point``) becomes a constant LPV model (every group ``X(i)``,
       ``i >= 1``, zero).
    2. :func:`lpvid.fit_nls` on all the data with only the constant part
       ``X(0)`` free: the LTI model that best fits every point.
    3. The groups are freed and refined with :func:`lpvid.fit_nls`: all at
       once (``stages="all"``) or one degree at a time (``stages="degree"``:
       first the degree-1 functions, then up to degree 2, ...; for a basis
       without degrees, one function at a time).

    The l2,1 path later removes what is not needed.

    Parameters
    ----------
    data : FrfData
        Identification data.
    order : int
        Number of states.
    basis : Basis
        Basis functions of the LPV model.
    fixed : optional
        Parameters kept fixed throughout (see :func:`lpvid.fixed_mask`);
        ``{"D": True}`` also makes the local models strictly proper.
    local : LocalModels, optional
        Local models to start from; default :func:`lpvid.identify_lti`.
    point : int, optional
        The local model to start from; default :func:`best_determined`.
    stages : {"all", "degree"}
        How the groups are freed.
    max_iter : int
        Most Levenberg-Marquardt steps per stage.

    Returns
    -------
    LpvModel
        With ``info``: ``method`` ("global_start"), ``point``, ``stages``,
        and ``history``, one entry per stage (groups free, V_NLS after it,
        steps taken).

    """
    model, _, _ = _global_start(
        data,
        order,
        basis,
        fixed,
        local=local,
        point=point,
        stages=stages,
        max_iter=max_iter,
    )
    return model


def _global_start(
    data: FrfData,
    order: int,
    basis: Basis,
    fixed: Any = None,
    *,
    local: LocalModels | None = None,
    point: int | None = None,
    stages: str = "all",
    max_iter: int = 100,
) -> tuple[LpvModel, FitResult, LpvModel]:
    """:func:`global_start`, also returning the last fit and the model it started from."""
    from lpvid.fit import fit_nls
    from lpvid.local import identify_lti
    from lpvid.smile import _p_range

    if not isinstance(data, FrfData):
        raise TypeError(f"data: expected an FrfData, got {type(data).__name__}")
    if not isinstance(basis, Basis):
        raise TypeError(f"basis: expected an lpvid basis, got {type(basis).__name__}")
    n = positive_int(order, "order")
    if stages not in STAGES:
        raise ValueError(f"stages: expected one of {STAGES}, got {stages!r}")
    max_iter = positive_int(max_iter, "max_iter")
    proper = isinstance(fixed, dict) and fixed.get("D") is True
    if local is None:
        local = identify_lti(data, n, strictly_proper=proper)
    if len(local) != data.n_points or local.order != n:
        raise ValueError(
            f"local: expected {data.n_points} local models of order {n}, got {len(local)} "
            f"of order {local.order}"
        )
    fixed_lti = {"D": True} if proper else None
    if point is None:
        point = best_determined(local, data, consistency(local), fixed_lti) if len(local) > 1 else 0
    point = positive_int(point, "point", minimum=0)
    if point >= len(local):
        raise ValueError(f"point: expected an index below {len(local)}, got {point}")
    nb = len(basis)
    mats = [
        np.concatenate([x, np.zeros((nb, *x.shape[1:]))]) for x in local[point].matrices().values()
    ]
    model = LpvModel(*mats, basis=basis, Ts=data.Ts, p_range=_p_range(basis._points(data.p)))
    check_compatible(model, data)
    user = fixed_mask(model, fixed)
    degrees = _degrees(basis)
    levels = sorted(set(degrees)) if stages == "degree" else ([max(degrees)] if degrees else [])
    history = []
    plan = [0] + levels
    for level in plan:
        frozen = [i + 1 for i, d in enumerate(degrees) if d > level]
        mask = user | _group_mask(model, frozen)
        stage_start = model
        fit = fit_nls(model, data, mask, max_iter=max_iter)
        model = fit.model
        history.append(
            {
                "free_groups": "constant only" if level == 0 else f"degree <= {level}",
                "vnls": float(fit.vnls),
                "n_iter": int(fit.n_iter),
            }
        )
    model.info.update(
        {
            "method": "global_start",
            "point": int(point),
            "stages": stages,
            "history": history,
        }
    )
    stage_start.info.update(model.info)
    return model, fit, stage_start


# ----------------------------------------------------------------------------- candidates
ROUTES = ("plain", "continuation", "global")


def between_points(p: ArrayLike, steps: int = 8) -> Arr:
    """Scheduling values on the segments joining neighbouring points.

    The segments are the edges of the minimum spanning tree of the points
    (in one dimension: consecutive sorted points), each cut into ``steps``
    equal parts; the points themselves are included.

    Parameters
    ----------
    p : array_like, shape (N,) or (N, Np)
    steps : int

    Returns
    -------
    ndarray, shape (M, Np)

    """
    arr = real_array(p, "p", ndim=(1, 2))
    arr = arr.reshape(arr.shape[0], -1)
    steps = positive_int(steps, "steps")
    order, parent = propagation_order(arr)
    t = np.linspace(0.0, 1.0, steps + 1)[1:-1, None]
    out = [arr]
    for q in order[1:]:
        a, b = arr[parent[q]], arr[q]
        out.append(a + t * (b - a))
    return np.concatenate(out)


def frozen_stable(model: LpvModel, p: ArrayLike) -> bool:
    """Whether the frozen models of an LPV model are stable at every given scheduling value.

    Parameters
    ----------
    model : LpvModel
    p : array_like, shape (M,) or (M, Np)

    Returns
    -------
    bool

    """
    psi = model.basis_values(p)
    w = np.concatenate([np.ones((psi.shape[0], 1)), psi], axis=1)
    A = np.tensordot(w, model.A, axes=1)
    lam = np.linalg.eigvals(A)
    if model.Ts is None:
        return bool(np.all(lam.real < 0))
    return bool(np.all(np.abs(lam) < 1))


@dataclass
class Candidate:
    """An initial LPV model refined by :func:`lpvid.fit_nls` on the identification data.

    Attributes
    ----------
    name : str
        Route and variant: ``"smile:<form>"`` (plain local models),
        ``"continuation+smile:<form>"``, ``"global:all"``, ``"global:degree"``.
    model : LpvModel
        The refined model; ``model.info`` says how its start was built.
    vnls : float
        V_NLS on the identification data.
    noise_floor : int
        Number of complex residuals of the identification data.
    validation_vnls : float or None
        V_NLS on the validation data, None without them.
    validation_floor : int or None
        Their number of complex residuals.
    seconds : float
        Time spent on this candidate (building the start and the fit; the
        local models, shared by several candidates, are not counted).
    constant_groups : int
        Groups (of 4 Nb) that the SMILE start left constant (relative
        magnitude below 1e-6, its ``info["constant_groups"]``): the
        simplicity the start offers the l2,1 path. For a global start, the
        groups still constant in the refined model (usually 0: its last
        stage frees every group).
    stable : bool
        Whether the frozen models are stable at the identification points
        and at 7 values between every two neighbouring points
        (:func:`between_points`, :func:`frozen_stable`). An LPV model that
        fits the points but has unstable frozen models between them is
        usually interpolating mismatched local models.
    note : str
        What was done, in words.
    fit : FitResult or None
        The last :func:`lpvid.fit_nls` run (its history and timings).
    start : LpvModel or None
        The model that run started from: the SMILE model (with its
        ``info["form"]``), or for a global start the model before its last
        stage (for ``"global:all"``, the constant model).
    """

    name: str
    model: LpvModel
    vnls: float
    noise_floor: int
    validation_vnls: float | None
    validation_floor: int | None
    seconds: float
    constant_groups: int
    stable: bool = True
    note: str = ""
    fit: FitResult | None = None
    start: LpvModel | None = None

    @property
    def ratio(self) -> float:
        """V_NLS relative to the noise floor."""
        return self.vnls / self.noise_floor

    @property
    def validation_ratio(self) -> float | None:
        """Validation V_NLS relative to its noise floor (None without validation data)."""
        if self.validation_vnls is None or not self.validation_floor:
            return None
        return self.validation_vnls / self.validation_floor

    def __str__(self) -> str:
        val = self.validation_ratio
        v = "" if val is None else f", validation V/floor {val:.3f}"
        st = "" if self.stable else ", unstable between the points"
        return f"{self.name}: V/floor {self.ratio:.3f}{v}{st}, {self.seconds:.2f} s"


def _candidate(
    name: str,
    start: LpvModel,
    data: FrfData,
    validation: FrfData | None,
    fixed: Any,
    t0: float,
    note: str,
    fit: FitResult | None = None,
    max_iter: int = 100,
) -> Candidate:
    """Refine ``start`` by fit_nls (unless its ``fit`` is given) and evaluate it."""
    from lpvid.fit import fit_nls

    if fit is None:
        fit = fit_nls(start, data, fixed, max_iter=max_iter)
    model = fit.model
    if model is not start and "method" not in model.info:
        # A refined SMILE model: say where it came from.
        model.info.update({"method": "fit_nls", "start": dict(start.info)})
    model.info["candidate"] = name
    nb = model.n_basis
    if "constant_groups" in start.info:  # a SMILE start
        const = int(start.info["constant_groups"])
    elif nb and model.p_range is not None:
        const = 4 * nb - model.group_norms().count(1e-6)
    else:
        const = 0
    return Candidate(
        name=name,
        model=model,
        vnls=float(fit.vnls),
        noise_floor=data.n_residuals,
        validation_vnls=None if validation is None else vnls(model, validation),
        validation_floor=None if validation is None else validation.n_residuals,
        seconds=time.perf_counter() - t0,
        constant_groups=int(const),
        stable=frozen_stable(model, between_points(data.p)),
        note=note,
        fit=fit,
        start=start,
    )


def initial_candidates(
    data: FrfData,
    order: int,
    basis: Basis,
    fixed: Any = None,
    validation: FrfData | None = None,
    routes: Sequence[str] = ROUTES,
    *,
    forms: Sequence[str] | None = None,
    local: LocalModels | None = None,
    max_iter: int = 100,
) -> list[Candidate]:
    """Initial LPV models by several routes, each refined by :func:`lpvid.fit_nls`.

    - ``"plain"``: :func:`lpvid.identify_lti`, then :func:`lpvid.smile_candidates`
      in every coherent form (``"smile:<form>"``);
    - ``"continuation"``: the local models by continuation
      (:func:`continue_local`), then every coherent form
      (``"continuation+smile:<form>"``);
    - ``"global"``: :func:`global_start` from the best-determined local
      model, groups freed all at once (``"global:all"``) and one degree at
      a time (``"global:degree"``, left out when the basis has one degree
      only, where it would repeat ``"global:all"``).

    Parameters
    ----------
    data : FrfData
        Identification data.
    order : int
        Number of states.
    basis : Basis
        Basis functions of the LPV model.
    fixed : optional
        Fixed parameters (see :func:`lpvid.fixed_mask`); ``{"D": True}``
        makes the local models strictly proper.
    validation : FrfData, optional
        Data at other scheduling values; every candidate is evaluated on them.
    routes : sequence of str
        Which routes to take, among ``"plain"``, ``"continuation"``, ``"global"``.
    forms : sequence of str, optional
        Coherent forms for the SMILE routes (default all of :data:`lpvid.smile.FORMS`).
    local : LocalModels, optional
        Plain local models, when already identified.
    max_iter : int
        Most Levenberg-Marquardt steps per fit.

    Returns
    -------
    list of Candidate
        In the order of ``routes``; a coherent form that cannot be built for
        a set of local models is left out (the reason is in the notes of
        that route's candidates).

    """
    from lpvid.local import LocalModels, identify_lti
    from lpvid.smile import smile_candidates

    if not isinstance(data, FrfData):
        raise TypeError(f"data: expected an FrfData, got {type(data).__name__}")
    if not isinstance(basis, Basis):
        raise TypeError(f"basis: expected an lpvid basis, got {type(basis).__name__}")
    n = positive_int(order, "order")
    if isinstance(routes, str):
        routes = (routes,)
    for r in routes:
        if r not in ROUTES:
            raise ValueError(f"routes: unknown route {r!r}; choose from {ROUTES}")
    if not routes:
        raise ValueError("routes: needs at least one route")
    if validation is not None and not isinstance(validation, FrfData):
        raise TypeError(f"validation: expected an FrfData, got {type(validation).__name__}")
    proper = isinstance(fixed, dict) and fixed.get("D") is True
    t = time.perf_counter()
    if local is None:
        local = identify_lti(data, n, strictly_proper=proper)
    elif not isinstance(local, LocalModels):
        raise TypeError(f"local: expected LocalModels, got {type(local).__name__}")
    local_s = time.perf_counter() - t
    out: list[Candidate] = []

    def smile_route(prefix: str, models: Any, shared: str) -> None:
        t0 = time.perf_counter()
        starts = smile_candidates(models, basis=basis, forms=forms)
        build = (time.perf_counter() - t0) / max(len(starts), 1)
        failed = next(iter(starts.values())).info.get("unavailable", {}) if starts else {}
        missing = f"; forms not built: {', '.join(failed)}" if failed else ""
        for form, m0 in starts.items():
            t1 = time.perf_counter() - build
            out.append(
                _candidate(
                    f"{prefix}smile:{form}",
                    m0,
                    data,
                    validation,
                    fixed,
                    t1,
                    f"SMILE ({form} form) of {shared}, refined by fit_nls{missing}",
                    max_iter=max_iter,
                )
            )

    for route in routes:
        if route == "plain":
            smile_route("", local, f"the plain local models ({local_s:.2f} s)")
        elif route == "continuation":
            t0 = time.perf_counter()
            cont = continue_local(data, local, strictly_proper=proper, max_iter=max_iter)
            which = ", ".join(f"{q}: {s}" for q, s in enumerate(cont.starts))
            smile_route(
                "continuation+",
                cont,
                f"the local models by continuation ({time.perf_counter() - t0:.2f} s; {which})",
            )
        else:
            levels = len(set(_degrees(basis)))
            for stages in ("all", "degree") if levels > 1 else ("all",):
                t0 = time.perf_counter()
                m, last, m0 = _global_start(
                    data, n, basis, fixed, local=local, stages=stages, max_iter=max_iter
                )
                steps = "; ".join(
                    f"{h['free_groups']}: V/floor {h['vnls'] / data.n_residuals:.3f}"
                    for h in m.info["history"]
                )
                out.append(
                    _candidate(
                        f"global:{stages}",
                        m0,
                        data,
                        validation,
                        fixed,
                        t0,
                        f"constant model from local model {m.info['point']}, then groups "
                        f"freed ({stages}): {steps}",
                        fit=last,
                    )
                )
    return out


def choose(candidates: Sequence[Candidate], tolerance: float = 0.02) -> tuple[Candidate, str]:
    """The best initial candidate, and why.

    Only the candidates whose frozen models are stable between the points
    (:attr:`Candidate.stable`) take part, when there are any: a model that
    fits the points and goes unstable between them is rarely what the data
    mean, however it fares at a few validation points.

    With validation data (every candidate has ``validation_vnls``): the
    lowest validation V_NLS; candidates within ``tolerance`` of it count
    as equal and the simplest of them (most constant groups), then the
    one with the lowest validation V_NLS, wins.

    Without: the lowest identification V_NLS, where candidates within two
    standard deviations of the noise floor (``2 sqrt(M)``, M the number of
    residuals) of the best count as equal and the simplest wins, then the
    lowest V_NLS.

    Parameters
    ----------
    candidates : sequence of Candidate
    tolerance : float
        Relative slack on the best validation V_NLS.

    Returns
    -------
    Candidate, str

    """
    cands = list(candidates)
    if not cands:
        raise ValueError("candidates: needs at least one candidate")
    for k, c in enumerate(cands):
        if not isinstance(c, Candidate):
            raise TypeError(f"candidates[{k}]: expected a Candidate, got {type(c).__name__}")
    tol = positive_float(tolerance, "tolerance", allow_zero=True)
    finite = [c for c in cands if np.isfinite(c.vnls)] or cands
    pool = [c for c in finite if c.stable] or finite
    dropped = len(finite) - len(pool)
    among = (
        f" among the {len(pool)} candidates whose frozen models are stable between the "
        f"points ({dropped} left out)"
        if dropped
        else ""
    )
    if all(c.validation_vnls is not None for c in pool):
        vals = {id(c): float(c.validation_vnls) for c in pool}  # type: ignore[arg-type]
        best = min(vals.values())
        tied = [c for c in pool if vals[id(c)] <= (1 + tol) * best]
        pick = min(tied, key=lambda c: (-c.constant_groups, vals[id(c)]))
        reason = (
            f"lowest validation V_NLS ({vals[id(pick)]:.5g}, "
            f"{pick.validation_ratio:.3f} x its noise floor){among}"
        )
        if len(tied) > 1:
            reason += (
                f"; {len(tied)} candidates within {tol:.0%} of the best validation V_NLS, "
                f"the simplest ({pick.constant_groups} constant groups) kept"
            )
        return pick, reason
    floor = pool[0].noise_floor
    best_v = min(c.vnls for c in pool)
    slack = 2.0 * np.sqrt(floor)
    tied = [c for c in pool if c.vnls <= best_v + slack]
    pick = min(tied, key=lambda c: (-c.constant_groups, c.vnls))
    reason = (
        f"no validation data; lowest identification V_NLS ({pick.vnls:.5g}, "
        f"{pick.ratio:.3f} x the noise floor){among}"
    )
    if len(tied) > 1:
        reason += (
            f"; {len(tied)} candidates within 2 sqrt(M) = {slack:.3g} of the best, "
            f"the simplest ({pick.constant_groups} constant groups) kept"
        )
    return pick, reason
