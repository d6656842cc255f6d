"""The output error of a model on time records, alone or added to the FRF cost.

``V_time = sum_records sum_{t >= skip} sum_j ((y_model_j(t) - y_j(t)) / sigma_j(t))^2``
with ``y_model`` the simulation of :meth:`lpvid.LpvModel.simulate` along the
records' scheduling trajectories. Its noise floor is the number of real
residuals; FRF data and time records together cost ``V_NLS + V_time``
with the floor ``M_frf + M_time`` (each part weighted by its own noise).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from lpvid import _core
from lpvid._checks import positive_int, real_array, same_sample_time
from lpvid.data.frf import FrfData
from lpvid.data.schedule import as_rows, range_pairs
from lpvid.data.timedata import TimeData
from lpvid.fit.cost import build_problem, check_compatible
from lpvid.model.lpv import LpvModel

__all__ = [
    "TimeCost",
    "as_time_cost",
    "build_time_problem",
    "check_time_compatible",
    "check_time_data",
    "combined_problem",
    "initial_states",
    "time_residual",
    "time_vnls",
    "total_vnls",
]

#: How the initial states can be treated.
X0_MODES = ("estimate", "zero")


@dataclass(frozen=True)
class TimeCost:
    """Time records with how their initial states and first samples count.

    Pass it where a fitting function takes ``time_data`` to change the
    defaults (a plain :class:`TimeData` means ``x0="estimate", skip=0``).

    Parameters
    ----------
    data : TimeData
        The records.
    x0 : {"estimate", "zero"} or array_like, optional
        Initial state of every record: estimated for every record at every
        parameter vector (the least output error over the initial states;
        default), zero (the system starts at rest), or given: shape ``(n,)``
        for all records or ``(n_records, n)``.
    skip : int, optional
        Samples at the start of every record simulated but left out of the
        cost (a transient the model need not match), >= 0.

    Examples
    --------
    >>> import numpy as np, lpvid
    >>> td = lpvid.TimeData(np.ones(50), np.zeros(50), np.zeros(50), dt=0.1)
    >>> lpvid.TimeCost(td, x0="zero", skip=10).n_residuals
    40

    """

    data: TimeData
    x0: Any = "estimate"
    skip: int = 0

    def __post_init__(self) -> None:
        if not isinstance(self.data, TimeData):
            raise TypeError(f"time_data: expected a TimeData, got {type(self.data).__name__}")
        if isinstance(self.x0, str):
            if self.x0 not in X0_MODES:
                raise ValueError(
                    f"x0: expected 'estimate', 'zero' or an array of initial states, "
                    f"got {self.x0!r}"
                )
        else:
            object.__setattr__(self, "x0", real_array(self.x0, "x0", ndim=(1, 2)))
        skip = positive_int(self.skip, "skip", minimum=0)
        shortest = min(self.data.n_samples)
        if skip >= shortest:
            raise ValueError(
                f"skip: {skip} samples skipped leave nothing of the shortest record "
                f"({shortest} samples)"
            )
        object.__setattr__(self, "skip", skip)

    @property
    def n_residuals(self) -> int:
        """Real residuals in the cost, ``sum (T - skip) l``: its noise floor."""
        return (sum(self.data.n_samples) - self.skip * self.data.n_records) * self.data.n_outputs

    def x0_values(self, n: int) -> NDArray[np.float64] | None:
        """Given initial states as ``(n_records, n)``, or None for a mode."""
        if isinstance(self.x0, str):
            return None
        x = np.asarray(self.x0)
        k = self.data.n_records
        if x.shape == (n,):
            return np.tile(x, (k, 1))
        if x.shape != (k, n):
            raise ValueError(
                f"x0: expected shape ({n},) or ({k}, {n}) for {k} record(s) of a model with "
                f"{n} states, got {x.shape}"
            )
        return x


def as_time_cost(time_data: Any) -> TimeCost:
    """``time_data`` as a :class:`TimeCost` (a TimeData gets the defaults)."""
    return _with_options(time_data, "estimate", 0)


def check_time_compatible(model: LpvModel, data: TimeData) -> None:
    """Raise when a model cannot be compared with time records.

    Warns (``UserWarning``) when a record's scheduling trajectory leaves
    the model's scheduling range, where the basis extrapolates.
    """
    if not isinstance(model, LpvModel):
        raise TypeError(f"model: expected an LpvModel, got {type(model).__name__}")
    if (model.n_outputs, model.n_inputs) != (data.n_outputs, data.n_inputs):
        raise ValueError(
            f"time_data: has {data.n_outputs} outputs x {data.n_inputs} inputs, the model "
            f"{model.n_outputs} x {model.n_inputs}"
        )
    if model.basis.n_params != data.n_params:
        raise ValueError(
            f"time_data: has {data.n_params} scheduling parameter(s), the model's basis takes "
            f"{model.basis.n_params}"
        )
    if model.Ts is not None and not same_sample_time(model.Ts, data.dt):
        raise ValueError(
            f"time_data: sample time dt={data.dt:g} s differs from the discrete-time model's "
            f"Ts={model.Ts:g} s"
        )
    if model.p_range is None:
        return
    pairs = np.asarray(range_pairs(model.p_range), dtype=float)
    lo, hi = pairs[:, 0], pairs[:, 1]
    slack = 1e-9 * np.maximum(hi - lo, 1.0)
    for k, p in enumerate(data.p):
        rows = as_rows(p)
        if np.any(rows < lo - slack) or np.any(rows > hi + slack):
            warnings.warn(
                f"time_data: record {k} leaves the model's scheduling range {model.p_range} "
                f"(it spans {rows.min(0).tolist()} to {rows.max(0).tolist()}); the basis "
                "functions extrapolate there",
                UserWarning,
                stacklevel=3,
            )


def check_time_data(data: FrfData, time_data: Any) -> TimeCost:
    """``time_data`` as a TimeCost, checked against FRF data of the same system."""
    cost = as_time_cost(time_data)
    td = cost.data
    if (td.n_outputs, td.n_inputs, td.n_params) != (data.n_outputs, data.n_inputs, data.n_params):
        raise ValueError(
            f"time_data: {td.n_outputs} outputs, {td.n_inputs} inputs and {td.n_params} "
            f"scheduling parameter(s), the FRF data {data.n_outputs}, {data.n_inputs} and "
            f"{data.n_params}"
        )
    if data.Ts is not None and not same_sample_time(data.Ts, td.dt):
        raise ValueError(
            f"time_data: sample time dt={td.dt:g} s differs from the FRF data's Ts={data.Ts:g} s "
            "(a discrete-time model runs at one sample time)"
        )
    return cost


def build_time_problem(model: LpvModel, time_data: Any) -> Any:
    """The compiled time-record cost of ``model`` (checked) for the core."""
    cost = as_time_cost(time_data)
    data = cost.data
    check_time_compatible(model, data)
    values = cost.x0_values(model.n_states)
    mode = "given" if values is not None else str(cost.x0)
    return _core.TimeProblem(
        model.shape,
        [np.ascontiguousarray(u).ravel() for u in data.u],
        [np.ascontiguousarray(model.basis_values(p)).ravel() for p in data.p],
        [np.ascontiguousarray(y).ravel() for y in data.y],
        [np.ascontiguousarray(s).ravel() for s in data.sigma],
        None if model.Ts is not None else data.dt,
        mode,
        None if values is None else values.ravel(),
        cost.skip,
    )


def combined_problem(model: LpvModel, data: FrfData, time_data: Any = None) -> tuple[Any, int]:
    """The compiled cost of FRF data (and time records, when given) and its noise floor."""
    frf = build_problem(model, data)
    if time_data is None:
        return frf, data.n_residuals
    both = _core.SumProblem(frf, build_time_problem(model, time_data))
    return both, int(both.n_residuals)


def time_vnls(model: LpvModel, time_data: Any, x0: Any = "estimate", skip: int = 0) -> float:
    """Weighted output error of a model on time records.

    ``sum ((y_model - y) / sigma)^2`` over every record, sample from
    ``skip`` on and output; about ``sum (T - skip) l`` (the noise floor)
    for the true system when sigma is right.

    Parameters
    ----------
    model : LpvModel
    time_data : TimeData or TimeCost
        The records (a TimeCost carries its own ``x0`` and ``skip``).
    x0, skip : optional
        As in :class:`TimeCost`, for a plain TimeData (a TimeCost keeps its own).

    Returns
    -------
    float

    Raises
    ------
    ValueError
        On incompatible data, or when the model diverges along a record
        (the message names the record and the sample).
    """
    cost = _with_options(time_data, x0, skip)
    return float(build_time_problem(model, cost).vnls(model.theta))


def time_residual(
    model: LpvModel, time_data: Any, x0: Any = "estimate", skip: int = 0
) -> list[NDArray[np.float64]]:
    """Weighted output error ``(y_model - y) / sigma`` per record, shape ``(T - skip, l)``."""
    cost = _with_options(time_data, x0, skip)
    flat = build_time_problem(model, cost).residual(model.theta)
    l = cost.data.n_outputs
    out, start = [], 0
    for t_len in cost.data.n_samples:
        size = (t_len - cost.skip) * l
        out.append(flat[start : start + size].reshape(-1, l))
        start += size
    return out


def initial_states(model: LpvModel, time_data: Any, skip: int = 0) -> NDArray[np.float64]:
    """The least-squares initial state of every record, shape ``(n_records, n)``.

    The initial states :func:`lpvid.fit_time` estimates (``x0="estimate"``):
    directions of the state that do not show in the outputs are left at zero.
    """
    cost = _with_options(time_data, "estimate", skip)
    x = build_time_problem(model, cost).initial_states(model.theta)
    return x.reshape(cost.data.n_records, model.n_states)


def total_vnls(model: LpvModel, data: FrfData, time_data: Any = None) -> float:
    """V_NLS on the FRF data plus the output error on the time records (when given)."""
    check_compatible(model, data)
    return float(combined_problem(model, data, time_data)[0].vnls(model.theta))


def _with_options(time_data: Any, x0: Any, skip: int) -> TimeCost:
    if isinstance(time_data, TimeCost):
        return time_data
    if not isinstance(time_data, TimeData):
        raise TypeError(
            f"time_data: expected a TimeData or TimeCost, got {type(time_data).__name__}"
        )
    return TimeCost(time_data, x0=x0, skip=skip)
