"""Levenberg-Marquardt and the reweighted l2,1 fit (method.md sections 3-4).

The work happens in the Rust core; these functions check the arguments,
build the compiled problem and wrap the results.
"""

from __future__ import annotations

import logging
import warnings
from collections.abc import Callable, Sequence
from typing import Any, TypeVar

import numpy as np

from lpvid import _core
from lpvid._checks import flag, positive_float, real_array
from lpvid._core import FitOutcome
from lpvid._problemlike import fit_args, l21_settings_of
from lpvid._spread import stop_flag
from lpvid.data.frf import FrfData
from lpvid.errors import ConvergenceWarning, logger
from lpvid.fit.memory import check_fit
from lpvid.fit.results import FitResult, L21Result, PathResult
from lpvid.fit.settings import L21Settings, LmSettings
from lpvid.fit.timecost import combined_problem
from lpvid.model.layout import free_mask
from lpvid.model.lpv import LpvModel
from lpvid.model.similarity import pointwise_similarity_directions, similarity_directions
from lpvid.stable.enforce import pole_floor, run_stable

__all__ = ["fit_nls", "fit_l21", "l21_path", "lm_settings", "raise_if_interrupted"]

Callback = Callable[[dict[str, Any]], Any]
R = TypeVar("R", FitResult, L21Result)

#: The stop code of a fit that Ctrl-C (SIGINT) stopped.
KEYBOARD_INTERRUPT = "keyboard_interrupt"

#: Curvature that ``fit_l21(..., pinned=True)`` adds along the flat
#: directions, relative to the unit diagonal of the Jacobi-scaled step
#: (measured on the positioning stage: 1 keeps its interpolation; 100 and
#: more keep more groups).
PIN_WEIGHT = 1.0


def _monitor(callback: Callback | None) -> Callback | None:
    """The user's callback, with every step logged at DEBUG on the ``lpvid`` logger.

    In a piece of :func:`lpvid.identify`'s work running on a thread
    (:mod:`lpvid._spread`), where Ctrl-C never arrives, a set stop flag
    stops the fit at its next step as Ctrl-C would.
    """
    if callback is not None and not callable(callback):
        raise TypeError(f"callback: expected a callable, got {type(callback).__name__}")
    stop = stop_flag()
    if stop is not None:
        inner = callback

        def stoppable(row: dict[str, Any]) -> Any:
            if stop.is_set():
                raise KeyboardInterrupt("stopped: the run this fit belongs to was interrupted")
            return None if inner is None else inner(row)

        callback = stoppable
    if not logger.isEnabledFor(logging.DEBUG):
        return callback

    def logged(row: dict[str, Any]) -> Any:
        logger.debug(
            "%s step: V_NLS %.6g, objective %.6g, step %.3g, lambda %.3g, %s, %s",
            row["kind"],
            row["vnls"],
            row["objective"],
            row["step_norm"],
            row["lambda"],
            "accepted" if row["accepted"] else "rejected",
            row["status"],
        )
        return None if callback is None else callback(row)

    return logged


def raise_if_interrupted(result: R) -> R:
    """Raise KeyboardInterrupt when Ctrl-C stopped ``result``'s fit; else return it.

    The fitting functions return the best model so far when Ctrl-C stops
    them (``result.interrupted``). A routine that runs several fits (such as
    :func:`lpvid.identify`) calls this after each, so that Ctrl-C stops the
    whole run rather than one of its fits.
    """
    if result.stop == KEYBOARD_INTERRUPT:
        raise KeyboardInterrupt(result.message)
    return result


def _still_falling(history: list[dict[str, Any]], tol: float) -> float | None:
    """Relative fall of the objective over the last three accepted steps, when above ``tol``."""
    objectives = [row["objective"] for row in history if row["accepted"]]
    if len(objectives) < 2:
        return None
    before, now = objectives[max(len(objectives) - 4, 0)], objectives[-1]
    fall = (before - now) / max(abs(before), 1e-300)
    return fall if fall > tol else None


