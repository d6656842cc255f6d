"""Coherent state coordinates for a set of local LTI models (method.md 5a).

A state-space realisation is unique only up to a similarity transform
``(T A T^-1, T B, C T^-1, D)``. Before the matrix entries of local models can
be interpolated over the scheduling parameter, the models must be brought to
coordinates that vary smoothly from point to point. Each function here takes
a list of ``(A, B, C, D)`` tuples (all of one order) and returns the
transformed list together with notes (condition number of the transforms,
reference point, ...).

Forms:

- ``observability`` / ``controllability``: the transform of the SMILE
  authors (``decaigny.m`` of meco-group/resmile), with Krylov matrices of the
  shifted and scaled ``A`` and the reference point chosen by the true
  worst-case condition number.
- ``modal`` / ``modal_input``: real modal form with modes tracked across the
  points (nearest neighbours first); each mode's free scaling is fixed by
  balancing ``||b||`` and ``||c||`` (``modal``) or by making one column of B
  constant (``modal_input``).
- ``pairwise``: sequential least-squares alignment of neighbouring points,
  ``min_T ||T A_k - A_m T||^2 + ||T B_k - B_m||^2 + ||C_k - C_m T||^2``.

What cannot be untangled: modal forms fail when the number of complex pole
pairs changes across the points (two real poles merging into a pair), and
modes that cross between two neighbouring points (equal frequency, similar
shape) may be swapped. The Krylov forms need every local model to be
observable (controllable): a mode that nearly vanishes from the outputs
(inputs) at one point makes its transform ill-conditioned.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from lpvid._graphs import assignment
from lpvid._spread import side_by_side
from lpvid.data.schedule import propagation_order, subtrees
from lpvid.errors import CoherenceError
from lpvid.model.frozen import stable_poles

__all__ = [
    "CoherenceError",
    "balance",
    "krylov_form",
    "modal_form",
    "pairwise_form",
]

Arr = NDArray[np.float64]
Ss = tuple[Arr, Arr, Arr, Arr]

#: Largest condition number accepted for a similarity transform.
MAX_COND = 1e12


def transform(model: Ss, T: Arr) -> Ss:
    """Apply the similarity transform ``x~ = T x``."""
    A, B, C, D = model
    Ti = np.linalg.inv(T)
    return T @ A @ Ti, T @ B, C @ Ti, D.copy()


def _stable(A: Arr, Ts: float | None) -> bool:
    return bool(np.all(stable_poles(np.linalg.eigvals(A), Ts)))


def balance(models: Sequence[Ss], Ts: float | None) -> tuple[list[Ss], bool]:
    """Balanced realisation of every model, when all of them allow one.

    Parameters
    ----------
    models : sequence of (A, B, C, D)
    Ts : float or None
        Sample time (None: continuous time).

    Returns
    -------
    models : list of (A, B, C, D)
        Balanced models, or the input unchanged.
    done : bool
        False when a model is unstable or not minimal enough for its
        Gramians to be positive definite; then nothing is balanced.

    """
    import scipy.linalg as sla

    out = []
    for A, B, C, D in models:
        if not _stable(A, Ts):
            return list(models), False
        try:
            if Ts is None:
                P = sla.solve_continuous_lyapunov(A, -B @ B.T)
                Q = sla.solve_continuous_lyapunov(A.T, -C.T @ C)
            else:
                P = sla.solve_discrete_lyapunov(A, B @ B.T)
                Q = sla.solve_discrete_lyapunov(A.T, C.T @ C)
            Lc = np.linalg.cholesky((P + P.T) / 2)
            Lo = np.linalg.cholesky((Q + Q.T) / 2)
        except np.linalg.LinAlgError:
            return list(models), False
        U, s, Vt = np.linalg.svd(Lo.T @ Lc)
        if s[-1] <= 1e-14 * s[0]:
            return list(models), False
        T = (U / np.sqrt(s)).T @ Lo.T
        out.append(transform((A, B, C, D), T))
    return out, True


def _shift_scale(models: Sequence[Ss]) -> tuple[float, float]:
    """A common shift c and scale rho so that (A - cI)/rho has spectral radius about 1."""
    n = models[0][0].shape[0]
    c = float(np.mean([np.trace(m[0]) / n for m in models]))
    rho = float(np.mean([np.max(np.abs(np.linalg.eigvals(m[0] - c * np.eye(n)))) for m in models]))
    return c, rho if rho > 0 else 1.0


def _krylov(model: Ss, kind: str, c: float, rho: float) -> Arr:
    A, B, C, _ = model
    n = A.shape[0]
    F = (A - c * np.eye(n)) / rho
    if kind == "observability":
        blocks = [C]
        for _ in range(n - 1):
            blocks.append(blocks[-1] @ F)
        return np.concatenate(blocks, axis=0)
    blocks = [B]
    for _ in range(n - 1):
        blocks.append(F @ blocks[-1])
    return np.concatenate(blocks, axis=1)


def _cond(T: Arr) -> float:
    s = np.linalg.svd(T, compute_uv=False)
    return float(s[0] / s[-1]) if s[-1] > 0 else np.inf


def _worst_conditions(K: Sequence[Arr], pinvs: Sequence[Arr], kind: str) -> Arr:
    """``max_k cond(T_ik)`` for every reference ``i``: all ``N^2`` transforms in one batch.

    One stacked product and one stacked SVD instead of ``N^2`` small ones
    (at N = 24 points, a leave-one-out check builds this 96 times: 55 000
    SVD calls of 6 x 6 matrices took 1.3 s). A singular transform counts as
    infinitely ill-conditioned.
    """
    Ks, Ps = np.stack(K), np.stack(pinvs)
    T = Ps[:, None] @ Ks[None, :] if kind == "observability" else Ks[:, None] @ Ps[None, :]
    s = np.linalg.svd(T, compute_uv=False)
    big, small = s[..., 0], s[..., -1]
    cond = np.full(small.shape, np.inf)
    np.divide(big, small, out=cond, where=small > 0)
    return np.where(np.isnan(cond), np.inf, cond).max(axis=1)


def krylov_form(models: Sequence[Ss], kind: str) -> tuple[list[Ss], dict[str, float | int]]:
    """The SMILE authors' observability- or controllability-based coherent form.

    With Krylov matrices ``K_k`` of the shifted, scaled ``A_k`` (observability
    ``[C; C F; ...]`` or controllability ``[B, F B, ...]``), the reference
    ``i*`` minimises the worst-case ``max_k cond(T_ik)`` and every model is
    transformed with ``T_k = pinv(O_i*) O_k`` (or ``Ctr_i* pinv(Ctr_k)``).

    Parameters
    ----------
    models : sequence of (A, B, C, D)
    kind : {"observability", "controllability"}

    Returns
    -------
    models : list of (A, B, C, D)
    notes : dict
        ``condition`` (worst-case condition number of the transforms) and
        ``reference`` (index of the reference point).

    Raises
    ------
    CoherenceError
        When every choice of reference leaves a singular transform.

    """
    c, rho = _shift_scale(models)
    K = [_krylov(m, kind, c, rho) for m in models]
    pinvs = [np.linalg.pinv(k) for k in K]

    def tr(i: int, k: int) -> Arr:
        return pinvs[i] @ K[k] if kind == "observability" else K[i] @ pinvs[k]

    worst = _worst_conditions(K, pinvs, kind)
    ref = int(np.argmin(worst))
    if not np.isfinite(worst[ref]) or worst[ref] > MAX_COND:
        raise CoherenceError(
            f"{kind}: the local models are not all {kind[:-4]}able enough "
            f"(best worst-case condition number {worst[ref]:.3g})"
        )
    out = [transform(m, tr(ref, k)) for k, m in enumerate(models)]
    return out, {"condition": float(worst[ref]), "reference": ref}


def _modes(model: Ss, Ts: float | None) -> list[dict[str, object]]:
    """Modes of one model: eigenvalue (Im >= 0), output and input vectors."""
    A, B, C, _ = model
    lam, V = np.linalg.eig(A)
    W = np.linalg.inv(V)
    scale = np.max(np.abs(lam)) if lam.size else 1.0
    tol = 1e-9 * max(scale, 1e-300)
    modes = []
    for k in range(lam.size):
        if lam[k].imag < -tol:
            continue
        real = abs(lam[k].imag) <= tol
        v, w = V[:, k], W[k]
        if real:
            v, w = v.real, w.real
        modes.append({"lam": lam[k].real if real else lam[k], "real": real, "v": v, "w": w})
    for m in modes:
        m["c"] = C @ m["v"]
        m["b"] = m["w"] @ B
        m["s"] = np.log(complex(m["lam"])) / Ts if Ts is not None else complex(m["lam"])
    return modes


def _match_cost(a: dict[str, object], b: dict[str, object]) -> float:
    """Distance between two modes: eigenvalue (relative) plus residue direction."""
    sa, sb = complex(a["s"]), complex(b["s"])  # type: ignore[arg-type]
    d_lam = abs(sa - sb) / max(abs(sa) + abs(sb), 1e-300)
    Ra = np.outer(a["c"], a["b"]).ravel()  # type: ignore[arg-type]
    Rb = np.outer(b["c"], b["b"]).ravel()  # type: ignore[arg-type]
    na, nb = np.linalg.norm(Ra), np.linalg.norm(Rb)
    shape = 1.0 - abs(np.vdot(Ra, Rb)) / (na * nb) if na > 0 and nb > 0 else 1.0
    return float(d_lam + 0.5 * shape)


def _track(all_modes: list[list[dict[str, object]]], p: Arr) -> list[list[dict[str, object]]]:
    """Reorder every point's modes so that index j is the same mode everywhere."""
    counts = {(sum(m["real"] for m in ms), len(ms)) for ms in all_modes}  # type: ignore[misc]
    if len(counts) != 1:
        raise CoherenceError(
            "modal: the number of real poles and complex pole pairs changes across the "
            "points; modes cannot be tracked through a real/complex transition"
        )
    order, parent = propagation_order(p)
    tracked: list[list[dict[str, object]] | None] = [None] * len(all_modes)
    tracked[order[0]] = sorted(
        all_modes[order[0]], key=lambda m: (not m["real"], abs(complex(m["s"])))
    )
    for k in order[1:]:
        ref = tracked[parent[k]]
        assert ref is not None
        mine = all_modes[k]
        out: list[dict[str, object] | None] = [None] * len(ref)
        for real in (True, False):
            ri = [j for j, m in enumerate(ref) if m["real"] == real]
            mi = [j for j, m in enumerate(mine) if m["real"] == real]
            if not ri:
                continue
            cost = np.array([[_match_cost(ref[a], mine[b]) for b in mi] for a in ri])
            rows, cols = assignment(cost)
            for a, b in zip(rows, cols, strict=True):
                out[ri[a]] = mine[mi[b]]
        tracked[k] = out  # type: ignore[assignment]
    return tracked  # type: ignore[return-value]


