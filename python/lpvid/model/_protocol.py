"""What the helpers of :class:`lpvid.LpvModel` read from a model (private).

The bodies of some of the model's methods live in their own modules
(simulation, group norms, parameter masks, model files, frozen models, the
hand-off to python-control), and :class:`~lpvid.LpvModel` imports them.
They take the model as an argument; to name its type without importing
:mod:`lpvid.model.lpv` (which would tie the two modules both ways) they name
:class:`ModelLike`, the part of the model they use. :class:`~lpvid.LpvModel`
has all of it, so every ``LpvModel`` is a ``ModelLike``.
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lpvid.data.basis import Basis

__all__ = ["ModelLike"]


class ModelLike(Protocol):
    """The attributes and methods of :class:`lpvid.LpvModel` its helpers use.

    Attributes
    ----------
    A, B, C, D : ndarray, shape (Nb+1, ., .)
        Coefficient matrices of the model (method.md (2)).
    basis : Basis
        Scheduling basis functions ``psi_1..psi_Nb``.
    Ts : float or None
        Sample time (None: continuous time).
    p_range : list or None
        Scheduling range the model was identified on.
    info : dict
        Free-form notes.
    """

    A: NDArray[np.float64]
    B: NDArray[np.float64]
    C: NDArray[np.float64]
    D: NDArray[np.float64]
    basis: Basis
    Ts: float | None
    p_range: Any
    info: dict[str, Any]

    @property
    def n_basis(self) -> int:
        """Number of basis functions Nb."""
        ...

    @property
    def shape(self) -> tuple[int, int, int, int]:
        """``(n, r, l, Nb)``."""
        ...

    @property
    def theta(self) -> NDArray[np.float64]:
        """Flat parameter vector ``[theta_A; theta_B; theta_C; theta_D]``."""
        ...

    def matrices(self) -> dict[str, NDArray[np.float64]]:
        """The coefficient arrays by name, ``{"A": A, "B": B, "C": C, "D": D}``."""
        ...

    def basis_values(self, p: ArrayLike) -> NDArray[np.float64]:
        """``psi_1..psi_Nb`` at ``p`` as ``(N, Nb)``, checked to be finite."""
        ...