#: A fit that stops at its iteration limit counts as still improving when its
#: objective fell by more than this fraction over its last three accepted steps
#: (slower falls are the slide along flat directions, worth nothing at the data).
FALLING = 1e-4


def warn_if_unconverged(result: FitResult, what: str, stacklevel: int = 3) -> bool:
    """Warn (:class:`lpvid.ConvergenceWarning`) when a fit hit its limit while still improving.

    Still improving: the objective fell by more than :data:`FALLING` (relative)
    over the last three accepted steps. Returns whether it warned.
    """
    if result.stop != "max_iterations":
        return False
    fall = _still_falling(result.history, FALLING)
    if fall is None:
        return False
    warnings.warn(
        f"{what} stopped at its iteration limit ({result.n_iter} steps) with the objective "
        f"still falling ({fall:.2g} relative over its last steps); the model may be short of "
        "the optimum: raise the iteration limits",
        ConvergenceWarning,
        stacklevel=stacklevel,
    )
    return True


def lm_settings(
    max_iter: int, xtol: float, ftol: float, gtol: float, lambda0: float
) -> dict[str, Any]:
    """The Levenberg-Marquardt settings as the core reads them, checked (:class:`LmSettings`)."""
    return LmSettings(max_iter, xtol, ftol, gtol, lambda0).to_core()


def fit_nls(
    model: LpvModel,
    data: FrfData,
    fixed: Any = None,
    *,
    max_iter: int = LmSettings.max_iter,
    xtol: float = LmSettings.xtol,
    ftol: float = LmSettings.ftol,
    gtol: float = LmSettings.gtol,
    lambda0: float = LmSettings.lambda0,
    callback: Callback | None = None,
    warn: bool = True,
    time_data: Any = None,
    stable: bool = False,
    p_range: Any = None,
) -> FitResult:
    """Minimise V_NLS by Levenberg-Marquardt (method.md (11)).

    Each step solves ``(J^T J + lambda^2 diag(J^T J)) d = -J^T r``. The damping
    follows the gain ratio (actual over predicted decrease, Nielsen's rule),
    so few steps are wasted. The run releases the GIL; Ctrl-C stops it and
    returns the best model so far (``result.interrupted`` is then True and
    ``result.stop`` is ``"keyboard_interrupt"``).

    Parameters
    ----------
    model : LpvModel
        Starting point; its structure (sizes, basis, Ts) is kept.
    data : FrfData or Problem
        The measurements; or a :class:`lpvid.Problem`, whose data,
        ``fixed``, ``time_data`` and ``p_range`` are then used (those
        arguments must not be given beside it).
    fixed : optional
        Parameters kept at their starting value, as in
        :func:`lpvid.fixed_mask` (e.g. ``{"D": True}``).
    max_iter : int
        Most steps computed, accepted or not.
    xtol : float
        Stop when ``||d|| <= xtol (||theta|| + xtol)``.
    ftol : float
        Stop when an accepted step lowers V_NLS by less than ``ftol V_NLS``.
    gtol : float
        Stop when the largest gradient entry is below ``gtol``.
    lambda0 : float
        Initial damping.
    callback : callable, optional
        Called after every step with a dict (see :attr:`FitResult.history`);
        returning ``False`` stops the fit.
    warn : bool
        Warn (:class:`lpvid.ConvergenceWarning`) when the fit stops at
        ``max_iter`` with V_NLS still falling (default True).
    time_data : TimeData or TimeCost, optional
        Time records beside the FRF data: the fit then minimises V_NLS plus
        their output error (see :func:`lpvid.fit_time`), ``result.vnls``
        is that sum and ``result.noise_floor`` the sum of both floors.
    stable : bool
        Keep every frozen model on ``p_range`` stable: steps that leave the
        stable set are refused (see :mod:`lpvid.stable.enforce`). The start
        must be stable.
    p_range : optional
        Scheduling range for ``stable``; default the model's (its basis
        domain), else the data's.

    Returns
    -------
    FitResult

    Raises
    ------
    ValueError
        On bad arguments, when V_NLS is not finite at the start, or with
        ``stable=True`` when the start is not stable over the range.
    MemoryError
        Before any work when the fit needs more memory than the process may
        allocate (the estimate of :func:`lpvid.fit_memory` against
        :func:`lpvid.available_memory`), and when an allocation in the core
        fails all the same.
    """
    settings = lm_settings(max_iter, xtol, ftol, gtol, lambda0)
    data, fixed, time_data, p_range = fit_args(data, fixed, time_data, p_range)
    problem, floor = combined_problem(model, data, time_data)
    free, monitor = free_mask(model, fixed), _monitor(callback)
    check_fit("fit_nls", model, data, free, "lm", time_data)
    raw = _stable_run(
        model,
        stable,
        _p_range_and_sup(model, data, p_range)[0] if stable else None,
        lambda rng: _core.fit_nls(problem, model.theta, free, settings, monitor, rng),
        data,
    )
    result = FitResult._from_core(raw, model, floor)
    if warn:
        warn_if_unconverged(result, "fit_nls")
    return result


