"""The core's view of a model at some scheduling points (private).

Every binding that evaluates a model (its frequency response, its
simulation, its LTI Jacobian, an identification problem, the check points
of a stability range) takes one :class:`lpvid._core.ModelView`: the shape
``(n, r, l, nb)``, the parameters and the basis values, checked once when
the view is built. :func:`model_view` is the one place that builds it.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from lpvid import _core
from lpvid.model._protocol import ModelLike

__all__ = ["model_view"]


def model_view(model: ModelLike, psi: ArrayLike) -> _core.ModelView:
    """The core's view of ``model`` at basis values ``psi`` of shape ``(N, Nb)``.

    The basis values are passed as a C-contiguous float64 array (a copy
    when ``psi`` is not one already): the core reads them without the GIL.
    """
    return _core.ModelView(model.shape, model.theta, np.ascontiguousarray(psi, dtype=np.float64))
