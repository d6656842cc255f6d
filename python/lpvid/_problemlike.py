"""A :class:`lpvid.Problem` in place of data, for the functions below the pipeline (private).

The fits, the refit, the covariance and the stability check sit below
:mod:`lpvid.pipeline`, which defines :class:`~lpvid.Problem`; they take a
problem in place of their data by what it carries (:class:`ProblemLike`),
without importing it.
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable


@runtime_checkable
class ProblemLike(Protocol):
    """What a :class:`lpvid.Problem` carries that the fits and checks read."""

    data: Any
    order: int
    basis: Any
    fixed: Any
    p_range: Any
    time_data: Any
    settings: Any


def from_problem(data: Any, **given: Any) -> tuple[Any, dict[str, Any]]:
    """``data`` and ``given`` as they are, or a problem's data and its values of ``given``'s names.

    Parameters
    ----------
    data : FrfData or Problem
        What the caller passed as data.
    **given
        The caller's values of arguments a problem holds (``fixed``,
        ``p_range``, ``time_data``); None when not set.

    Returns
    -------
    data : FrfData
        ``data``, or the problem's data.
    given : dict
        ``given``, or the problem's values of the same names.

    Raises
    ------
    TypeError
        When a problem comes with one of ``given`` set: the problem holds it.
    """
    if not isinstance(data, ProblemLike):
        return data, given
    clash = sorted(k for k, v in given.items() if v is not None)
    if clash:
        them = "it" if len(clash) == 1 else "them"
        raise TypeError(
            f"{', '.join(clash)}: held by the Problem given as data; "
            f"set {them} there (Problem.replace)"
        )
    return data.data, {k: getattr(data, k) for k in given}


def fit_args(data: Any, fixed: Any, time_data: Any, p_range: Any) -> tuple[Any, Any, Any, Any]:
    """``(data, fixed, time_data, p_range)`` of a fit: as given, or from a problem."""
    data, held = from_problem(data, fixed=fixed, time_data=time_data, p_range=p_range)
    return data, held["fixed"], held["time_data"], held["p_range"]


def l21_settings_of(data: Any, settings: Any) -> Any:
    """``settings``, or a problem's l2,1 settings of the path when ``settings`` is None."""
    if settings is None and isinstance(data, ProblemLike):
        return data.settings.path.l21
    return settings