def modal_form(
    models: Sequence[Ss], p: Arr, Ts: float | None, norm: str = "balanced"
) -> tuple[list[Ss], dict[str, float | int]]:
    """Real modal form with modes tracked across the points.

    Complex pairs ``sigma +- j omega`` become blocks ``[[sigma, omega],
    [-omega, sigma]]`` (real modes 1 x 1), in the same order at every point.
    A mode's remaining freedom (a complex factor ``alpha``: ``c -> c alpha``,
    ``b -> b / alpha``) is fixed by ``norm``:

    - ``"balanced"``: ``||b|| = ||c||`` and the entry of ``b`` for the input
      that drives the mode best (over all points) real and positive;
    - ``"input"``: that entry of ``b`` equal to one, so that the matching
      column of B is constant over the points.

    Parameters
    ----------
    models : sequence of (A, B, C, D)
    p : ndarray, shape (N, Np)
    Ts : float or None
    norm : {"balanced", "input"}

    Returns
    -------
    models : list of (A, B, C, D)
    notes : dict
        ``condition``: worst condition number of the modal transforms.

    Raises
    ------
    CoherenceError
        When modes cannot be tracked (see module notes) or a mode is not
        driven by any input.

    """
    all_modes = [_modes(m, Ts) for m in models]
    tracked = _track(all_modes, p)
    n_modes = len(tracked[0])
    pivot = []
    for j in range(n_modes):
        bs = np.array([np.abs(np.asarray(ms[j]["b"])) for ms in tracked])  # (N, r)
        rel = bs / np.maximum(np.linalg.norm(bs, axis=1, keepdims=True), 1e-300)
        pivot.append(int(np.argmax(rel.min(axis=0))))
        if np.min(bs[:, pivot[-1]]) == 0.0:
            raise CoherenceError("modal: a mode is not driven by any input at some point")
    out = []
    worst = 1.0
    for (A, B, C, D), ms in zip(models, tracked, strict=True):
        cols, rows = [], []
        for j, m in enumerate(ms):
            v, w = np.asarray(m["v"]), np.asarray(m["w"])
            b, c = np.asarray(m["b"]), np.asarray(m["c"])
            bj = b[pivot[j]]
            if norm == "input":
                alpha = bj
            else:
                mag = np.sqrt(np.linalg.norm(b) / max(np.linalg.norm(c), 1e-300))
                alpha = mag * bj / abs(bj)
            v, w = v * alpha, w / alpha
            if m["real"]:
                cols.append(v.real[:, None])
                rows.append(w.real[None, :])
            else:
                cols.append(np.stack([v.real, v.imag], axis=1))
                rows.append(np.stack([2 * w.real, -2 * w.imag], axis=0))
        T = np.concatenate(rows, axis=0)
        Tinv = np.concatenate(cols, axis=1)
        worst = max(worst, _cond(T))
        out.append((T @ A @ Tinv, T @ B, C @ Tinv, D.copy()))
    if worst > MAX_COND:
        raise CoherenceError(f"modal: a modal transform is singular (condition {worst:.3g})")
    return out, {"condition": float(worst)}


