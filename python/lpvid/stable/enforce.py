"""Fits that keep every frozen model on the scheduling range stable (``stable=True``).

The core refuses a trial step when the smallest stability margin it finds
on a set of check points is below :data:`STABLE_TOL` (``rust/stable.rs``):
for one scheduling parameter a uniform grid of :data:`CHECK_POINTS` points,
every :data:`STRIDE`-th evaluated first and every point next to the
smallest local minima then, so that the least stable place is resolved to
the grid spacing; for several parameters every point of a grid over the
box. Levenberg-Marquardt and the l2,1 fit treat a refused step like one
that does not lower the cost, so a fit from a stable start stays on the
check points' stable set.

After the fit, :func:`lpvid.stability` checks the continuum. Should it find
an unstable frozen model between the check points, that scheduling value
is added to them and the fit runs again from the same start (at most
:data:`MAX_ROUNDS` times), every check point then evaluated at every step:
a point added where the margin dips between two coarse samples that are
not local minima would otherwise be skipped, and the fit would return to
the same unstable place.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from lpvid import _core
from lpvid._core import FitOutcome
from lpvid.data.schedule import axis_values
from lpvid.model._view import model_view
from lpvid.model.frozen import frozen_poles
from lpvid.model.lpv import LpvModel
from lpvid.stable.ranges import as_convention, box_grid, check_range
from lpvid.stable.scan import format_p, stability

__all__ = ["STABLE_TOL", "check_points", "run_stable", "stabilised"]

#: Smallest stability margin a fit with ``stable=True`` accepts at its check
#: points (the margins of :func:`lpvid.model.frozen.stability_margin`).
STABLE_TOL = 1e-6
#: Check points of one scheduling parameter.
CHECK_POINTS = 2049
#: Every STRIDE-th check point is evaluated first.
STRIDE = 16
#: Check points over a box of several parameters (about).
BOX_POINTS = 1600
#: Fits run at most this many times (each adds the unstable place found).
MAX_ROUNDS = 3


def check_points(model: LpvModel, pairs: list[tuple[float, float]], extra: list[Any]) -> Any:
    """The core's check points for ``model`` over the range, with ``extra`` scheduling values."""
    if len(pairs) == 1:
        lo, hi = pairs[0]
        p = axis_values(lo, hi, CHECK_POINTS, model.basis.scales[0])
        stride = STRIDE
        if extra:
            p = np.unique(np.concatenate([p, np.ravel(extra)]))
            stride = 1  # the points added are always evaluated (module notes)
        pts = p[:, None]
    else:
        pts, stride = box_grid(pairs, BOX_POINTS, model.basis.scales), 1
        if extra:
            pts = np.concatenate([pts, np.asarray(extra, dtype=float).reshape(-1, len(pairs))])
    view = model_view(model, model.basis_values(pts))
    return _core.FrozenRange(view, stride, model.Ts is not None, STABLE_TOL)


def stabilised(model: LpvModel, p_range: Any = None, margin: float = 1e-3) -> LpvModel:
    """The model with every frozen model on the range made stable by moving its poles inwards.

    Discrete time: all coefficient matrices of ``A`` scaled by ``(1 - margin) /
    rho``, ``rho`` the largest spectral radius on the range, so that every
    pole is scaled towards the origin. Continuous time: ``A(0)`` shifted by
    ``-alpha I`` so that every pole lies left of ``-margin`` times the
    largest pole magnitude. A model that is already stable with at least
    this margin is returned unchanged. A start for fits with ``stable=True``.
    """
    pairs = check_range(model, p_range)
    rng = as_convention(pairs)
    rep = stability(model, rng, quadratic=False)
    if rep.stable and rep.margin >= margin:
        return model
    A = model.A.copy()
    if model.Ts is not None:
        A *= (1.0 - margin) / max(1.0 - rep.margin, 1e-300)
        return _with_A(model, A)
    pts = box_grid(pairs, 2001, model.basis.scales)
    extra = np.atleast_2d(np.asarray(rep.worst_p, dtype=float)).reshape(1, -1)
    poles = frozen_poles(model, np.concatenate([pts, extra]))
    alpha = max(float(np.max(poles.real)), 0.0) + margin * float(np.max(np.abs(poles)))
    for _ in range(20):
        A[0] = model.A[0] - alpha * np.eye(model.n_states)
        out = _with_A(model, A)
        check = stability(out, rng, quadratic=False)
        if check.stable and check.margin > 0:
            return out
        alpha *= 2.0
    raise RuntimeError("stabilised: could not move the poles into the stable region")


def _with_A(model: LpvModel, A: Any) -> LpvModel:
    return LpvModel(
        A,
        model.B,
        model.C,
        model.D,
        model.basis,
        Ts=model.Ts,
        p_range=model.p_range,
        info=model.info,
    )


def run_stable(
    model: LpvModel,
    p_range: Any,
    run: Callable[[Any], FitOutcome],
) -> FitOutcome:
    """Run a fit that keeps stability: ``run(check_points)`` returns the core's outcome.

    Raises
    ------
    ValueError
        When the start is not stable over the range (or closer to the
        boundary than :data:`STABLE_TOL`), or when the range is invalid.
    RuntimeError
        When the fit still leaves the stable set between the check points
        after :data:`MAX_ROUNDS` rounds.
    """
    pairs = check_range(model, p_range)
    start = stability(model, as_convention(pairs), quadratic=False)
    points = check_points(model, pairs, [])
    _, at_points = points.worst(model.theta)
    if not start.stable or not at_points >= STABLE_TOL:
        what = "unstable" if not start.stable else "closer to the stability boundary than allowed"
        raise ValueError(
            f"model: stable=True needs a stable start, but the frozen model at p = "
            f"{format_p(start.worst_p)} is {what} (stability margin {start.margin:.3g}, "
            f"needs >= {STABLE_TOL:g}); start from a stable model (e.g. "
            "lpvid.stable.enforce.stabilised(model)) or narrow p_range"
        )
    extra: list[Any] = []
    for _ in range(MAX_ROUNDS):
        raw = run(points if not extra else check_points(model, pairs, extra))
        if raw.interrupted:
            return raw
        fitted = model.with_theta(raw.theta)
        rep = stability(fitted, start.p_range, quadratic=False)
        if rep.stable:
            return raw
        extra.append(rep.worst_p)
    raise RuntimeError(
        f"stable=True: after {MAX_ROUNDS} rounds the fit still leaves the stable set between "
        f"the check points (at p = {format_p(extra[-1])}); this should not happen, please report it"
    )
