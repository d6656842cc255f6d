"""Hints at the model order from the subspace singular values of the local data."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from lpvid._checks import positive_int
from lpvid._threads import single_blas
from lpvid.data.frf import FrfData
from lpvid.initial.subspace import max_order, singular_values

__all__ = ["OrderHints", "order_hints"]

#: Most block rows of the subspace step used for the hints.
MAX_ROWS = 20

#: Smallest mean drop (decades) of the singular values that makes an order a hint.
MIN_DROP = 0.1

#: Singular values below this many times the largest of pure noise count as noise
#: (the weighting by sigma is approximate and the noise's singular values come in
#: pairs: measured up to 1.6 times the bound on noise alone).
NOISE_LEVEL = 2.0


@dataclass
class OrderHints:
    """The orders the subspace singular values of the local data point at.

    Attributes
    ----------
    orders : list of int
        Candidate orders, strongest first: the orders ``n`` after which the
        singular values drop most (largest mean ``log10(s[n-1] / s[n])``
        over the scheduling points, each singular value counted at least at
        :data:`NOISE_LEVEL`), at most ``count`` of them with a drop of at
        least :data:`MIN_DROP` decades (empty when the data show no drop
        above the noise).
    gaps : ndarray, shape (n_max,)
        That mean drop in decades for the orders ``1..n_max``.
    singular_values : ndarray, shape (N, q l)
        The singular values at every scheduling point in units of the
        largest singular value of pure noise of the data's sigma (values
        below 1 are indistinguishable from noise).
    n_rows : int
        Block rows q of the subspace step.
    """

    orders: list[int]
    gaps: NDArray[np.float64]
    singular_values: NDArray[np.float64]
    n_rows: int

    def __str__(self) -> str:
        if not self.orders:
            return "order hints: none (the subspace singular values show no drop above the noise)"
        parts = [f"{n} ({self.gaps[n - 1]:.2f} decades)" for n in self.orders]
        return "order hints (drop of the subspace singular values): " + ", ".join(parts)


@single_blas
def order_hints(data: FrfData, *, count: int = 3, n_rows: int | None = None) -> OrderHints:
    """Candidate model orders from the singular values of the subspace step at every point.

    At every scheduling point the frequency-domain subspace step
    (:func:`lpvid.fd_subspace`, McKelvey et al. 1996) projects the weighted
    FRF onto a matrix whose rank is the order of the system; with noise, the
    singular values beyond the order fall to the noise level (known from
    sigma, the data's weights). The orders after which they drop most,
    averaged over the points in decades, are returned strongest first. A
    hint, not a choice: close or weak modes and heavy noise blur the drop
    (:func:`lpvid.select` tries the orders).

    Parameters
    ----------
    data : FrfData
        FRFs at the scheduling points.
    count : int
        How many candidate orders to return.
    n_rows : int, optional
        Block rows q of the subspace step; default ``min(20, 2 F r / (l + r))``
        so that all ``q l`` singular values are determined by the data.

    Returns
    -------
    OrderHints

    Raises
    ------
    ValueError, TypeError
        When ``data`` is not an FrfData or ``count``/``n_rows`` are not
        positive integers (``n_rows`` at least 2 and within the data).

    Examples
    --------
    >>> import lpvid
    >>> hints = lpvid.order_hints(lpvid.datasets.gantry().identification)
    >>> hints.orders[0]
    6

    """
    if not isinstance(data, FrfData):
        raise TypeError(f"data: expected an FrfData, got {type(data).__name__}")
    k = positive_int(count, "count")
    F, l, r = data.n_lines, data.n_outputs, data.n_inputs
    if n_rows is None:
        q = max(2, min(MAX_ROWS, (2 * F * r) // (l + r)))
    else:
        q = positive_int(n_rows, "n_rows", minimum=2)
    s = np.array(
        [
            singular_values(data.freqs_hz, data.G[i], data.sigma[i], data.Ts, n_rows=q)
            for i in range(data.n_points)
        ]
    )
    # Pure noise of unit variance per weighted entry: singular values of about
    # sqrt(F r - q r / 2) (1 + sqrt(q l / (2 F r - q r))) at most.
    edge = np.sqrt(F * r - q * r / 2) * (1 + np.sqrt(q * l / max(2 * F * r - q * r, 1)))
    s = s / edge
    n_max = max(1, min(q * l - 1, max_order(F, l, r)))
    clipped = np.log10(np.maximum(s, NOISE_LEVEL))
    gaps = (clipped[:, :n_max] - clipped[:, 1 : n_max + 1]).mean(axis=0)
    ranked = [int(i) + 1 for i in np.argsort(-gaps, kind="stable") if gaps[i] >= MIN_DROP]
    orders = ranked[:k]
    return OrderHints(orders=orders, gaps=gaps, singular_values=s, n_rows=q)
