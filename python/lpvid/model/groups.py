"""Group magnitudes of an LPV model: the paper's Tables 1-4 (method.md (23), (26))."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from lpvid.model._protocol import ModelLike
from lpvid.model.layout import MATRICES

__all__ = ["GroupNorms", "group_norms"]


@dataclass(frozen=True)
class GroupNorms:
    """Magnitudes of the groups ``theta_X(i)``, ``i = 1..Nb``.

    Attributes
    ----------
    absolute : ndarray, shape (4, Nb)
        ``||theta_X(i)||_2`` for X = A, B, C, D (rows).
    relative : ndarray, shape (4, Nb)
        ``||theta_X(i)|| ||psi_i||_inf / ||theta_X(0)||``: the contribution
        of the group relative to the constant part (the paper's right-hand
        tables). When ``theta_X(0) = 0`` the division is dropped.
    constant : ndarray, shape (4,)
        ``||theta_X(0)||_2``.
    names : list of str
        Basis function names.

    """

    absolute: NDArray[np.float64]
    relative: NDArray[np.float64]
    constant: NDArray[np.float64]
    names: list[str]

    def nonzero(self, threshold: float = 1e-6) -> dict[str, list[int]]:
        """Basis indices ``i`` (1-based) with relative magnitude above ``threshold``, per matrix."""
        return {
            x: [int(i) + 1 for i in np.flatnonzero(self.relative[k] > threshold)]
            for k, x in enumerate(MATRICES)
        }

    def count(self, threshold: float = 1e-6) -> int:
        """Number of groups whose relative magnitude exceeds ``threshold``."""
        return int(np.sum(self.relative > threshold))

    def dependence(self) -> float:
        """The sum of the relative magnitudes: how strongly the model depends on the scheduling.

        The convex surrogate of :meth:`count` that the l2,1 penalty with the
        weights (23) and the scale (25) measures; 0 for an LTI model. Among
        models that fit the data equally well, the one with the smaller
        dependence is the simpler (see :mod:`lpvid.fit.judge`).
        """
        return float(self.relative.sum())

    def table(self) -> str:
        """The paper-style table: absolute norms left, relative magnitudes right."""
        nb = len(self.names)
        head_l = ["i"] + [f"|th_{x}(i)|" for x in MATRICES]
        head_r = [f"rel {x}" for x in MATRICES]
        rows = []
        for i in range(nb):
            rows.append(
                [f"{i + 1} ({self.names[i]})"]
                + [f"{v:.3e}" for v in self.absolute[:, i]]
                + [f"{v:.3e}" for v in self.relative[:, i]]
            )
        header = head_l + head_r
        # The constant's row has no relative magnitudes (they are relative to it).
        const = ["0 (const)"] + [f"{v:.3e}" for v in self.constant]
        widths = [
            max([len(h), *(len(r[c]) for r in [const, *rows] if c < len(r))])
            for c, h in enumerate(header)
        ]

        def joined(cells: list[str]) -> str:
            return "  ".join(v.rjust(w) for v, w in zip(cells, widths, strict=False))

        return "\n".join([joined(header), joined(const), *(joined(r) for r in rows)])

    def __str__(self) -> str:
        return self.table()


def group_norms(model: ModelLike, p_range: Any = None) -> GroupNorms:
    """Compute :class:`GroupNorms` of a model; see :meth:`LpvModel.group_norms`."""
    rng = model.p_range if p_range is None else p_range
    nb = model.n_basis
    if nb and rng is None:
        raise ValueError(
            "p_range: the model has no scheduling range; pass p_range=(lo, hi) "
            "or build the basis with a domain"
        )
    sup = model.basis.sup_norms(rng) if nb else np.zeros(0)
    absolute = np.zeros((4, nb))
    constant = np.zeros(4)
    for k, x in enumerate(model.matrices().values()):
        constant[k] = np.linalg.norm(x[0])
        absolute[k] = [np.linalg.norm(x[i]) for i in range(1, nb + 1)]
    relative = absolute * sup[None, :]
    scale = np.where(constant > 0, constant, 1.0)
    relative = relative / scale[:, None]
    return GroupNorms(absolute, relative, constant, model.basis.names)
