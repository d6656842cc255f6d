"""The body of :meth:`lpvid.LpvModel.simulate` (private).

Argument checks, the call into the core and the report of a divergence; the
method's docstring is the documentation.
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from lpvid import _core
from lpvid._checks import positive_float, real_array
from lpvid.model._protocol import ModelLike
from lpvid.model._view import model_view

# What `LpvModel.simulate` does when the simulation diverges.
_ON_DIVERGENCE = ("warn", "raise")


def simulate(
    model: ModelLike,
    u: ArrayLike,
    p: ArrayLike,
    x0: ArrayLike | None,
    *,
    dt: float | None,
    return_states: bool,
    on_divergence: str,
) -> Any:
    """Simulate ``model`` along ``p(t)``: see :meth:`lpvid.LpvModel.simulate`."""
    n, r, l, nb = model.shape
    if on_divergence not in _ON_DIVERGENCE:
        raise ValueError(f"on_divergence: expected one of {_ON_DIVERGENCE}, got {on_divergence!r}")
    u_arr = real_array(u, "u", ndim=(1, 2))
    if u_arr.ndim == 1:
        if r != 1:
            raise ValueError(
                f"u: the model has {r} inputs: expected shape (T, {r}), got {u_arr.shape}"
            )
        u_arr = u_arr[:, None]
    if u_arr.shape[1] != r:
        raise ValueError(
            f"u: expected shape (T, {r}) for a model with {r} inputs, got {u_arr.shape}"
        )
    t_len = u_arr.shape[0]
    if t_len == 0:
        raise ValueError("u: needs at least one sample")
    p_arr = real_array(p, "p", ndim=(0, 1, 2))
    n_params = model.basis.n_params
    if p_arr.ndim == 0:
        if n_params != 1:
            raise ValueError(
                f"p: the basis takes {n_params} scheduling parameters: expected shape "
                f"(T, {n_params}), got a single number"
            )
        p_arr = np.full(t_len, float(p_arr))
    if p_arr.shape[0] != t_len:
        raise ValueError(
            f"p: expected one scheduling value per sample of u (T={t_len}), got {p_arr.shape[0]}"
        )
    if p_arr.ndim == 1 and n_params != 1:
        raise ValueError(
            f"p: the basis takes {n_params} scheduling parameters: expected shape "
            f"(T, {n_params}), got {p_arr.shape}"
        )
    psi = np.ascontiguousarray(model.basis_values(p_arr), dtype=np.float64)
    if x0 is None:
        x_init = np.zeros(n)
    else:
        x_init = real_array(x0, "x0", ndim=1)
        if x_init.shape != (n,):
            raise ValueError(f"x0: expected {n} initial states, got shape {x_init.shape}")
    if model.Ts is not None:
        if dt is not None:
            step = positive_float(dt, "dt")
            if not np.isclose(step, model.Ts, rtol=1e-9, atol=0.0):
                raise ValueError(
                    f"dt: a discrete-time model runs at its sample time Ts={model.Ts:g} s, "
                    f"got dt={step:g}; leave dt out"
                )
        hold = None
    else:
        if dt is None:
            raise ValueError(
                "dt: a continuous-time model needs the sample time of u in seconds "
                "(zero-order hold), e.g. dt=1e-3"
            )
        hold = positive_float(dt, "dt")
    # u_arr and psi are this call's own arrays: the core may read them
    # without the GIL.
    y, x, diverged = _core.simulate(
        model_view(model, psi),
        np.ascontiguousarray(u_arr).ravel(),
        x_init,
        hold,
        bool(return_states),
    )
    if diverged is not None:
        message = (
            f"simulate: the simulation left the range of floating point at sample "
            f"{diverged} (p = {p_arr[diverged].tolist()}): the model is unstable along "
            f"the scheduling trajectory; values from there on are Inf or NaN"
        )
        if on_divergence == "raise":
            raise ValueError(message)
        warnings.warn(message, RuntimeWarning, stacklevel=3)  # the caller of LpvModel.simulate
    y = y.reshape(t_len, l)
    if return_states:
        assert x is not None
        return y, x.reshape(t_len + 1, n)
    return y