def _pinned(
    model: LpvModel, data: FrfData, free: np.ndarray, pinned: Any
) -> tuple[np.ndarray, np.ndarray, float] | None:
    """The flat directions a pinned fit keeps its steps off, over the free parameters."""
    if not flag(pinned, "pinned"):
        return None
    W = pointwise_similarity_directions(model, data.p)
    if W.shape[1] == 0:
        return None
    exempt = similarity_directions(model)
    return np.ascontiguousarray(W[free]), np.ascontiguousarray(exempt[free]), PIN_WEIGHT


def _stable_run(
    model: LpvModel, stable: bool, p_range: Any, run: Callable[[Any], FitOutcome], data: Any
) -> FitOutcome:
    """``run(None)``, or with ``stable`` one that keeps the frozen models stable (pole_floor)."""
    if not flag(stable, "stable"):
        return run(None)
    return run_stable(model, p_range, run, pole_floor(model, data))


def _p_range_and_sup(model: LpvModel, data: FrfData, p_range: Any) -> tuple[Any, np.ndarray]:
    """The scheduling range for ``||psi_i||_inf`` (given, the model's, else the data's)."""
    rng = p_range if p_range is not None else model.p_range
    if rng is None:
        rng = data.p_range
    return rng, model.basis.sup_norms(rng)


def _l21_result(
    raw: FitOutcome,
    model: LpvModel,
    noise_floor: int,
    gamma: float,
    p_range: Any,
    threshold: float,
) -> L21Result:
    fitted = model.with_theta(raw.theta)
    return L21Result._from_core(
        raw,
        model,
        noise_floor,
        gamma=float(gamma),
        weights=np.asarray(raw.weights),
        group_norms=fitted.group_norms(p_range),
        threshold=threshold,
        outer_iterations=int(raw.outer_iterations),
    )


