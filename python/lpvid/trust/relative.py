"""The relative FRF's sensitivity to theta over a grid of scheduling values.

The part of one frozen FRF at ``p`` is ``Re(J^H J) / ||G_m(p)||^2`` on the
frozen parameters (``J`` the Jacobian of the frozen FRF, ``||.||`` the
Frobenius norm over every line, output and input); it reaches theta
through the coefficient weights ``w = [1, psi(p)]``. Its mean over a grid
is the form ``W`` whose trace against a covariance is the mean relative
FRF variance over the grid (:func:`target`); per grid value, the relative
band (:func:`relative_band`). Used by where to measure next
(:mod:`lpvid.experiment.design`) and by the band's check
(:mod:`lpvid.trust.profile`).
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
from numpy.typing import NDArray

from lpvid.model.lpv import LpvModel
from lpvid.trust.uncertainty import (
    band_radius,
    coefficient_weights,
    frozen_blocks,
    frozen_grams,
)

__all__ = ["GridParts", "chunks", "relative_band", "target"]

#: Entries of the grid's parts kept in memory (200 MB), see :class:`GridParts`.
_KEPT_ENTRIES = 25_000_000
#: Entries per chunk of the algebra over a grid or candidates (memory of one chunk).
_CHUNK_ENTRIES = 2_000_000


def chunks(m: int, per_item: int) -> list[slice]:
    """Slices of ``range(m)`` holding at most about :data:`_CHUNK_ENTRIES` entries each."""
    size = max(1, _CHUNK_ENTRIES // max(per_item, 1))
    return [slice(a, min(a + size, m)) for a in range(0, m, size)]


class GridParts:
    """The criterion's part at every grid value, by chunks: ``Re(J^H J) / ||G_m||^2`` (Q, L, L).

    ``J`` the Jacobian of the frozen FRF on the frozen parameters. Kept in
    memory up to :data:`_KEPT_ENTRIES` entries, recomputed at each use beyond.
    """

    def __init__(self, model: LpvModel, freqs_hz: NDArray, grid: NDArray) -> None:
        self.model, self.freqs_hz, self.grid = model, freqs_hz, grid
        lti = model.theta.size // (model.n_basis + 1)
        self.slices = chunks(len(grid), lti * lti)
        self._kept = None
        if len(grid) * lti * lti <= _KEPT_ENTRIES:
            self._kept = [self._part(sl) for sl in self.slices]

    def _part(self, sl: slice) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        p = self.grid[sl]
        G = self.model.frf(self.freqs_hz, p)
        norm2 = np.sum(np.abs(G) ** 2, axis=(1, 2, 3))
        if np.any(norm2 <= 0):
            at = p[int(np.argmin(norm2))]
            raise ValueError(
                f"result: the model's FRF is zero at p = {', '.join(f'{x:g}' for x in at)}; "
                "its relative band is not defined there"
            )
        weights = np.broadcast_to((1.0 / norm2)[:, None, None, None], G.shape)
        K = frozen_grams(self.model, self.freqs_hz, p, weights)
        return coefficient_weights(self.model, p), K

    def __iter__(self) -> Iterator[tuple[NDArray[np.float64], NDArray[np.float64]]]:
        """``(w, K)`` per chunk: coefficient weights (q, Nb+1) and parts (q, L, L)."""
        if self._kept is not None:
            yield from self._kept
        else:
            for sl in self.slices:
                yield self._part(sl)


def target(parts: GridParts, index: NDArray) -> NDArray[np.float64]:
    """The form ``W`` (P, P) of the criterion: the mean of the parts over the grid, on theta."""
    k1, lti = index.shape
    blocks = np.zeros((k1, lti, k1, lti))
    for w, K in parts:
        blocks += np.einsum("qi,quv,qj->iujv", w, K, w, optimize=True)
    P = parts.model.theta.size
    W = np.zeros((P, P))
    W[index[:, :, None, None], index[None, None, :, :]] = blocks / len(parts.grid)
    return W


def relative_band(C: NDArray, parts: GridParts, index: NDArray) -> NDArray[np.float64]:
    """``band_radius(0.95) * sqrt(E||dG||^2) / ||G_m||`` at the grid values, for covariance C."""
    out = []
    for w, K in parts:
        out.append(np.sum(frozen_blocks(C, index, w) * K, axis=(1, 2)))
    return band_radius(0.95) * np.sqrt(np.maximum(np.concatenate(out), 0.0))
