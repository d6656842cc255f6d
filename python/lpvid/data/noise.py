"""lpvid's noise model: circular complex Gaussian noise of a given standard deviation."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["circular_noise"]


def circular_noise(sigma: NDArray[np.float64], rng: np.random.Generator) -> NDArray[np.complex128]:
    """Circular complex Gaussian noise of standard deviation ``sigma``, entry by entry.

    lpvid's noise model: ``E|e|^2 = sigma^2``, real and imaginary parts
    independent with variance ``sigma^2 / 2`` each, so that V_NLS of the
    true model has mean ``M``, the number of complex residuals (the noise
    floor). The real parts are drawn first, then the imaginary ones.
    """
    shape = np.shape(sigma)
    return sigma * (rng.normal(size=shape) + 1j * rng.normal(size=shape)) / np.sqrt(2)
