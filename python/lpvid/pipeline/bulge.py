"""A frozen FRF rising between the points far above every measured one: a resonance unseen.

The directions the measured points leave open (:mod:`lpvid.trust.silent`)
let a fit that holds every point within the noise pull a pole toward the
stability boundary between two points, where its resonance rises far above
anything measured while the points see nothing of it. On the synthetic
parametric model measured at three even points (one noise draw of
``benches/bench_plan.py``) every fit of the chosen start's route did so, a
thousand times above the truth at ``p = 0.18``, and agreed with each other
to 3e-4: a committee of one mind, wrong.

**The rule.** A model *bulges* when its frozen FRF's norm (Frobenius over
the data's lines, outputs and inputs) somewhere on the grid over the range
(:func:`lpvid.trust.silent.range_grid`) is more than :data:`BULGE` times
the largest norm of the measured FRFs. Without validation data, a member of
the committee that bulges leaves it, as a misfit does
(:func:`lpvid.pipeline.fewpoints.choose_route`), unless every member
bulges; :func:`lpvid.identify` warns when the model it returns bulges. The
known truths of the benchmarks rise at most 1.18 times above their
neighbouring points' norms; a resonance whose damping dips between two
points to a tenth of its damping at both is what the rule would mistake.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from lpvid.data.frf import FrfData
from lpvid.errors import SingularModelError
from lpvid.model.lpv import LpvModel
from lpvid.trust.silent import range_grid

__all__ = ["BULGE", "Bulge", "bulge"]

#: How many times the largest measured FRF's norm a model's frozen FRF may
#: reach between the points before it counts as a resonance no point sees.
BULGE = 10.0


@dataclass(frozen=True)
class Bulge:
    """How far a model's frozen FRF rises above the measured ones, and where.

    Attributes
    ----------
    ratio : float
        The largest, over the grid, of the frozen FRF's norm over the
        largest measured FRF's norm.
    at : ndarray, shape (Np,)
        The scheduling value where it is largest.
    """

    ratio: float
    at: NDArray[np.float64]

    @property
    def bulges(self) -> bool:
        """Whether the ratio is above :data:`BULGE`."""
        return self.ratio > BULGE

    def describe(self) -> str:
        """The figures in words."""
        where = ", ".join(f"{x:.4g}" for x in self.at)
        return (
            f"its frozen FRF at p = {where} is {self.ratio:.3g} times the largest measured "
            f"(more than {BULGE:g} times: a resonance between the points that no point sees)"
        )


def _norms(model: LpvModel, freqs_hz: NDArray, grid: NDArray) -> NDArray[np.float64]:
    """The frozen FRF's norm at every row of ``grid``; inf where it is singular or overflows."""
    try:
        return np.linalg.norm(model.frf(freqs_hz, grid).reshape(len(grid), -1), axis=1)
    except SingularModelError:
        if len(grid) == 1:
            return np.array([np.inf])
        return np.concatenate([_norms(model, freqs_hz, row[None]) for row in grid])


def bulge(model: LpvModel, data: FrfData) -> Bulge:
    """How far ``model``'s frozen FRF rises above the largest measured FRF (module notes)."""
    grid = range_grid(model, data)
    top = float(np.max(np.linalg.norm(data.G.reshape(data.n_points, -1), axis=1)))
    ratio = _norms(model, data.freqs_hz, grid) / max(top, np.finfo(float).tiny)
    k = int(np.argmax(ratio))
    return Bulge(float(ratio[k]), grid[k].copy())