def _align_branch(
    branch: list[int], models: Sequence[Ss], parent: NDArray[np.int_], root: Ss
) -> list[tuple[int, Ss, float]]:
    """:func:`pairwise_form` along one subtree below the root.

    Returns every point of ``branch`` with its aligned model and the
    condition number of its transform, in walking order.
    """
    aligned = {int(parent[branch[0]]): root}
    out = []
    for k in branch:
        Am, Bm, Cm, _ = aligned[int(parent[k])]
        Ak, Bk, Ck, _ = models[k]
        n = Ak.shape[0]
        eye = np.eye(n)
        wa = 1.0 / max(np.linalg.norm(Am), 1e-300)
        wb = 1.0 / max(np.linalg.norm(Bm), 1e-300)
        wc = 1.0 / max(np.linalg.norm(Cm), 1e-300)
        # Column-major vec: vec(T X) = (X^T kron I) vec T, vec(X T) = (I kron X) vec T.
        M = np.concatenate(
            [
                wa * (np.kron(Ak.T, eye) - np.kron(eye, Am)),
                wb * np.kron(Bk.T, eye),
                wc * np.kron(eye, Cm),
            ]
        )
        rhs = np.concatenate([np.zeros(n * n), wb * Bm.ravel(order="F"), wc * Ck.ravel(order="F")])
        T = np.linalg.lstsq(M, rhs, rcond=None)[0].reshape(n, n, order="F")
        c = _cond(T)
        if not np.isfinite(c) or c > MAX_COND:
            raise CoherenceError(f"pairwise: the alignment of point {k} is singular")
        aligned[k] = transform(models[k], T)
        out.append((k, aligned[k], c))
    return out