def fit_l21(
    model: LpvModel,
    data: FrfData,
    gamma: float,
    settings: L21Settings | None = None,
    fixed: Any = None,
    *,
    p_range: Any = None,
    callback: Callback | None = None,
    warn: bool = True,
    time_data: Any = None,
    stable: bool = False,
    pinned: bool = False,
    **options: Any,
) -> L21Result:
    """Reweighted l2,1-regularised fit: Algorithm 1 of the paper (method.md section 4).

    Minimises ``V_NLS(theta) / M + gamma * sum_g phi_g varphi_g ||theta_g||``
    over the groups ``theta_X(i)``, ``i >= 1``, by a sequence of second-order
    cone programs (27) solved with Clarabel, re-computing the weights
    ``phi`` until they settle. A step is taken only when the objective
    decreases; a cone solve that fails is a rejected step.

    **Scale of gamma.** ``M = data.n_residuals`` is the number of complex
    residuals (plus the real residuals of ``time_data``), so ``V_NLS / M``
    is about 1 at the noise floor whatever the amount of data. With the
    relative weights each group in use costs about ``gamma``: a group is
    kept only when it lowers V_NLS by more than about ``gamma * M``
    (``gamma = 1e-3`` asks for 0.1 % of M). The paper's raw gamma equals
    ``gamma * M``.

    **Stopping.** The inner loop ends on a small step or a small relative
    decrease of the objective; the outer loop ends when the weights stop
    changing (the paper's test) or when the set of groups in use and
    V_NLS stay the same over a reweighting. The second test matters: a
    realisation is only defined up to a similarity transform, and once the
    structure is found, further reweighting mostly slides along such
    transforms, shrinking the penalised groups while the constant parts grow.

    Parameters
    ----------
    model : LpvModel
        Starting point, usually the result of :func:`fit_nls`.
    data : FrfData or Problem
        The measurements; or a :class:`lpvid.Problem`, whose data,
        ``fixed``, ``time_data`` and ``p_range`` are then used (those
        arguments must not be given beside it), and whose path's
        ``L21Settings`` are the default of ``settings``.
    gamma : float
        Regularisation weight, >= 0. ``gamma = 0`` is plain Levenberg-Marquardt.
    settings : L21Settings, optional
        How Algorithm 1 runs (weights rule, ``eps``, tolerances, iteration
        limits); default :class:`lpvid.L21Settings`.
    fixed : optional
        Parameters kept at their starting value, as in :func:`lpvid.fixed_mask`.
    p_range : optional
        Scheduling range for ``||psi_i||_inf`` (and for ``stable``); default
        the model's, else the data's.
    callback : callable, optional
        Called after every cone step with a dict; returning ``False`` stops.
        Ctrl-C stops the fit and returns the best model so far
        (``result.stop == "keyboard_interrupt"``).
    warn : bool
        Warn (:class:`lpvid.ConvergenceWarning`) when the fit stops at its
        iteration limit with the objective still falling (default True).
    time_data : TimeData or TimeCost, optional
        Time records beside the FRF data: the cost is then V_NLS plus their
        output error and ``M`` the sum of both noise floors (as in
        :func:`fit_nls`).
    stable : bool
        Keep every frozen model on the range stable (as in :func:`fit_nls`);
        the start must be stable.
    pinned : bool
        Keep the cone steps off the directions that are flat at the data:
        with one scheduling point per coefficient matrix (``N = Nb + 1``),
        a state transformation at one point alone leaves V_NLS unchanged
        but moves the model between the points, and the l2,1 term can buy
        smaller groups with such moves. A curvature (:data:`PIN_WEIGHT`
        relative to the scaled quadratic, along those directions at the
        start, the transformation common to all points left free) damps
        them; the answer is still a stationary point of the objective, the
        damping chooses which of the equally good fits is reached. No
        effect at other numbers of points. :func:`lpvid.identify` uses it
        when the warm path loses interpolation.
    **options
        Fields of :class:`lpvid.L21Settings` to change, e.g. ``eps=1e-4``,
        ``weights="scaled"``, ``max_outer=5``.

    Returns
    -------
    L21Result

    Raises
    ------
    ValueError, TypeError
        On bad arguments (an unknown option names itself), or when V_NLS is
        not finite at the start.
    MemoryError
        As :func:`fit_nls` (the cone programs need more: see
        :mod:`lpvid.fit.memory`).
    """
    g = positive_float(gamma, "gamma", allow_zero=True)
    s = L21Settings.of(l21_settings_of(data, settings), **options)
    data, fixed, time_data, p_range = fit_args(data, fixed, time_data, p_range)
    rng, sup = _p_range_and_sup(model, data, p_range)
    problem, floor = combined_problem(model, data, time_data)
    free, monitor = free_mask(model, fixed), _monitor(callback)
    check_fit("fit_l21", model, data, free, "l21" if g > 0 else "lm", time_data, bool(pinned))
    pin = _pinned(model, data, free, pinned)
    raw = _stable_run(
        model,
        stable,
        rng,
        lambda check: _core.fit_l21(
            problem, model.theta, sup, free, s.to_core(g), monitor, check, pin
        ),
        data,
    )
    result = _l21_result(raw, model, floor, g, rng, s.threshold)
    if warn:
        warn_if_unconverged(result, f"fit_l21 (gamma = {g:g})")
    return result


