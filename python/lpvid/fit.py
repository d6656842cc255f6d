"""Levenberg-Marquardt and the reweighted l2,1 fit (method.md sections 3-4).

The work happens in the Rust core; these functions check the arguments,
build the compiled problem and wrap the results.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from lpvid import _core
from lpvid._checks import positive_float, positive_int, real_array
from lpvid.cost import build_problem
from lpvid.data import FrfData
from lpvid.layout import free_mask
from lpvid.model import LpvModel
from lpvid.results import FitResult, L21Result, PathResult

__all__ = ["fit_nls", "fit_l21", "l21_path"]

Callback = Callable[[dict[str, Any]], Any]

WEIGHTS = ("relative", "scaled", "plain")


def _callback(callback: Callback | None) -> Callback | None:
    if callback is not None and not callable(callback):
        raise TypeError(f"callback: expected a callable, got {type(callback).__name__}")
    return callback


def fit_nls(
    model: LpvModel,
    data: FrfData,
    fixed: Any = None,
    *,
    max_iter: int = 100,
    xtol: float = 1e-10,
    ftol: float = 1e-10,
    gtol: float = 0.0,
    lambda0: float = 1e-2,
    callback: Callback | None = None,
) -> FitResult:
    """Minimise V_NLS by Levenberg-Marquardt (method.md (11)).

    Each step solves ``(J^T J + lambda^2 diag(J^T J)) d = -J^T r``. The damping
    follows the gain ratio (actual over predicted decrease, Nielsen's rule),
    so few steps are wasted. The run releases the GIL; Ctrl-C stops it and
    returns the best model so far (``result.interrupted`` is then True).

    Parameters
    ----------
    model : LpvModel
        Starting point; its structure (sizes, basis, Ts) is kept.
    data : FrfData
        The measurements.
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

    Returns
    -------
    FitResult
    """
    settings = dict(
        max_iter=positive_int(max_iter, "max_iter"),
        xtol=positive_float(xtol, "xtol", allow_zero=True),
        ftol=positive_float(ftol, "ftol", allow_zero=True),
        gtol=positive_float(gtol, "gtol", allow_zero=True),
        lambda0=positive_float(lambda0, "lambda0"),
    )
    problem = build_problem(model, data)
    raw = _core.fit_nls(
        problem, model.theta, free_mask(model, fixed), settings, _callback(callback)
    )
    return FitResult._from_core(raw, model, data.n_residuals)


def _l21_settings(
    model: LpvModel,
    data: FrfData,
    p_range: Any,
    *,
    eps: float,
    weights: str,
    dtheta_min: float,
    dphi_min: float,
    dvnls_min: float,
    threshold: float,
    ftol: float,
    max_outer: int,
    max_inner: int,
    lambda0: float,
) -> tuple[dict[str, Any], Any, np.ndarray]:
    """Checked settings for the core, the scheduling range and ``||psi_i||_inf`` on it."""
    if weights not in WEIGHTS:
        raise ValueError(f"weights: expected one of {WEIGHTS}, got {weights!r}")
    rng = p_range if p_range is not None else model.p_range
    if rng is None:
        rng = data.p_range if data.n_params == 1 else list(zip(*data.p_range, strict=True))
    settings = dict(
        eps=positive_float(eps, "eps"),
        weights=weights,
        dtheta_min=positive_float(dtheta_min, "dtheta_min", allow_zero=True),
        dphi_min=positive_float(dphi_min, "dphi_min", allow_zero=True),
        dvnls_min=positive_float(dvnls_min, "dvnls_min", allow_zero=True),
        threshold=positive_float(threshold, "threshold"),
        ftol=positive_float(ftol, "ftol", allow_zero=True),
        max_outer=positive_int(max_outer, "max_outer"),
        max_inner=positive_int(max_inner, "max_inner"),
        lambda0=positive_float(lambda0, "lambda0"),
    )
    return settings, rng, model.basis.sup_norms(rng)


def _l21_result(
    raw: dict[str, Any],
    model: LpvModel,
    data: FrfData,
    gamma: float,
    p_range: Any,
    threshold: float,
) -> L21Result:
    fitted = model.with_theta(raw["theta"])
    return L21Result._from_core(
        raw,
        model,
        data.n_residuals,
        gamma=float(gamma),
        weights=np.asarray(raw["weights"]),
        group_norms=fitted.group_norms(p_range),
        threshold=threshold,
        outer_iterations=int(raw["outer_iterations"]),
    )


def fit_l21(
    model: LpvModel,
    data: FrfData,
    gamma: float,
    eps: float = 1e-3,
    weights: str = "relative",
    fixed: Any = None,
    dtheta_min: float = 1e-6,
    dphi_min: float = 1e-3,
    *,
    dvnls_min: float = 1e-3,
    ftol: float = 1e-6,
    max_outer: int = 20,
    max_inner: int = 10,
    lambda0: float = 1e-2,
    p_range: Any = None,
    threshold: float = 1e-6,
    callback: Callback | None = None,
) -> L21Result:
    """Reweighted l2,1-regularised fit: Algorithm 1 of the paper (method.md section 4).

    Minimises ``V_NLS(theta) / M + gamma * sum_g phi_g varphi_g ||theta_g||``
    over the groups ``theta_X(i)``, ``i >= 1``, by a sequence of second-order
    cone programs (27) solved with Clarabel, re-computing the weights
    ``phi`` until they settle. A step is taken only when the objective
    decreases; a cone solve that fails is a rejected step.

    **Scale of gamma.** ``M = data.n_residuals`` is the number of complex
    residuals, so ``V_NLS / M`` is about 1 at the noise floor whatever the
    amount of data. With the relative weights each group in use costs
    about ``gamma``: a group is kept only when it lowers V_NLS by more than
    about ``gamma * M`` (``gamma = 1e-3`` asks for 0.1 % of M). The paper's
    raw gamma equals ``gamma * M``.

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
    data : FrfData
        The measurements.
    gamma : float
        Regularisation weight, >= 0. ``gamma = 0`` is plain Levenberg-Marquardt.
    eps : float
        ``eps`` of the weights (21)-(23).
    weights : {"relative", "scaled", "plain"}
        Reweighting rule: (23) with the scale (25) (groups whose X(0) is zero
        or fixed fall back to (22)), (22), or (21).
    fixed : optional
        Parameters kept at their starting value, as in :func:`lpvid.fixed_mask`.
    dtheta_min : float
        Inner loop ends when ``||d|| <= dtheta_min (||theta|| + dtheta_min)``.
    dphi_min : float
        Outer loop ends when the largest relative change of the weights is
        at most ``dphi_min``.
    dvnls_min : float
        Outer loop ends when the groups in use are unchanged and V_NLS
        changed by at most this fraction over the last reweighting.
    ftol : float
        Inner loop also ends when a step lowers the objective by less than
        ``ftol`` times its value.
    max_outer, max_inner : int
        Iteration limits of the two loops.
    lambda0 : float
        Initial damping (reset at every reweighting).
    p_range : optional
        Scheduling range for ``||psi_i||_inf``; default the model's, else the data's.
    threshold : float
        Relative magnitude (23) below which a group counts as removed.
    callback : callable, optional
        Called after every cone step with a dict; returning ``False`` stops.

    Returns
    -------
    L21Result
    """
    g = positive_float(gamma, "gamma", allow_zero=True)
    settings, rng, sup = _l21_settings(
        model,
        data,
        p_range,
        eps=eps,
        weights=weights,
        dtheta_min=dtheta_min,
        dphi_min=dphi_min,
        dvnls_min=dvnls_min,
        threshold=threshold,
        ftol=ftol,
        max_outer=max_outer,
        max_inner=max_inner,
        lambda0=lambda0,
    )
    problem = build_problem(model, data)
    raw = _core.fit_l21(
        problem,
        model.theta,
        sup,
        free_mask(model, fixed),
        {**settings, "gamma": g},
        _callback(callback),
    )
    return _l21_result(raw, model, data, g, rng, settings["threshold"])


def l21_path(
    model: LpvModel,
    data: FrfData,
    gammas: Sequence[float],
    eps: float = 1e-3,
    weights: str = "relative",
    fixed: Any = None,
    dtheta_min: float = 1e-6,
    dphi_min: float = 1e-3,
    *,
    dvnls_min: float = 1e-3,
    ftol: float = 1e-6,
    max_outer: int = 20,
    max_inner: int = 10,
    lambda0: float = 1e-2,
    p_range: Any = None,
    threshold: float = 1e-6,
    callback: Callback | None = None,
) -> PathResult:
    """A warm-started sweep of :func:`fit_l21` from the largest gamma to the smallest.

    Each fit starts from the previous result, as in section 5.3 of the
    paper; the weights are recomputed at each start. Arguments as in
    :func:`fit_l21`.

    Returns
    -------
    PathResult
        One :class:`L21Result` per gamma, largest gamma first.
    """
    gs = real_array(gammas, "gammas", ndim=1)
    if gs.size == 0 or np.any(gs < 0):
        raise ValueError("gammas: needs at least one value, all >= 0")
    settings, rng, sup = _l21_settings(
        model,
        data,
        p_range,
        eps=eps,
        weights=weights,
        dtheta_min=dtheta_min,
        dphi_min=dphi_min,
        dvnls_min=dvnls_min,
        threshold=threshold,
        ftol=ftol,
        max_outer=max_outer,
        max_inner=max_inner,
        lambda0=lambda0,
    )
    problem = build_problem(model, data)
    raws = _core.l21_path(
        problem, model.theta, sup, gs, free_mask(model, fixed), settings, _callback(callback)
    )
    thr = settings["threshold"]
    return PathResult([_l21_result(raw, model, data, g, rng, thr) for g, raw in raws])
