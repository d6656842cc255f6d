"""Fitting an LPV model to time records along a varying scheduling trajectory.

:func:`fit_time` minimises the output error of :mod:`lpvid.fit.timecost` with
the same optimisers as the FRF fits (Levenberg-Marquardt, or the
reweighted l2,1 cone steps with ``gamma > 0``), on the analytic Jacobian
of the LPV recursion computed in the Rust core.
"""

from __future__ import annotations

from typing import Any

from lpvid import _core
from lpvid._checks import positive_float
from lpvid.fit.fits import Callback, _l21_result, _monitor, lm_settings, warn_if_unconverged
from lpvid.fit.memory import check_fit
from lpvid.fit.results import FitResult, L21Result
from lpvid.fit.settings import L21Settings, LmSettings
from lpvid.fit.timecost import TimeCost, build_time_problem
from lpvid.model.layout import free_mask
from lpvid.model.lpv import LpvModel

__all__ = ["fit_time"]


def fit_time(
    model: LpvModel,
    time_data: Any,
    *,
    fixed: Any = None,
    x0: Any = "estimate",
    skip: int = 0,
    gamma: float = 0.0,
    max_iter: int | None = None,
    settings: L21Settings | None = None,
    p_range: Any = None,
    callback: Callback | None = None,
    warn: bool = True,
    **options: Any,
) -> FitResult | L21Result:
    r"""Fit an LPV model to time records: minimise the weighted output error.

    The cost is ``V = sum ((y_model - y) / sigma)^2`` over every record,
    sample from ``skip`` on and output, with ``y_model`` the simulation of
    :meth:`lpvid.LpvModel.simulate` (continuous-time models with the same
    zero-order hold). Its noise floor is the number of real residuals
    ``sum (T - skip) l``.

    The Jacobian comes from the forward sensitivity equations of the LPV
    recursion, one sensitivity per parameter, computed in the Rust core
    with the GIL released; only ``J^T J`` and ``J^T r`` are formed. With
    ``x0="estimate"`` the initial state of every record is eliminated
    exactly: the cost at ``theta`` is the least output error over the
    initial states, and the Gauss-Newton matrix is the Schur complement of
    their block (variable projection). A trial point whose simulation
    diverges is a rejected step; a starting model that diverges along a
    record raises ValueError naming the record and the sample.

    With ``gamma = 0`` the fit is Levenberg-Marquardt (as
    :func:`lpvid.fit_nls`); with ``gamma > 0`` the reweighted l2,1 cone
    steps of :func:`lpvid.fit_l21` on this cost (``M`` = the noise floor).
    To fit FRF data and time records together, pass ``time_data=`` to
    :func:`lpvid.fit_nls`, :func:`lpvid.fit_l21` or :func:`lpvid.identify`.

    Parameters
    ----------
    model : LpvModel
        Starting point, e.g. the result of :func:`lpvid.identify` on local
        FRF data. A discrete-time model must have ``Ts == time_data.dt``.
    time_data : TimeData or TimeCost
        The records (a TimeCost carries its own ``x0`` and ``skip``, and
        then the two arguments below must keep their defaults).
    fixed : optional
        Parameters kept at their starting value (see :func:`lpvid.fixed_mask`).
    x0 : {"estimate", "zero"} or array_like
        Initial states: estimated for every record (default), zero, or
        given (``(n,)`` for all records or ``(n_records, n)``).
    skip : int
        Samples at the start of every record left out of the cost.
    gamma : float
        Regularisation weight, >= 0 (lpvid's normalised gamma, see
        :func:`lpvid.fit_l21`).
    max_iter : int, optional
        Most Levenberg-Marquardt steps (default 100); only for
        ``gamma = 0`` (the l2,1 fit has ``max_outer`` and ``max_inner``).
    settings : L21Settings, optional
        Settings of the l2,1 fit (``gamma > 0``).
    p_range : optional
        Scheduling range for ``||psi_i||_inf`` (``gamma > 0``); default the
        model's, else the range the records visit.
    callback : callable, optional
        Called after every step with a dict; returning ``False`` stops.
        Ctrl-C stops the fit and returns the best model so far.
    warn : bool
        Warn (:class:`lpvid.ConvergenceWarning`) when the fit stops at its
        iteration limit with the cost still falling.
    **options
        With ``gamma = 0``: ``xtol``, ``ftol``, ``gtol``, ``lambda0`` of
        :func:`lpvid.fit_nls`; with ``gamma > 0``: fields of
        :class:`lpvid.L21Settings`.

    Returns
    -------
    FitResult or L21Result
        As :func:`lpvid.fit_nls` (``gamma = 0``) or :func:`lpvid.fit_l21`:
        ``vnls`` is the output error, ``noise_floor`` its floor. The
        initial states of the fitted model: :func:`lpvid.initial_states`.

    Raises
    ------
    ValueError, TypeError
        On bad arguments (named), records that do not fit the model, or a
        starting model that diverges along a record.
    MemoryError
        Before any work, when the fit needs more memory than the process may
        allocate (:func:`lpvid.available_memory`). With ``S`` the free
        parameters of A and B plus ``n`` (the initial states, when
        estimated), ``P = (Nb + 1)(n + l)(n + r)`` free parameters in all and
        ``t`` threads, it needs about ``8 (S^2 (t + 1) + 2 P^2)`` bytes (each
        thread's Gram sums, one record's Gram matrix, ``J^T J`` of the
        current point and of the trial point), ``16 * 2048 S`` for a block of
        Jacobian rows and, for a continuous-time model, ``8 (2048 / l) n^2
        (n + r)`` for the hold's derivatives of a block; with ``gamma > 0``
        the cone programs as in :func:`lpvid.fit_l21`; the simulated
        trajectory of the longest record (``T`` samples) ``8 T (n + 3 l)``;
        then half as much again and 64 MB (:func:`lpvid.fit.memory.resident`).
        The records themselves hold ``8 T (r + Nb + 2 l)`` bytes each.
        :func:`lpvid.fit_memory` gives the figure.

    Warns
    -----
    UserWarning
        When a record's scheduling trajectory leaves the model's range.
    ConvergenceWarning
        As :func:`lpvid.fit_nls`.

    Examples
    --------
    >>> import numpy as np, lpvid
    >>> true = lpvid.LpvModel([[[0.8]], [[0.1]]], np.ones((2, 1, 1)), np.ones((2, 1, 1)),
    ...                       basis=lpvid.Polynomial(1, domain=(0, 1)), Ts=0.01)
    >>> t = np.arange(400)
    >>> u, p = np.sin(0.3 * t), 0.5 + 0.5 * np.sin(0.05 * t)
    >>> y = true.simulate(u, p) + 1e-3 * np.random.default_rng(0).standard_normal((400, 1))
    >>> td = lpvid.TimeData(u, p, y, dt=0.01, sigma=1e-3)
    >>> start = true.with_theta(true.theta * 0.9)
    >>> lpvid.time_vnls(start, td) / td.n_residuals > 100
    True
    >>> fit = lpvid.fit_time(start, td)
    >>> fit.converged, 0.8 < fit.vnls / fit.noise_floor < 1.1
    (True, True)

    """
    if isinstance(time_data, TimeCost):
        if not (isinstance(x0, str) and x0 == "estimate") or skip != 0:
            raise ValueError(
                "x0, skip: a TimeCost carries its own; leave x0 and skip out or pass a TimeData"
            )
        cost = time_data
    else:
        cost = TimeCost(time_data, x0=x0, skip=skip)
    g = positive_float(gamma, "gamma", allow_zero=True)
    problem = build_time_problem(model, cost)
    free = free_mask(model, fixed)
    check_fit("fit_time", model, None, free, "lm" if g == 0.0 else "l21", cost)
    if g == 0.0:
        if settings is not None:
            raise ValueError("settings: the l2,1 settings apply with gamma > 0 only")
        defaults = LmSettings()
        lm = {k: getattr(defaults, k) for k in ("xtol", "ftol", "gtol", "lambda0")}
        for key in options:
            if key not in lm:
                raise TypeError(
                    f"{key}: not a setting of the Levenberg-Marquardt fit (gamma = 0); "
                    f"expected one of {sorted(lm)}"
                )
        lm.update(options)
        core_settings = lm_settings(defaults.max_iter if max_iter is None else max_iter, **lm)
        raw = _core.fit_nls(problem, model.theta, free, core_settings, _monitor(callback))
        result: FitResult | L21Result = FitResult._from_core(raw, model, problem.n_residuals)
        if warn:
            warn_if_unconverged(result, "fit_time")
        return result
    if max_iter is not None:
        raise ValueError(
            "max_iter: limits the Levenberg-Marquardt fit (gamma = 0); with gamma > 0 set "
            "max_outer and max_inner (L21Settings)"
        )
    s = L21Settings.of(settings, **options)
    rng = p_range if p_range is not None else model.p_range
    if rng is None:
        rng = cost.data.p_range
    sup = model.basis.sup_norms(rng)
    raw = _core.fit_l21(problem, model.theta, sup, free, s.to_core(g), _monitor(callback))
    result = _l21_result(raw, model, problem.n_residuals, g, rng, s.threshold)
    if warn:
        warn_if_unconverged(result, f"fit_time (gamma = {g:g})")
    return result
