"""Standard deviations of measured FRFs from what analyzers record.

lpvid's sigma is the standard deviation of the complex FRF estimate,
``sigma^2 = E|G_hat - G|^2`` (the sum of the variances of its real and
imaginary parts), so that V_NLS at the true system is about the number of
complex residuals.

From coherence (Bendat and Piersol, *Random Data*, the random error of the
H1 estimate from n averages): the magnitude and the phase (in radians,
relative to |G|) of the estimate each have the variance

    var(|G_hat|) = |G|^2 (1 - gamma^2) / (2 n gamma^2)

with gamma^2 the (magnitude-squared) coherence at the line. The error is
circular, so the complex variance is twice that:

    sigma^2 = E|G_hat - G|^2 = |G|^2 (1 - gamma^2) / (n gamma^2).

It is exact for an input without noise and n averages of one experiment
(then ``(1 - gamma^2) / gamma^2`` is the noise-to-signal power ratio of the
output), and a first-order approximation otherwise; it needs enough
averages (say n >= 10) for the estimated coherence to be near the true one.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lpvid._checks import positive_int

__all__ = ["sigma_from_coherence", "sigma_from_variance", "sigma_relative"]


def sigma_from_coherence(
    G: ArrayLike, coherence: ArrayLike, averages: int, *, where: str = "coherence"
) -> NDArray[np.float64]:
    """Standard deviation of an H1 FRF estimate from its coherence.

    ``sigma = |G| sqrt((1 - gamma^2) / (n gamma^2))``, the square root of
    ``E|G_hat - G|^2`` (twice the variance of the magnitude that Bendat and
    Piersol give, since the error is circular).

    Parameters
    ----------
    G : array_like
        FRF estimates (complex).
    coherence : array_like
        Magnitude-squared coherence gamma^2 of each estimate, in (0, 1);
        broadcast against ``G``.
    averages : int
        Number of averages n the estimates were computed from (>= 2).
    where : str
        What to name in errors (a file and record).

    Returns
    -------
    ndarray of float
        sigma, the shape of ``G``.

    Raises
    ------
    ValueError
        When a coherence is not in (0, 1) (1 means no noise at all and gives
        no sigma; 0 no signal) or an FRF value is 0.

    Examples
    --------
    ``|G| = 2``, ``gamma^2 = 0.8``, 20 averages: ``sigma = 2 sqrt(0.2 / (20 * 0.8))``.

    >>> from lpvid.readers import sigma_from_coherence
    >>> float(sigma_from_coherence(2.0, 0.8, 20).round(6))
    0.223607

    """
    n = positive_int(averages, "averages", minimum=2)
    g = np.asarray(G)
    coh = np.asarray(coherence, dtype=np.float64)
    bad = ~((coh > 0) & (coh < 1))
    if np.any(bad):
        k = int(np.flatnonzero(bad.ravel())[0])
        raise ValueError(
            f"{where}: coherence must lie in (0, 1); found {coh.ravel()[k]:g} at {_at(coh, k)} "
            "(1 means no noise and gives no sigma: take sigma from a variance or a relative level)"
        )
    sigma = np.abs(g) * np.sqrt((1.0 - coh) / (n * coh))
    _positive(sigma, g, where)
    return sigma


def sigma_from_variance(variance: ArrayLike, *, where: str = "variance") -> NDArray[np.float64]:
    """Standard deviation ``sqrt(variance)`` of an FRF from its variance ``E|dG|^2`` (> 0)."""
    var = np.asarray(variance, dtype=np.float64)
    bad = ~(var > 0)
    if np.any(bad):
        k = int(np.flatnonzero(bad.ravel())[0])
        raise ValueError(
            f"{where}: variance must be > 0; found {var.ravel()[k]:g} at {_at(var, k)}"
        )
    return np.sqrt(var)


def sigma_relative(G: ArrayLike, level: float, *, where: str = "G") -> NDArray[np.float64]:
    """Standard deviation ``level * |G|``: a constant relative noise level."""
    g = np.asarray(G)
    sigma = float(level) * np.abs(g)
    _positive(sigma, g, where)
    return sigma


def _at(arr: np.ndarray, k: int) -> str:
    """Where the flat index k is: a line of a record, or an index of an array."""
    if arr.ndim <= 1:
        return f"line {k + 1}"
    return f"index {tuple(int(i) for i in np.unravel_index(k, arr.shape))}"


def _positive(sigma: np.ndarray, g: np.ndarray, where: str) -> None:
    zero = ~(sigma > 0)
    if np.any(zero):
        k = int(np.flatnonzero(zero.ravel())[0])
        g = np.broadcast_to(g, sigma.shape)
        raise ValueError(
            f"{where}: the FRF is {g.ravel()[k]} at {_at(sigma, k)}, which gives sigma 0 "
            "(a relative or coherence-based sigma needs |G| > 0)"
        )
