"""Fits that keep every frozen model on the scheduling range stable (``stable=True``).

The core refuses a trial step when the smallest stability margin it finds
on a set of check points is below :data:`STABLE_TOL` (``rust/fit/stable.rs``):
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
the same unstable place. With one parameter the whole window of
instability is added, densely (:func:`window_points`).

**Real poles near the origin.** In continuous time the margin is a
damping ratio, which is 1 for a real pole however near the origin it is:
at the check points a fit could bring a real pole to ``-1e-15`` and push
it across zero in a window between them, unseen, round after round (seen
on ``lpvid.testing.synthetic_parametric`` at four points: the window moved
by 1e-5 each round). The fits' check points therefore measure every pole
against ``max(|lambda|, floor)`` with ``floor`` the lowest measured angular
frequency (:func:`pole_floor`): a real pole must stay ``STABLE_TOL *
floor`` left of the origin, a pole a million times slower than the data
reach, so that the margin falls continuously as a pole nears zero and a
window between the check points is rare and wide enough to be added
whole. :func:`lpvid.stability` and the margins it reports are unchanged.
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

__all__ = [
    "STABLE_TOL",
    "check_points",
    "pole_floor",
    "run_stable",
    "stabilised",
    "window_points",
]

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
#: Check points added over a window of instability found between the check
#: points (one parameter), from the check point before it to the one after.
WINDOW_POINTS = 129


def pole_floor(model: LpvModel, data: Any) -> float:
    """The floor of the fits' check-point margins: the lowest measured angular frequency.

    0 (no floor) in discrete time and without measured frequencies above
    zero (module notes).
    """
    if model.Ts is not None or data is None:
        return 0.0
    f = np.asarray(data.freqs_hz, dtype=float)
    f = f[f > 0]
    return float(2.0 * np.pi * f.min()) if f.size else 0.0


def check_points(
    model: LpvModel, pairs: list[tuple[float, float]], extra: list[Any], floor: float = 0.0
) -> Any:
    """The core's check points for ``model`` over the range, with ``extra`` scheduling values.

    Their margins measure every pole against ``max(|lambda|, floor)``
    (continuous time; module notes).
    """
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
    return _core.FrozenRange(view, stride, model.Ts is not None, STABLE_TOL, floor)


def window_points(rep: Any, pairs: list[tuple[float, float]], scale: str) -> list[Any]:
    """The unstable place a check found and, with one parameter, its window densely sampled.

    The window is the pair of the report's crossings around ``rep.worst_p``:
    :data:`WINDOW_POINTS` points spread over it and one check-point spacing
    on either side (evenly on the basis's scale), and ``worst_p``. With
    several parameters, ``worst_p`` alone.
    """
    if len(pairs) != 1 or rep.crossings.size == 0:
        return [rep.worst_p]
    worst = float(np.ravel(rep.worst_p)[0])
    lo, hi = pairs[0]
    log = scale == "log"
    u = np.array([lo, hi, worst, *rep.crossings], dtype=float)
    u = np.log10(u) if log else u
    (ulo, uhi, uw), cross = u[:3], u[3:]
    a = float(cross[cross <= uw].max(initial=uw))
    b = float(cross[cross >= uw].min(initial=uw))
    step = (uhi - ulo) / (CHECK_POINTS - 1)
    pts = np.linspace(max(ulo, a - step), min(uhi, b + step), WINDOW_POINTS)
    return [*np.clip(10.0**pts if log else pts, lo, hi), worst]


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
    floor: float = 0.0,
) -> FitOutcome:
    """Run a fit that keeps stability: ``run(check_points)`` returns the core's outcome.

    ``floor``: that of the check points' margins (:func:`pole_floor`).

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
    points = check_points(model, pairs, [], floor)
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
        raw = run(points if not extra else check_points(model, pairs, extra, floor))
        if raw.interrupted:
            return raw
        fitted = model.with_theta(raw.theta)
        rep = stability(fitted, start.p_range, quadratic=False)
        if rep.stable:
            return raw
        extra.extend(window_points(rep, pairs, model.basis.scales[0]))
    raise RuntimeError(
        f"stable=True: after {MAX_ROUNDS} rounds the fit still leaves the stable set between "
        f"the check points (at p = {format_p(extra[-1])}); this should not happen, please report it"
    )
