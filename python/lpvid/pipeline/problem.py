"""One identification problem, checked once: what :func:`lpvid.identify` works on.

A :class:`Problem` holds the data, the model structure and the settings of
an identification and checks them all when it is made, with the messages
:func:`lpvid.identify` gives for the same inputs. The stages of the
pipeline take the checked problem (or its checked parts) and check nothing
it guarantees again.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from lpvid._checks import positive_int, same_sample_time
from lpvid.data.basis import Basis
from lpvid.data.frf import FrfData
from lpvid.data.schedule import model_range
from lpvid.fit.judge import identify_range
from lpvid.fit.settings import (
    DEFAULT_GAMMAS,
    PATH_L21,
    ROUTES,
    IdentifySettings,
    L21Settings,
    PathSettings,
    StartSettings,
)
from lpvid.fit.timecost import TimeCost, check_time_data
from lpvid.initial.local import check_local_order
from lpvid.model.layout import fixed_mask
from lpvid.model.lpv import LpvModel
from lpvid.pipeline.capacity import check_order, zero_model

__all__ = ["IdentifyArguments", "Problem", "check_scale", "check_validation"]


def check_validation(data: FrfData, validation: Any) -> FrfData | None:
    """Validation data of :func:`lpvid.identify`, checked against the identification data."""
    if validation is None:
        return None
    if not isinstance(validation, FrfData):
        raise TypeError(f"validation: expected an FrfData, got {type(validation).__name__}")

    def sizes(d: FrfData) -> str:
        return f"{d.n_outputs} outputs x {d.n_inputs} inputs, {d.n_params} scheduling parameter(s)"

    if sizes(validation) != sizes(data):
        raise ValueError(f"validation: has {sizes(validation)}; the data have {sizes(data)}")
    if not same_sample_time(validation.Ts, data.Ts):
        raise ValueError(f"validation: Ts={validation.Ts} differs from data's Ts={data.Ts}")
    return validation


def _check_basis(basis: Basis, data: FrfData) -> None:
    """The basis against the data: enough points for its functions, as many parameters."""
    if data.n_points < len(basis) + 1:
        raise ValueError(
            f"basis: {len(basis)} basis functions need at least {len(basis) + 1} scheduling "
            f"points, the data have {data.n_points}"
        )
    if basis.n_params != data.n_params:
        raise ValueError(
            f"basis: takes {basis.n_params} scheduling parameter(s), the data have {data.n_params}"
        )


def check_scale(
    basis: Basis, data: FrfData, validation: FrfData | None, who: str = "basis:"
) -> None:
    """Refuse a basis on the log scale where the data's scheduling values reach zero or below.

    Parameters
    ----------
    basis : Basis
    data, validation : FrfData
        The data (validation may be None).
    who : str
        What the message starts with (the argument that holds the basis).

    Raises
    ------
    ValueError
        Naming the parameter, the data and their smallest value.
    """
    for what, d in (("data", data), ("validation data", validation)):
        if d is None:
            continue
        p = d.p_rows
        for k, scale in enumerate(basis.scales):
            if scale == "log" and not np.all(p[:, k] > 0):
                which = "" if basis.n_params == 1 else f" parameter {k + 1}"
                raise ValueError(
                    f"{who} takes the scheduling{which} on the log scale, which needs values "
                    f"above zero; the {what} reach {float(np.min(p[:, k])):g} (take it on "
                    "scale='linear')"
                )


def _range(n: int, basis: Basis, data: FrfData, p_range: Any) -> Any:
    """The scheduling range the models are judged on, as :func:`lpvid.identify` derives it.

    Every start of :func:`lpvid.initial_candidates` is built with
    ``p_range=model_range(data.p)`` (its basis domain when a parameter does
    not vary); :func:`lpvid.fit.judge.identify_range` of such a model. A range
    given is checked as :class:`lpvid.LpvModel` checks it.
    """
    zero = zero_model(n, basis, data)
    rng = model_range(data.p) if p_range is None else p_range
    model = LpvModel(zero.A, zero.B, zero.C, zero.D, basis=basis, Ts=data.Ts, p_range=rng)
    return identify_range(model, data)


@dataclass(frozen=True, eq=False)
class Problem:
    """An identification problem: data, model structure and settings, checked once.

    :func:`lpvid.identify` (and :func:`lpvid.select`, for the data) take
    a problem in place of their arguments; the stages of the pipeline then
    check nothing it guarantees again. Every field is checked when the
    problem is made, with the message :func:`lpvid.identify` gives for the
    same input; change one with :meth:`replace` (checked again).

    Parameters
    ----------
    data : FrfData
        Identification data.
    order : int
        Number of states, >= 1, within what the data determine (see
        :func:`lpvid.pipeline.capacity.check_order` and :func:`lpvid.identify_lti`).
    basis : Basis
        Basis functions of the scheduling dependency, at most ``N - 1`` of
        them, over the data's scheduling parameters.
    validation : FrfData, optional
        Data at other scheduling values, of the same sizes and sample time.
    fixed : optional
        Parameters kept fixed, in any form :func:`lpvid.fixed_mask` takes
        (kept as given; :attr:`mask` is the mask over theta).
    time_data : TimeData or TimeCost, optional
        Time records of the same system; held as a :class:`lpvid.TimeCost`.
    p_range : (lo, hi) or sequence of (lo, hi), optional
        Scheduling range the models are judged on (stability, dropped
        groups, group magnitudes). Default: the range of the data's
        scheduling values (the basis domain when a parameter does not vary,
        else the data's range), which is what every start model holds.
    settings : IdentifySettings
        The l2,1 path, the starts, ``stable`` and ``refit``; default
        ``IdentifySettings()`` (its l2,1 fits ``L21Settings(max_outer=10)``).

    Raises
    ------
    TypeError, ValueError
        Naming the argument, as :func:`lpvid.identify` does.

    Examples
    --------
    >>> import numpy as np, lpvid, lpvid.testing
    >>> true = lpvid.testing.modal_lpv([[10.0, 3.0]])
    >>> f = np.linspace(2, 30, 40)
    >>> data = lpvid.testing.noisy_data(true, [0.0, 0.5, 1.0], f, np.random.default_rng(0), 0.01)
    >>> problem = lpvid.Problem(data, 2, lpvid.Polynomial(1, domain=(0, 1)))
    >>> problem.p_range, problem.settings.path.gammas[0]
    ([0.0, 1.0], 0.1)

    """

    data: FrfData
    order: int
    basis: Basis
    validation: FrfData | None = None
    fixed: Any = None
    time_data: TimeCost | None = None
    p_range: Any = None
    settings: IdentifySettings = field(default_factory=IdentifySettings)

    def __post_init__(self) -> None:
        data, basis = self.data, self.basis
        if not isinstance(data, FrfData):
            raise TypeError(f"data: expected an FrfData, got {type(data).__name__}")
        if not isinstance(basis, Basis):
            raise TypeError(f"basis: expected an lpvid basis, got {type(basis).__name__}")
        n = positive_int(self.order, "order")
        validation = check_validation(data, self.validation)
        time_cost = None if self.time_data is None else check_time_data(data, self.time_data)
        if not isinstance(self.settings, IdentifySettings):
            raise TypeError(
                f"settings: expected an IdentifySettings, got {type(self.settings).__name__}"
            )
        _check_basis(basis, data)
        check_scale(basis, data, validation)
        check_order(n, basis, data, self.fixed)
        check_local_order(n, data)
        for name, value in (
            ("order", n),
            ("validation", validation),
            ("time_data", time_cost),
            ("p_range", _range(n, basis, data, self.p_range)),
        ):
            object.__setattr__(self, name, value)

    @property
    def mask(self) -> np.ndarray:
        """The fixed parameters as a boolean mask over theta (:func:`lpvid.fixed_mask`)."""
        return fixed_mask(zero_model(self.order, self.basis, self.data), self.fixed)

    def replace(self, **changes: Any) -> Problem:
        """A copy with some fields changed, checked again (``p_range`` anew unless given)."""
        known = {f.name for f in dataclasses.fields(self)}
        for key in changes:
            if key not in known:
                raise TypeError(f"{key}: not a field of Problem; expected one of {sorted(known)}")
        if "p_range" not in changes and {"data", "basis"} & set(changes):
            changes["p_range"] = None
        return dataclasses.replace(self, **changes)

    def __repr__(self) -> str:
        val = "" if self.validation is None else f", validation N={self.validation.n_points}"
        td = "" if self.time_data is None else ", time records"
        return (
            f"Problem(order={self.order}, {len(self.basis)} basis functions, "
            f"data N={self.data.n_points}{val}{td})"
        )


@dataclass(frozen=True)
class IdentifyArguments:
    """:func:`lpvid.identify`'s arguments that a :class:`Problem` holds, with their defaults.

    The one record of them: ``identify`` reads its own into it
    (:meth:`of`), makes the problem from it (:meth:`problem`), and refuses
    them beside a given :class:`Problem` (:meth:`refuse`), as
    :func:`lpvid.select` does with the ones it shares. ``settings``
    (default ``L21Settings(max_outer=10)``, the default of
    :class:`lpvid.fit.settings.PathSettings`) are those of the path's l2,1
    fits; the starts' fits end by their own rule
    (:data:`lpvid.fit.settings.START_FTOL`; a :class:`Problem` with
    :class:`lpvid.fit.settings.StartSettings` sets another).
    """

    order: Any = None
    basis: Any = None
    gammas: Any = None
    validation: Any = None
    fixed: Any = None
    forms: Any = None
    routes: Any = ROUTES
    tolerance: float = 0.1
    settings: Any = None
    time_data: Any = None
    stable: bool = False
    refit: bool = True

    @classmethod
    def of(cls, arguments: dict[str, Any]) -> IdentifyArguments:
        """The record of those of ``arguments`` (a call's ``locals()``) that it holds."""
        return cls(
            **{f.name: arguments[f.name] for f in dataclasses.fields(cls) if f.name in arguments}
        )

    def given(self) -> list[str]:
        """The names of the arguments given (not left at their defaults), in the record's order."""
        out = []
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if value is f.default or (f.default is not None and value == f.default):
                continue
            out.append(f.name)
        return out

    def refuse(self) -> None:
        """Refuse every argument given: a :class:`Problem` was given, which holds them."""
        given = self.given()
        if given:
            raise TypeError(
                f"{', '.join(given)}: the problem holds these; give them to lpvid.Problem "
                "(or problem.replace(...)), not beside it"
            )

    def problem(self, data: FrfData) -> Problem:
        """The checked :class:`Problem` of ``data`` and these arguments."""
        l21 = L21Settings.of(PATH_L21 if self.settings is None else self.settings)
        gs = DEFAULT_GAMMAS if self.gammas is None else self.gammas
        path = PathSettings(gammas=gs, tolerance=self.tolerance, l21=l21)
        starts = StartSettings(routes=self.routes, forms=self.forms)
        chosen = IdentifySettings(path=path, starts=starts, stable=self.stable, refit=self.refit)
        return Problem(
            data,
            self.order,
            self.basis,
            self.validation,
            self.fixed,
            self.time_data,
            settings=chosen,
        )
