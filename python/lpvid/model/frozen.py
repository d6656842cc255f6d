"""Frozen LTI models of an LPV model: their matrices, poles, stability and frequency response.

The one place for the frozen stability test (poles strictly inside the unit
circle in discrete time, strictly in the left half plane in continuous time),
its margin, and the frequency response of an LTI model written in numpy.
The core's stability check (``rust/fit/stable.rs``) follows the same margin
rule; a test compares the two.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lpvid.model._protocol import ModelLike

__all__ = [
    "frozen_A",
    "frozen_poles",
    "frozen_stable",
    "lti_frf",
    "stability_margin",
    "stable_poles",
]


def stable_poles(lam: ArrayLike, Ts: float | None) -> NDArray[np.bool_]:
    """Which poles lie strictly inside the stability region.

    Parameters
    ----------
    lam : array_like of complex
        Poles (eigenvalues of A).
    Ts : float or None
        Sample time; None for continuous time.

    Returns
    -------
    ndarray of bool, the shape of ``lam``
    """
    arr = np.asarray(lam)
    return arr.real < 0 if Ts is None else np.abs(arr) < 1


def stability_margin(lam: ArrayLike, Ts: float | None) -> NDArray[np.float64]:
    """Distance of a frozen model to the stability boundary, from its poles.

    Discrete time: ``1 - max |lambda|``. Continuous time: the smallest
    ``-Re lambda / |lambda|`` (the damping ratio of the least damped pole;
    0 for a pole at the origin), so that the margin does not depend on the
    time unit. Positive exactly when :func:`stable_poles` holds for every pole.

    Parameters
    ----------
    lam : array_like of complex, shape (..., n)
        Poles of one or several frozen models (the last axis).
    Ts : float or None
        Sample time; None for continuous time.

    Returns
    -------
    ndarray, shape (...)
        ``-inf`` where a pole is not finite.

    Examples
    --------
    >>> float(stability_margin([0.5 + 0.5j, 0.9], Ts=1.0))
    0.09999999999999998
    >>> float(stability_margin([-1 + 1j, -3.0], Ts=None))  # damping ratio of -1 +- 1j
    0.7071067811865475

    """
    arr = np.asarray(lam, dtype=complex)
    size = np.abs(arr)
    if Ts is None:
        with np.errstate(invalid="ignore", divide="ignore"):
            rel = np.where(size > 0, -arr.real / np.where(size > 0, size, 1.0), 0.0)
        out = np.min(rel, axis=-1)
    else:
        out = 1.0 - np.max(size, axis=-1)
    bad = ~np.all(np.isfinite(arr), axis=-1)
    return np.where(bad, -np.inf, out)


def frozen_A(model: ModelLike, p: ArrayLike) -> NDArray[np.float64]:
    """``A(p)`` at every scheduling value, shape ``(M, n, n)``."""
    psi = model.basis_values(p)
    w = np.concatenate([np.ones((psi.shape[0], 1)), psi], axis=1)
    return np.tensordot(w, model.A, axes=1)


def frozen_poles(model: ModelLike, p: ArrayLike) -> NDArray[np.complex128]:
    """Poles of the frozen models at every scheduling value, shape ``(M, n)``."""
    return np.linalg.eigvals(frozen_A(model, p)).astype(complex)


def frozen_stable(model: ModelLike, p: ArrayLike) -> bool:
    """Whether the frozen models are stable at every given scheduling value.

    Parameters
    ----------
    model : LpvModel
    p : array_like, shape (M,) or (M, Np)

    Returns
    -------
    bool

    Examples
    --------
    >>> import lpvid
    >>> m = lpvid.LpvModel([[[0.5]], [[0.6]]], [[[1.0]], [[0.0]]], [[[1.0]], [[0.0]]],
    ...                    basis=lpvid.Polynomial(1), Ts=1.0)
    >>> frozen_stable(m, [0.0, 0.5]), frozen_stable(m, [0.0, 1.0])
    (True, False)

    """
    return bool(np.all(stable_poles(frozen_poles(model, p), model.Ts)))


def lti_frf(
    A: NDArray[np.float64],
    B: NDArray[np.float64],
    C: NDArray[np.float64],
    D: NDArray[np.float64],
    z: NDArray[np.complex128],
) -> NDArray[np.complex128]:
    """``C (zI - A)^-1 B + D`` at every point of ``z``, shape ``(F, l, r)``.

    A dense numpy solve per point, for small models outside the hot loop
    (the core evaluates LPV models; see :meth:`lpvid.LpvModel.frf`).
    """
    n = A.shape[0]
    lhs = z[:, None, None] * np.eye(n)[None] - A[None]
    return C[None] @ np.linalg.solve(lhs, np.broadcast_to(B, (z.size, *B.shape))) + D[None]
