"""The parameter covariance of a fitted model and what follows from it: FRF and pole spread.

First order, weighted by sigma: near the minimum of ``V_NLS = r^T r`` the
estimate scatters with ``Cov(theta) = (J^T J)^+ / 2``, since each real
residual (the real or the imaginary part of ``(G - Gm) / sigma``) has
variance 1/2 when sigma is the standard deviation of the complex error.

A realisation is only defined up to a state transformation, so ``J^T J``
is singular along the similarity directions
(:func:`lpvid.model.similarity.free_similarity_directions`). The pseudo-inverse is
taken on their orthogonal complement (within the free parameters): the
covariance describes the spread of the minimum-norm representative, and
every quantity a transformation leaves alone (the frequency response, the
poles) gets the same variance whichever representative is chosen.

**Rank rule.** On that complement, ``J^T J`` (Jacobi-scaled to a unit
diagonal) is inverted on its eigenvalues above ``k * eps`` times the largest
(``k`` the dimension, ``eps`` the machine precision: numpy's rule for a
numerically singular matrix); poorly determined directions are kept, since
they are what the uncertainty is meant to show. Directions below the
cut-off (a basis function that the points cannot determine, a mode that the
data do not excite) are left out with a warning: quantities that depend on
them are then more uncertain than the figures say. ``rank`` is the number
of directions kept.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lpvid import _core
from lpvid._checks import positive_float, real_array
from lpvid._problemlike import from_problem
from lpvid._spread import product
from lpvid._threads import single_blas
from lpvid.data.frf import FrfData, z_points
from lpvid.errors import ConvergenceWarning
from lpvid.fit.cost import gauss_newton
from lpvid.fit.memory import check_covariance
from lpvid.model._view import model_view
from lpvid.model.layout import MATRICES, fixed_mask
from lpvid.model.lpv import LpvModel
from lpvid.model.similarity import complement_basis, free_similarity_directions

__all__ = ["Covariance", "covariance", "band_radius", "frozen_grams"]

#: Rows of the LTI Jacobian per call to the core when propagating to the FRF.
_CHUNK_ROWS = 200_000
#: Complex Jacobian entries per call to the core in :func:`frozen_grams` (8 MB:
#: each chunk is copied about four times on its way to the Gram matrices).
_CHUNK_ENTRIES = 500_000


def band_radius(level: float = 0.95) -> float:
    """Radius, in standard deviations, of a circular band with coverage ``level``.

    For a circular complex Gaussian error with ``E|dG|^2 = sigma^2``,
    ``|dG|^2 / sigma^2`` is exponential with mean 1, so
    ``P(|dG| <= k sigma) = 1 - exp(-k^2)`` and ``k = sqrt(-ln(1 - level))``
    (``sqrt(ln 20) = 1.73`` for 95 %).

    Examples
    --------
    >>> round(band_radius(0.95), 4)
    1.7308

    """
    lv = positive_float(level, "level")
    if not lv < 1.0:
        raise ValueError(f"level: expected a probability in (0, 1), got {level}")
    return float(np.sqrt(-np.log1p(-lv)))


@dataclass(frozen=True, eq=False)
class Covariance:
    """First-order covariance of the parameters of a fitted model (see the module notes).

    Attributes
    ----------
    model : LpvModel
        The model at which it was computed (near a minimum of V_NLS).
    theta : ndarray, shape (P, P)
        Covariance of ``model.theta`` on the identifiable directions: zero
        rows and columns for fixed parameters, singular along the similarity
        directions.
    rank : int
        Number of identifiable directions kept.
    n_free : int
        Number of free parameters.
    n_similarity : int
        Similarity directions left out (``n^2`` when no fixed parameter
        restricts the transformations).
    n_unidentified : int
        Further directions left out by the rank rule (0 when all is well).
    factor : float
        Scale applied to ``(J^T J)^+ / 2``: 1, or the noise estimate of
        ``covariance(..., scale=True)``.
    vnls, noise_floor : float, int
        V_NLS of the model on the data and its noise floor.
    free : ndarray of bool, shape (P,)
        The parameters that were free (neither fixed nor held).
    """

    model: LpvModel
    theta: NDArray[np.float64]
    rank: int
    n_free: int
    n_similarity: int
    n_unidentified: int
    factor: float
    vnls: float
    noise_floor: int
    free: NDArray[np.bool_] = field(repr=False)
    _index: NDArray[np.int_] = field(repr=False)

    @property
    def std(self) -> NDArray[np.float64]:
        """Standard deviation of every entry of ``model.theta`` (0 where fixed)."""
        return np.sqrt(np.maximum(np.diag(self.theta), 0.0))

    @single_blas
    def lti_covariance(self, p: ArrayLike) -> NDArray[np.float64]:
        """Covariance of the frozen LTI parameters ``[vec A; vec B; vec C; vec D]`` at ``p``.

        Parameters
        ----------
        p : array_like, shape (M,) or (M, Np)
            Scheduling values (a scalar is one value).

        Returns
        -------
        ndarray, shape (M, L, L)
            ``L`` the number of parameters of one frozen model.
        """
        return frozen_blocks(self.theta, self._index, coefficient_weights(self.model, p))

    @single_blas
    def frf_std(self, freqs_hz: ArrayLike, p: ArrayLike) -> NDArray[np.float64]:
        """Standard deviation of the model FRF at any frequencies and scheduling values.

        ``sigma^2 = E|dG|^2`` with ``dG = J_G dtheta`` to first order, so a
        circular band of radius :func:`band_radius` ``(0.95) * sigma =
        sqrt(ln 20) sigma`` around ``model.frf`` covers the true FRF with
        probability about 95 % (exactly so for a circular Gaussian error).

        Parameters
        ----------
        freqs_hz : array_like, shape (F,)
            Frequencies in Hz.
        p : array_like, shape (M,) or (M, Np)
            Scheduling values.

        Returns
        -------
        ndarray, shape (M, F, l, r)
            The shape of ``model.frf(freqs_hz, p)``.

        Raises
        ------
        SingularModelError
            When a frozen model has a pole exactly at an evaluation point.
        """
        m = self.model
        f = real_array(freqs_hz, "freqs_hz", ndim=(0, 1)).ravel()
        psi = m.basis_values(p)
        n, r, l, nb = m.shape
        n_p = psi.shape[0]
        cov = self.lti_covariance(p)
        lti = cov.shape[-1]
        z = z_points(f, m.Ts)
        per_point = max(f.size * l * r * lti, 1)
        chunk = max(1, _CHUNK_ROWS * 8 // per_point)
        out = np.empty((n_p, f.size, l, r))
        for first in range(0, n_p, chunk):
            sl = slice(first, min(first + chunk, n_p))
            k = sl.stop - sl.start
            jac = _core.lti_jacobian(model_view(m, psi[sl]), z)
            jac = jac.reshape(k, f.size * l * r, lti)
            var = np.einsum("mau,mau->ma", jac @ cov[sl], jac.conj()).real
            out[sl] = np.sqrt(np.maximum(var, 0.0)).reshape(k, f.size, l, r)
        return out

    def frf_band(self, freqs_hz: ArrayLike, p: ArrayLike, level: float = 0.95) -> NDArray:
        """Radius of the circular band around ``model.frf`` with coverage ``level``.

        ``band_radius(level) * frf_std(freqs_hz, p)``, shape ``(M, F, l, r)``.
        """
        return band_radius(level) * self.frf_std(freqs_hz, p)

    @single_blas
    def pole_std(
        self, p: ArrayLike, *, return_poles: bool = False
    ) -> NDArray[np.float64] | tuple[NDArray[np.complex128], NDArray[np.float64]]:
        """Standard deviation of every pole of the frozen model at one scheduling value.

        ``sigma_i^2 = E|d lambda_i|^2`` from the first-order sensitivity
        ``d lambda_i / d A_ab = W_ia V_bi`` (``V`` the right eigenvectors of
        ``A(p)``, ``W = V^-1``), in the units of the poles (``z`` in
        discrete time, ``s`` in rad/s in continuous time). A multiple pole
        with a defective eigenvector basis has no derivative: the figure
        is then huge.

        Parameters
        ----------
        p : float or array_like of shape (Np,)
            One scheduling value.
        return_poles : bool
            Also return the poles, in the same order.

        Returns
        -------
        ndarray, shape (n,)
            In the order of ``numpy.linalg.eig(A(p))`` (the order of
            :meth:`lpvid.LpvModel.poles` in practice); with ``return_poles``,
            ``(poles, std)``.
        """
        A = self.model.at(p)[0]
        n = A.shape[0]
        lam, V = np.linalg.eig(A)
        W = np.linalg.inv(V)
        cov = self.lti_covariance(p)[0][: n * n, : n * n]
        # Entry a + b n of vec A is A[a, b].
        g = np.einsum("ia,bi->iba", W, V).reshape(n, n * n)
        var = np.einsum("iu,uv,iv->i", g, cov, g.conj()).real
        std = np.sqrt(np.maximum(var, 0.0))
        return (lam, std) if return_poles else std

    def __repr__(self) -> str:
        return (
            f"Covariance(rank={self.rank} of {self.n_free} free parameters, "
            f"{self.n_similarity} similarity directions, "
            f"{self.n_unidentified} unidentified)"
        )


def coefficient_weights(model: LpvModel, p: ArrayLike) -> NDArray[np.float64]:
    """``[1, psi_1(p), ..., psi_Nb(p)]`` at every point: shape (M, Nb+1).

    The frozen parameter ``u`` at ``p`` is ``sum_i w_i theta[index[i, u]]``
    (``index`` from :func:`_lti_index`).
    """
    psi = model.basis_values(p)
    return np.concatenate([np.ones((psi.shape[0], 1)), psi], axis=1)


def frozen_blocks(
    matrix: NDArray[np.float64], index: NDArray[np.int_], w: NDArray[np.float64]
) -> NDArray[np.float64]:
    """A (P, P) form on theta seen on the frozen parameters at every point: (M, L, L).

    ``sum_ij w[m, i] w[m, j] matrix[index[i, u], index[j, v]]``: for a
    covariance of theta, the covariance of the frozen parameters at the
    points whose coefficient weights are ``w``.
    """
    blocks = matrix[index[:, :, None, None], index[None, None, :, :]]
    return np.einsum("mi,iujv,mj->muv", w, blocks, w, optimize=True)


def frozen_grams(
    model: LpvModel, freqs_hz: NDArray[np.float64], p: NDArray[np.float64], weights: NDArray
) -> NDArray[np.float64]:
    """``Re(J^H diag(weights) J)`` of the frozen parameters at every point: (M, L, L).

    ``J`` is the Jacobian of the frozen FRF (every line, output and input,
    in the order of ``model.frf``) with respect to the frozen model's
    parameters ``[vec A; vec B; vec C; vec D]``; ``weights`` (M, F, l, r)
    weight its rows (``1 / sigma^2`` gives the information one measurement
    adds, as in :func:`lpvid.fit.cost.gauss_newton`).
    """
    n, r, l, nb = model.shape
    psi = model.basis_values(p)
    z = z_points(freqs_hz, model.Ts)
    rows = freqs_hz.size * l * r
    lti = n * n + n * r + l * n + l * r
    chunk = max(1, _CHUNK_ENTRIES // max(rows * lti, 1))
    m = psi.shape[0]
    out = np.empty((m, lti, lti))
    wt = weights.reshape(m, rows)
    for first in range(0, m, chunk):
        sl = slice(first, min(first + chunk, m))
        k = sl.stop - sl.start
        jac = _core.lti_jacobian(model_view(model, psi[sl]), z)
        x = jac.reshape(k, rows, lti) * np.sqrt(wt[sl])[:, :, None]
        x = np.concatenate([x.real, x.imag], axis=1)
        out[sl] = x.transpose(0, 2, 1) @ x
    return 0.5 * (out + out.transpose(0, 2, 1))


def _lti_index(model: LpvModel) -> NDArray[np.int_]:
    """Index in theta of LTI parameter ``u`` of coefficient ``i``: shape (Nb+1, L)."""
    k = model.n_basis + 1
    rows = []
    start = 0
    per_x = []
    for x in MATRICES:
        size = getattr(model, x)[0].size
        per_x.append((start, size))
        start += k * size
    for i in range(k):
        rows.append(
            np.concatenate([np.arange(s + i * size, s + (i + 1) * size) for s, size in per_x])
        )
    return np.array(rows)


def projected(H: NDArray[np.float64], Z: NDArray[np.float64]) -> NDArray[np.float64]:
    """``Z^T H Z`` as ``(Z^T H) Z``, large products side by side (:func:`lpvid._spread.product`)."""
    return product(product(Z.T, H), Z)


def pseudo_inverse(
    jtj: NDArray[np.float64], T: NDArray[np.float64]
) -> tuple[NDArray[np.float64], int, int, int]:
    """``(J^T J)^+`` on the orthogonal complement of the columns of ``T`` (module notes).

    Returns the pseudo-inverse, its rank, the dimension of ``span(T)`` and
    the number of further directions the rank rule left out.
    """
    Z, k = complement_basis(T)
    M = projected(jtj, Z)
    M = 0.5 * (M + M.T)
    d = np.sqrt(np.maximum(np.diag(M), 1e-300))
    lam, V = np.linalg.eigh(M / d[:, None] / d[None, :])
    top = float(lam[-1]) if lam.size else 0.0
    keep = lam > max(M.shape[0], 1) * np.finfo(float).eps * top
    # Z Vk diag(1/lam) Vk^T Z^T as W W^T: one product and a symmetric one
    # (n = 32 4x4's 3600 free parameters: 0.6 s against 1.4 s for the four
    # products one after the other).
    W = product(Z, V[:, keep] / d[:, None] / np.sqrt(lam[keep]))
    inv = W @ W.T
    return 0.5 * (inv + inv.T), int(keep.sum()), k, int((~keep).sum())


@single_blas
def covariance(
    model: LpvModel,
    data: FrfData,
    fixed: Any = None,
    *,
    scale: bool = False,
    warn: bool = True,
) -> Covariance:
    """First-order parameter covariance of a fitted model: ``(J^T J)^+ / 2`` (module notes).

    Valid near a minimum of V_NLS with the right sigma (the model fits the
    data at about the noise floor). For a model from the l2,1 fit, refit
    first with the dropped groups fixed at zero (:func:`lpvid.refit` does
    both): the penalty shrinks the estimate, and the first-order covariance
    describes the unpenalised fit.

    Parameters
    ----------
    model : LpvModel
        The fitted model.
    data : FrfData or Problem
        The data it was fitted to; or a :class:`lpvid.Problem`, whose data
        and ``fixed`` are then used (``fixed`` must not be given beside it).
    fixed : optional
        Parameters that were kept fixed (as in :func:`lpvid.fixed_mask`):
        they have no spread.
    scale : bool
        Multiply by the noise estimate ``V_NLS / (M - rank / 2)`` (``M`` the
        noise floor), for data whose sigma is only known up to a factor.
        Default False: sigma is taken as right.
    warn : bool
        Warn (:class:`lpvid.ConvergenceWarning`) when the rank rule leaves out
        directions besides the similarity transforms.

    Returns
    -------
    Covariance

    Examples
    --------
    >>> import numpy as np, lpvid
    >>> m = lpvid.LpvModel([[[0.5]]], [[[1.0]]], [[[1.0]]], Ts=1.0)
    >>> f = np.linspace(0.01, 0.4, 20)
    >>> data = lpvid.FrfData([0.0], f, m.frf(f, [0.0]), sigma=0.01, Ts=1.0)
    >>> cov = lpvid.covariance(m, data)
    >>> cov.rank  # 4 parameters, one similarity direction (the state scale)
    3

    """
    data, given = from_problem(data, fixed=fixed)
    fixed = given["fixed"]
    free = ~fixed_mask(model, fixed)
    check_covariance(model, data, free)
    v, _, jtj = gauss_newton(model, data, fixed)
    T = free_similarity_directions(model, free)
    inv, rank, n_sim, dropped = pseudo_inverse(jtj, T)
    if dropped and warn:
        warnings.warn(
            f"covariance: J^T J is singular along {dropped} direction(s) besides the "
            "similarity transforms: changes of the model that leave the FRF at every "
            "identification point unchanged (e.g. transformations that differ from point to "
            "point when the basis has about as many functions as there are points, or a mode "
            "the data do not excite); they are left out, and the band of quantities that "
            "depend on them (the FRF between the points) may be too narrow",
            ConvergenceWarning,
            stacklevel=2,
        )
    floor = data.n_residuals
    factor = 1.0
    if scale:
        factor = float(v / max(floor - rank / 2.0, 1.0))
    P = model.theta.size
    full = np.zeros((P, P))
    full[np.ix_(free, free)] = 0.5 * factor * inv
    return Covariance(
        model=model,
        theta=full,
        rank=rank,
        n_free=int(free.sum()),
        n_similarity=n_sim,
        n_unidentified=dropped,
        factor=factor,
        vnls=float(v),
        noise_floor=floor,
        free=free,
        _index=_lti_index(model),
    )
