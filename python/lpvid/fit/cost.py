"""V_NLS and its derivatives for a model on a data set (method.md (7), section 3)."""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np
from numpy.typing import NDArray

from lpvid import _core
from lpvid._checks import same_sample_time
from lpvid.data.frf import FrfData
from lpvid.model._view import model_view
from lpvid.model.layout import free_mask
from lpvid.model.lpv import LpvModel

__all__ = ["vnls", "vnls_value", "residual", "gauss_newton", "build_problem", "check_compatible"]


def check_compatible(model: LpvModel, data: FrfData) -> None:
    """Raise ValueError when a model cannot be compared with a data set."""
    if not isinstance(model, LpvModel):
        raise TypeError(f"model: expected an LpvModel, got {type(model).__name__}")
    if not isinstance(data, FrfData):
        raise TypeError(f"data: expected an FrfData, got {type(data).__name__}")
    if (model.n_outputs, model.n_inputs) != (data.n_outputs, data.n_inputs):
        raise ValueError(
            f"data: has {data.n_outputs} outputs x {data.n_inputs} inputs, the model "
            f"{model.n_outputs} x {model.n_inputs}"
        )
    if not same_sample_time(model.Ts, data.Ts):
        raise ValueError(f"data: sample time Ts={data.Ts} differs from the model's Ts={model.Ts}")
    if model.basis.n_params != data.n_params:
        raise ValueError(
            f"data: has {data.n_params} scheduling parameter(s), the model's basis takes "
            f"{model.basis.n_params}"
        )


def build_problem(model: LpvModel, data: FrfData) -> Any:
    """The compiled problem (data and basis values) for the core's evaluations."""
    check_compatible(model, data)
    view = model_view(model, model.basis_values(data.p))
    return _core.Problem(view, data.z, data.G.ravel(), data.sigma.ravel())


def vnls(model: LpvModel, data: FrfData) -> float:
    """Weighted squared error V_NLS of a model on a data set (method.md (7)).

    ``V_NLS = sum |G(theta) - Gm|^2 / sigma^2`` over every point, line,
    output and input. With correct ``sigma`` its expected value at the true
    system is ``data.n_residuals``: the noise floor.

    Parameters
    ----------
    model : LpvModel
    data : FrfData

    Returns
    -------
    float
        Finite, or ``inf`` with a ``RuntimeWarning`` when the sum overflows
        (a model whose errors are beyond 1e154 sigma).

    Raises
    ------
    SingularModelError
        When a frozen model is singular at an evaluation point or its
        response overflows.

    """
    value = vnls_value(model, data)
    if not np.isfinite(value):
        warnings.warn(
            f"vnls: V_NLS is not finite ({value}): the model's errors on these data are beyond "
            "the range of float64",
            RuntimeWarning,
            stacklevel=2,
        )
    return value


def vnls_value(model: LpvModel, data: FrfData) -> float:
    """:func:`vnls` without the warning: for callers that rank models and judge ``inf``."""
    return float(build_problem(model, data).vnls(model.theta))


def residual(model: LpvModel, data: FrfData) -> NDArray[np.complex128]:
    """Weighted residual ``(G(theta) - Gm) / sigma``, shape ``(N, F, l, r)``.

    Entries beyond the range of float64 (errors beyond about 1e308 sigma)
    come back as ``inf`` with a ``RuntimeWarning``, as in :func:`vnls`.
    """
    out = build_problem(model, data).residual(model.theta).reshape(data.G.shape)
    if not np.all(np.isfinite(out)):
        warnings.warn(
            "residual: some entries are not finite: the model's errors on these data are beyond "
            "the range of float64",
            RuntimeWarning,
            stacklevel=2,
        )
    return out


def gauss_newton(
    model: LpvModel, data: FrfData, fixed: Any = None
) -> tuple[float, NDArray[np.float64], NDArray[np.float64]]:
    """V_NLS, its gradient and the Gauss-Newton matrix over the free parameters.

    With ``r`` the real residual ``[Re; Im]`` of ``(G - Gm) / sigma`` and
    ``J = dr/dtheta``: ``V_NLS = r^T r``, gradient ``2 J^T r``, and
    ``J^T J``. The full Jacobian is never formed.

    Parameters
    ----------
    model : LpvModel
    data : FrfData
    fixed : optional
        Fixed parameters, as in :func:`lpvid.fixed_mask`; their rows and
        columns are left out.

    Returns
    -------
    vnls : float
    gradient : ndarray, shape (n_free,)
    jtj : ndarray, shape (n_free, n_free)

    """
    problem = build_problem(model, data)
    free = free_mask(model, fixed)
    v, g, h = problem.gauss_newton(model.theta, free)
    m = g.size
    return float(v), g, h.reshape(m, m)
