"""Frequency-domain subspace estimate of an LTI model from its FRF (method.md 5b).

McKelvey, Akcay and Ljung (1996): the FRF samples ``G_k`` at ``z_k`` on the
unit circle are stacked with the Vandermonde vectors ``W_q(z_k) = [1, z_k,
..., z_k^(q-1)]``; removing the input part by an LQ factorisation leaves a
matrix whose column space is the extended observability matrix. ``C`` and
``A`` follow from it (shift invariance); ``B`` and ``D`` from a weighted
linear least-squares fit to the data.

Continuous-time data are mapped to the unit circle by the bilinear map
``z = (a + s) / (a - s)`` with ``a`` at the geometric centre of the band;
``A`` and ``C`` are mapped back exactly and ``B``, ``D`` are fitted in the
continuous-time domain.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lpvid._checks import complex_array, positive_int, real_array, sample_time
from lpvid._threads import single_blas

__all__ = [
    "bilinear_to_continuous",
    "fd_subspace",
    "fit_bd",
    "max_order",
    "reflect_unstable",
    "singular_values",
]


def max_order(n_lines: int, n_outputs: int, n_inputs: int) -> int:
    """Largest model order the subspace estimate supports on ``n_lines`` FRF lines.

    The LQ step needs ``2 M r >= q r + n`` with ``q >= n + 1`` block rows, and
    the B/D least squares needs ``2 M l >= n + l`` equations per input.

    Parameters
    ----------
    n_lines, n_outputs, n_inputs : int
        Frequency lines M, outputs l and inputs r.

    Returns
    -------
    int
        The largest order n (0 when even n = 1 is out of reach).

    """
    m, l, r = n_lines, n_outputs, n_inputs
    by_lq = (2 * m * r - r) // (r + 1)
    by_bd = 2 * m * l - l
    return max(0, min(by_lq, by_bd))


def reflect_unstable(A: NDArray[np.float64], Ts: float | None) -> tuple[NDArray[np.float64], int]:
    """Mirror unstable eigenvalues of ``A`` into the stable region.

    Discrete time: ``lambda -> 1 / conj(lambda)`` for ``|lambda| > 1``;
    continuous time: ``lambda -> -conj(lambda)`` for ``Re lambda > 0``. The
    eigenvectors are kept, so ``C`` stays valid in the same coordinates.

    Parameters
    ----------
    A : ndarray, shape (n, n)
    Ts : float or None

    Returns
    -------
    A : ndarray
        The reflected matrix (``A`` itself when nothing was unstable).
    n_reflected : int
        How many eigenvalues were moved.

    """
    lam, vec = np.linalg.eig(A)
    bad = np.abs(lam) > 1.0 if Ts is not None else lam.real > 0.0
    if not np.any(bad):
        return A, 0
    new = lam.copy()
    new[bad] = 1.0 / np.conj(lam[bad]) if Ts is not None else -np.conj(lam[bad])
    out = vec @ np.diag(new) @ np.linalg.inv(vec)
    return np.ascontiguousarray(out.real), int(np.sum(bad))


def fit_bd(
    A: NDArray[np.float64],
    C: NDArray[np.float64],
    z: NDArray[np.complex128],
    G: NDArray[np.complex128],
    sigma: NDArray[np.float64],
    strictly_proper: bool = False,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Weighted least-squares B and D for given A and C.

    Minimises ``sum_k || (G_k - D - C (z_k I - A)^-1 B) / sigma_k ||^2``
    (entrywise division), which is linear in B and D.

    Parameters
    ----------
    A : ndarray, shape (n, n)
    C : ndarray, shape (l, n)
    z : ndarray, shape (M,), complex
        Evaluation points (``exp(j w Ts)`` or ``j w``).
    G : ndarray, shape (M, l, r), complex
    sigma : ndarray, shape (M, l, r)
    strictly_proper : bool
        Keep D at zero.

    Returns
    -------
    B : ndarray, shape (n, r)
    D : ndarray, shape (l, r)

    """
    n = A.shape[0]
    m, l, r = G.shape
    eye = np.eye(n)
    # Y_k = C (z_k I - A)^-1, shape (M, l, n), from solves with the transpose.
    lhs = z[:, None, None] * eye[None] - A[None]
    Y = np.swapaxes(np.linalg.solve(np.swapaxes(lhs, 1, 2), np.broadcast_to(C.T, (m, n, l))), 1, 2)
    B = np.zeros((n, r))
    D = np.zeros((l, r))
    for i in range(r):
        w = 1.0 / sigma[:, :, i]  # (M, l)
        regs = [Y * w[:, :, None]]
        if not strictly_proper:
            regs.append(np.broadcast_to(np.eye(l), (m, l, l)) * w[:, :, None])
        X = np.concatenate(regs, axis=2).reshape(m * l, -1)
        y = (G[:, :, i] * w).reshape(-1)
        Xr = np.concatenate([X.real, X.imag])
        yr = np.concatenate([y.real, y.imag])
        scale = np.linalg.norm(Xr, axis=0)
        scale[scale == 0] = 1.0
        sol = np.linalg.lstsq(Xr / scale, yr, rcond=None)[0] / scale
        B[:, i] = sol[:n]
        if not strictly_proper:
            D[:, i] = sol[n:]
    return B, D