def _sweep(
    model: LpvModel, gammas: Any, fit_one: Callable[[LpvModel, float], FitOutcome]
) -> list[tuple[float, FitOutcome]]:
    """A warm-started gamma path, largest gamma first, one ``fit_one(start, gamma)`` each.

    ``fit_one`` returns the core's outcome; the sweep stops after a fit
    that Ctrl-C interrupted (as the core's ``l21_path`` does).
    """
    out = []
    current = model
    for g in sorted((float(x) for x in gammas), reverse=True):
        raw = fit_one(current, g)
        out.append((g, raw))
        current = current.with_theta(raw.theta)
        if raw.interrupted:
            break
    return out


def l21_path(
    model: LpvModel,
    data: FrfData,
    gammas: Sequence[float],
    settings: L21Settings | None = None,
    fixed: Any = None,
    *,
    p_range: Any = None,
    callback: Callback | None = None,
    warn: bool = True,
    time_data: Any = None,
    stable: bool = False,
    pinned: bool = False,
    **options: Any,
) -> PathResult:
    """A warm-started sweep of :func:`fit_l21` from the largest gamma to the smallest.

    Each fit starts from the previous result, as in section 5.3 of the
    paper; the weights are recomputed at each start. Arguments (including
    ``time_data``) as in :func:`fit_l21`; Ctrl-C stops the sweep and returns
    the fits so far (the last one interrupted). With ``stable=True`` every fit
    keeps the frozen models on the range stable; with ``pinned=True`` every
    fit keeps its steps off the directions that are flat at the data
    (those of its own start, see :func:`fit_l21`).

    Returns
    -------
    PathResult
        One :class:`L21Result` per gamma, largest gamma first.

    Raises
    ------
    MemoryError
        As :func:`fit_l21`.
    """
    gs = real_array(gammas, "gammas", ndim=1)
    if gs.size == 0 or np.any(gs < 0):
        raise ValueError("gammas: needs at least one value, all >= 0")
    s = L21Settings.of(l21_settings_of(data, settings), **options)
    data, fixed, time_data, p_range = fit_args(data, fixed, time_data, p_range)
    rng, sup = _p_range_and_sup(model, data, p_range)
    problem, floor = combined_problem(model, data, time_data)
    free, monitor = free_mask(model, fixed), _monitor(callback)
    pin = flag(pinned, "pinned")
    check_fit("l21_path", model, data, free, "l21", time_data, pin)

    def one(m: LpvModel, g: float, check: Any = None) -> FitOutcome:
        flat = _pinned(m, data, free, pin)
        return _core.fit_l21(problem, m.theta, sup, free, s.to_core(g), monitor, check, flat)

    if flag(stable, "stable"):
        fl = pole_floor(model, data)
        raws = _sweep(model, gs, lambda m, g: run_stable(m, rng, lambda c: one(m, g, c), fl))
    elif pin:
        raws = _sweep(model, gs, one)
    else:
        path = _core.l21_path(problem, model.theta, sup, gs, free, s.to_core(), monitor)
        raws = list(zip(path.gammas, path.fits, strict=True))
    results = [_l21_result(raw, model, floor, g, rng, s.threshold) for g, raw in raws]
    if warn:
        for r in results:
            warn_if_unconverged(r, f"l21_path (gamma = {r.gamma:g})")
    return PathResult(results)
