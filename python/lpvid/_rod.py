"""The finite-difference heat rod of :func:`lpvid.testing.diffusion_rod` (numpy only).

Here rather than in ``lpvid/testing.py``, which re-exports it, to keep that
file within the house's 500 lines.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from lpvid._checks import positive_int, real_array
from lpvid.data.basis import Polynomial
from lpvid.model.lpv import LpvModel

__all__ = ["diffusion_rod", "rod_matrices"]


def rod_matrices(
    n: int, split: float, output_at: float
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """``A0``, ``A1``, ``B``, ``C`` of the rod ``dT/dt = (A0 + k A1) T + B q``, ``y = C T``.

    The rod ``[0, 1]`` is cut into ``n`` cells of width ``h = 1 / n`` with
    unit heat capacity; ``T[i]`` is the temperature of cell ``i`` (centre
    ``(i + 1/2) h``). Between neighbouring cells flows ``kappa (T[i] -
    T[i+1]) / h``, ``kappa = 1`` at interfaces left of ``split`` and ``k``
    at or right of it; the right end is held at temperature 0, half a cell
    beyond the last centre (conductance ``2 kappa / h``); the heat flux
    ``q`` enters cell 0 (``B = e_0 / h``); ``y`` is the temperature of the
    cell that holds ``output_at``.
    """
    h = 1.0 / n
    A0, A1 = np.zeros((n, n)), np.zeros((n, n))
    for i in range(n - 1):
        M = A1 if (i + 1) * h >= split else A0
        M[i, i] -= 1.0
        M[i + 1, i + 1] -= 1.0
        M[i, i + 1] += 1.0
        M[i + 1, i] += 1.0
    (A1 if split < 1.0 else A0)[n - 1, n - 1] -= 2.0
    B = np.zeros((n, 1))
    B[0, 0] = 1.0 / h
    C = np.zeros((1, n))
    C[0, min(int(output_at / h), n - 1)] = 1.0
    return A0 / h**2, A1 / h**2, B, C


def diffusion_rod(
    n: int = 101, k_range: tuple[float, float] = (0.1, 10.0), output_at: float = 0.25
) -> LpvModel:
    """A heat rod of ``n`` states whose conductivity on its far half is the scheduling ``k``.

    A 1-D diffusion by finite differences (continuous time, one input, one
    output): the rod ``[0, 1]`` in ``n`` cells of unit heat capacity,
    conductivity 1 on ``[0, 0.5)`` and ``k`` on ``[0.5, 1]``, the heat flux
    entering at ``x = 0`` (the input), the temperature held at 0 at
    ``x = 1``, the output the temperature at ``x = output_at`` (the
    discretisation: :func:`rod_matrices`). ``A(k)`` is affine in ``k``, so
    the model is exact over ``Polynomial(1, domain=k_range)`` with one
    group, ``A(1)``; but its DC gain, about ``0.5 - output_at + 0.5 / k``,
    and its slowest pole (0.29 rad/s at ``k = 0.1``, 2.5 at 1, 8.1 at 10)
    move evenly in ``log10(k)``, not in ``k``: a reduced model of a few
    states follows ``k`` at a low degree on the log scale.

    Parameters
    ----------
    n : int
        Number of cells (states), at least 4.
    k_range : (lo, hi)
        Range of ``k`` (the basis domain), above zero.
    output_at : float
        Where the temperature is measured, in [0, 1).

    Returns
    -------
    LpvModel

    Examples
    --------
    >>> import lpvid.testing
    >>> m = lpvid.testing.diffusion_rod(101)
    >>> m.n_states, round(float(m.frf([0.0], [1.0])[0, 0, 0, 0].real), 2)
    (101, 0.75)

    """
    n = positive_int(n, "n", minimum=4)
    pair = real_array(k_range, "k_range", ndim=1)
    if pair.size != 2 or not 0 < pair[0] < pair[1]:
        raise ValueError(f"k_range: expected (lo, hi) with 0 < lo < hi, got {k_range!r}")
    at = float(real_array(output_at, "output_at", ndim=0))
    if not 0 <= at < 1:
        raise ValueError(f"output_at: expected a place in [0, 1), got {output_at!r}")
    A0, A1, B, C = rod_matrices(n, 0.5, at)
    lo, hi = float(pair[0]), float(pair[1])
    mid, half = (lo + hi) / 2, (hi - lo) / 2  # k = mid + half s
    A = np.stack([A0 + mid * A1, half * A1])
    basis = Polynomial(1, domain=(lo, hi))
    return LpvModel(A, np.stack([B, 0 * B]), np.stack([C, 0 * C]), np.zeros((2, 1, 1)), basis)