def _weights(sigma: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Output scales (l,) and column weights (M, r) that approximate 1/sigma.

    A constant scale per output is a change of output coordinates and a
    weight per (line, input) column leaves the noise-free estimate exact
    (the column space of the projected matrix is unchanged), so only these
    two kinds of weighting enter the subspace step.
    """
    out_scale = np.sqrt(np.mean(sigma**2, axis=(0, 2)))
    col = np.sqrt(np.mean((sigma / out_scale[None, :, None]) ** 2, axis=1))
    return out_scale, 1.0 / col


def _projected(
    zd: NDArray[np.complex128],
    G: NDArray[np.complex128],
    sigma: NDArray[np.float64],
    q: int,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Left singular vectors and singular values of the projected matrix, and the output scales."""
    m, l, r = G.shape
    out_scale, colw = _weights(sigma)
    Gs = G / out_scale[None, :, None] * colw[:, None, :]
    W = zd[:, None] ** np.arange(q)[None, :]  # (M, q)
    # Gbig[(j, row), (k, i)] = z_k^j G_k[row, i] w_ki ;  Ubig[(j, i'), (k, i)] = z_k^j d_i'i w_ki
    Gbig = np.einsum("kj,kai->jaki", W, Gs).reshape(q * l, m * r)
    Ubig = np.einsum("kj,ab,kb->jakb", W, np.eye(r), colw).reshape(q * r, m * r)
    H = np.concatenate([Ubig, Gbig])
    H = np.concatenate([H.real, H.imag], axis=1)
    R = np.linalg.qr(H.T, mode="r")
    L22 = R[q * r :, q * r :].T
    U, s, _ = np.linalg.svd(L22)
    return U, s, out_scale


def _observability(
    zd: NDArray[np.complex128],
    G: NDArray[np.complex128],
    sigma: NDArray[np.float64],
    n: int,
    q: int,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """A and C (unit-circle domain) and the singular values of the projected matrix."""
    l = G.shape[1]
    U, s, out_scale = _projected(zd, G, sigma, q)
    O = U[:, :n]
    C = O[:l] * out_scale[:, None]
    A = np.linalg.lstsq(O[: (q - 1) * l], O[l:], rcond=None)[0]
    return A, C, s


def _unit_circle(w: NDArray[np.float64], Ts: float | None) -> tuple[NDArray[np.complex128], float]:
    """The evaluation points on the unit circle and the bilinear centre (0 in discrete time)."""
    if Ts is not None:
        return np.exp(1j * w * Ts), 0.0
    a = _bilinear_centre(w)
    z = 1j * w
    return (a + z) / (a - z), a


def singular_values(
    freqs_hz: ArrayLike,
    G: ArrayLike,
    sigma: ArrayLike | None = None,
    Ts: float | None = None,
    *,
    n_rows: int,
) -> NDArray[np.float64]:
    """Singular values of the projected matrix of the subspace step (the order's evidence).

    The matrix whose column space :func:`fd_subspace` takes as the extended
    observability matrix: a system of order n gives n large singular values
    and the rest at the level of the noise.

    Parameters
    ----------
    freqs_hz, G, sigma, Ts
        As in :func:`fd_subspace` (``G`` of shape (M, l, r)).
    n_rows : int
        Block rows q of the Vandermonde stack.

    Returns
    -------
    ndarray, shape (q l,)
        In decreasing order.

    """
    Ts = sample_time(Ts)
    f = real_array(freqs_hz, "freqs_hz", ndim=1)
    g = complex_array(G, "G", ndim=3)
    s = np.ones(g.shape) if sigma is None else real_array(sigma, "sigma").reshape(g.shape)
    m, _, r = g.shape
    q = positive_int(n_rows, "n_rows", minimum=2)
    if q * r > 2 * m * r:
        raise ValueError(f"n_rows: at most {2 * m} block rows fit {m} lines, got {q}")
    zd, _ = _unit_circle(2.0 * np.pi * f, Ts)
    return _projected(zd, g, s, q)[1]


@single_blas
def fd_subspace(
    freqs_hz: ArrayLike,
    G: ArrayLike,
    order: int,
    sigma: ArrayLike | None = None,
    Ts: float | None = None,
    *,
    n_rows: int | None = None,
    stable: bool = True,
    strictly_proper: bool = False,
) -> tuple[NDArray[np.float64], ...]:
    """State-space estimate of an LTI system from one FRF (McKelvey et al. 1996).

    Parameters
    ----------
    freqs_hz : array_like, shape (M,)
        Frequency lines in Hz.
    G : array_like, shape (M, l, r) or (M,)
        Measured FRF.
    order : int
        Model order n.
    sigma : array_like, optional
        Standard deviations, shape of ``G``; default 1. Used as weights.
    Ts : float, optional
        Sample time (discrete time); None for continuous time.
    n_rows : int, optional
        Block rows q of the Vandermonde stack (``q > n``); default
        ``min(3 n, what the data allow)``.
    stable : bool
        Mirror unstable poles into the stable region (default True).
    strictly_proper : bool
        Fix D to zero.

    Returns
    -------
    A, B, C, D : ndarray
        The estimate, in the same time domain as the data.

    Raises
    ------
    ValueError, TypeError
        When ``order`` is not a positive integer or exceeds what the data
        support, or an array is malformed.

    Notes
    -----
    Noise-free data of a system of order ``n`` give the system exactly (up to
    rounding). The weighting by ``sigma`` uses one scale per output and one
    weight per (line, input); the B/D fit uses ``1/sigma`` entrywise.

    """
    Ts = sample_time(Ts)
    f = real_array(freqs_hz, "freqs_hz", ndim=1)
    g = complex_array(G, "G", ndim=(1, 3))
    if g.ndim == 1:
        g = g[:, None, None]
    if g.shape[0] != f.size:
        raise ValueError(f"G: expected {f.size} lines along axis 0, got shape {g.shape}")
    s = np.ones(g.shape) if sigma is None else real_array(sigma, "sigma").reshape(g.shape)
    if np.any(s <= 0):
        raise ValueError("sigma: standard deviations must be > 0")
    n = positive_int(order, "order")
    m, l, r = g.shape
    limit = max_order(m, l, r)
    if n > limit:
        raise ValueError(
            f"order: {n} exceeds what the data support ({m} lines, {l} outputs x {r} inputs "
            f"allow at most order {limit})"
        )
    q_max = (2 * m * r - n) // r
    if n_rows is None:
        q = max(n + 1, min(3 * n, q_max))
    else:
        q = positive_int(n_rows, "n_rows", minimum=n + 1)
        if q > q_max:
            raise ValueError(f"n_rows: at most {q_max} block rows fit {m} lines, got {q}")
    w = 2.0 * np.pi * f
    zd, a = _unit_circle(w, Ts)
    A, C, _ = _observability(zd, g, s, n, q)
    if Ts is None:
        A, C = _from_unit_circle(A, C, a)
    z = zd if Ts is not None else 1j * w
    if stable:
        A, _ = reflect_unstable(A, Ts)
    B, D = fit_bd(A, C, z, g, s, strictly_proper)
    return A, B, C, D


def _bilinear_centre(w: NDArray[np.float64]) -> float:
    """Centre ``a`` of the bilinear map: the geometric mean of the band edges."""
    pos = w[w > 0]
    if pos.size == 0:
        return 1.0
    return float(np.sqrt(pos.min() * pos.max()))


def _from_unit_circle(
    Ad: NDArray[np.float64], Cd: NDArray[np.float64], a: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Exact inverse of the bilinear map for A and C (method.md 5b)."""
    n = Ad.shape[0]
    eye = np.eye(n)
    inv = np.linalg.inv(eye + Ad)
    A = a * inv @ (Ad - eye)
    C = np.sqrt(2.0 * a) * Cd @ inv
    return A, C


def bilinear_to_continuous(
    Ad: NDArray[np.float64],
    Bd: NDArray[np.float64],
    Cd: NDArray[np.float64],
    Dd: NDArray[np.float64],
    a: float,
) -> tuple[NDArray[np.float64], ...]:
    """Continuous-time model whose ``G(s)`` equals ``Gd((a + s) / (a - s))``.

    Parameters
    ----------
    Ad, Bd, Cd, Dd : ndarray
        Model on the unit circle.
    a : float
        Centre of the bilinear map (rad/s).

    Returns
    -------
    A, B, C, D : ndarray

    """
    A, C = _from_unit_circle(Ad, Cd, a)
    inv = np.linalg.inv(np.eye(Ad.shape[0]) + Ad)
    B = np.sqrt(2.0 * a) * inv @ Bd
    D = Dd - Cd @ inv @ Bd
    return A, B, C, D
