"""Poles of local LTI models: coordinates that compare them, matching, and uncertainty."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from lpvid._graphs import assignment
from lpvid.data.frf import FrfData
from lpvid.model.lpv import LpvModel
from lpvid.trust.uncertainty import covariance

__all__ = [
    "describe_pole",
    "is_real",
    "match_poles",
    "pole_coordinates",
    "pole_distance",
    "pole_uncertainty",
]


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


def match_poles(a: NDArray[np.complex128], b: NDArray[np.complex128]) -> tuple[float, int, int]:
    """Best pairing of two pole sets (in :func:`pole_coordinates`).

    Returns the largest distance among the paired poles and the indices of
    that worst pair in ``a`` and ``b``.
    """
    cost = np.abs(a[:, None] - b[None, :])
    rows, cols = assignment(cost)
    k = int(np.argmax(cost[rows, cols]))
    return float(cost[rows[k], cols[k]]), int(rows[k]), int(cols[k])


def is_real(u: NDArray[np.complex128]) -> NDArray[np.bool_]:
    """Which poles (in log(-s) coordinates) are real: angle exactly 0 or pi."""
    return (u.imag == 0.0) | (u.imag == np.pi)


def describe_pole(u: complex) -> str:
    """A pole in log(-s) coordinates as 'f Hz zeta z' or 'f Hz real'."""
    f = float(np.exp(u.real)) / (2 * np.pi)
    if u.imag == 0.0:
        return f"{f:.4g} Hz real"
    if u.imag == np.pi:
        return f"{f:.4g} Hz real unstable"
    return f"{f:.4g} Hz zeta {np.cos(abs(u.imag)):.2f}"


def pole_distance(a: LpvModel, b: LpvModel) -> float:
    """The worst matched pole distance between two LTI models (see :func:`match_poles`)."""
    return match_poles(pole_coordinates(a), pole_coordinates(b))[0]


def pole_uncertainty(model: LpvModel, data: FrfData, fixed: Any = None) -> NDArray[np.float64]:
    """Standard deviation of every pole of an LTI model in ``log(-s)`` units.

    :meth:`lpvid.Covariance.pole_std` (first-order propagation of the
    parameter covariance, on the complement of the similarity transforms,
    which move no pole) divided by ``|s|``, ``s`` the continuous-time pole:
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
        In the order of ``numpy.linalg.eig(model.A[0])``.

    """
    if model.n_basis != 0:
        raise ValueError("model: expected an LTI model (Nb = 0)")
    cov = covariance(model, data, fixed, warn=False)
    lam, std = cov.pole_std(0.0, return_poles=True)
    if model.Ts is None:
        scale = np.abs(lam)
    else:
        scale = np.abs(lam * np.log(lam.astype(complex)))
    return std / np.maximum(scale, 1e-300)