def pairwise_form(models: Sequence[Ss], p: Arr) -> tuple[list[Ss], dict[str, float | int]]:
    """Sequential least-squares alignment of each model to an aligned neighbour.

    Walking the minimum spanning tree of the points from the centre (see
    :func:`propagation_order`), model k is transformed with the ``T`` that
    minimises ``||T A_k - A_m T||^2 / ||A_m||^2 + ||T B_k - B_m||^2 / ||B_m||^2
    + ||C_k - C_m T||^2 / ||C_m||^2`` for its aligned neighbour m (linear in T).
    The subtrees below the root depend on the root alone and are walked
    side by side (:func:`lpvid._spread.side_by_side`), with the same result.

    Parameters
    ----------
    models : sequence of (A, B, C, D)
    p : ndarray, shape (N, Np)

    Returns
    -------
    models : list of (A, B, C, D)
    notes : dict
        ``condition``: worst condition number of the transforms,
        ``reference``: the root point.

    """
    order, parent = propagation_order(p)
    root = int(order[0])
    out: list[Ss | None] = [None] * len(models)
    out[root] = tuple(x.copy() for x in models[root])  # type: ignore[assignment]
    n = models[root][0].shape[0]
    rows = n * n + n * models[root][1].shape[1] + models[root][2].shape[0] * n
    branches = subtrees(order, parent)
    longest = max((len(b) for b in branches), default=0)
    walked = side_by_side(
        _align_branch,
        [(branch, models, parent, out[root]) for branch in branches],
        flops=4.0 * rows * n**4 * longest,
        each=3 * 8 * rows * n * n,
    )
    worst = 1.0
    for aligned in walked:
        for k, model, c in aligned:
            out[k] = model
            worst = max(worst, c)
    return out, {"condition": float(worst), "reference": root}  # type: ignore[return-value]
