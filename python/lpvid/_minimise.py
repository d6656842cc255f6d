"""Minimisation of a function of one variable on an interval (Brent's method).

Written here rather than taken from ``scipy.optimize.minimize_scalar``:
importing ``scipy.optimize`` costs 0.2-0.5 s on the 2-core machine, paid by
the first stability check of every process (``lpvid demo``, each CLI run),
for a routine of a few dozen lines.
"""

from __future__ import annotations

import math
from collections.abc import Callable

__all__ = ["minimise_bounded"]

#: The golden section's smaller part, (3 - sqrt(5)) / 2.
_GOLDEN = 0.5 * (3.0 - math.sqrt(5.0))

#: Relative accuracy that no tolerance can beat: sqrt of the machine epsilon.
_SQRT_EPS = math.sqrt(2.220446049250313e-16)


def minimise_bounded(
    f: Callable[[float], float], a: float, b: float, xatol: float, max_evals: int = 500
) -> tuple[float, float, int]:
    """A local minimum of ``f`` on ``[a, b]`` by Brent's method.

    Golden-section steps, replaced by the minimum of the parabola through
    the three best points whenever that falls well inside the bracket and
    shrinks it fast enough (R. P. Brent, *Algorithms for Minimization
    without Derivatives*, 1973, chapter 5). ``f`` is never evaluated at
    ``a`` or ``b`` themselves.

    Parameters
    ----------
    f : callable
        The function, ``float -> float``.
    a, b : float
        The interval, ``a < b``.
    xatol : float
        Absolute accuracy of the minimiser, > 0 (to which the method adds
        ``sqrt(eps) |x|``).
    max_evals : int
        Most evaluations of ``f``.

    Returns
    -------
    x : float
        The point found.
    fx : float
        ``f(x)``.
    evals : int
        Evaluations of ``f``.

    Raises
    ------
    ValueError
        When ``a < b`` does not hold, ``xatol`` is not a finite number > 0,
        or ``max_evals`` is below 1.
    """
    if not (math.isfinite(a) and math.isfinite(b) and a < b):
        raise ValueError(f"the interval must be finite with a < b, got [{a}, {b}]")
    if not (math.isfinite(xatol) and xatol > 0.0):
        raise ValueError(f"xatol must be a finite number > 0, got {xatol}")
    if max_evals < 1:
        raise ValueError(f"max_evals must be at least 1, got {max_evals}")
    x = w = v = a + _GOLDEN * (b - a)
    fx = fw = fv = float(f(x))
    evals = 1
    step = last = 0.0  # the latest step, and the one before it
    while evals < max_evals:
        mid = 0.5 * (a + b)
        tol = _SQRT_EPS * abs(x) + xatol / 3.0
        if abs(x - mid) <= 2.0 * tol - 0.5 * (b - a):
            break
        golden = True
        if abs(last) > tol:
            # The parabola through (v, fv), (w, fw), (x, fx): its minimum is
            # at x + p / q.
            r = (x - w) * (fx - fv)
            q = (x - v) * (fx - fw)
            p = (x - v) * q - (x - w) * r
            q = 2.0 * (q - r)
            if q > 0.0:
                p = -p
            q = abs(q)
            before = last
            last = step
            # Taken when inside the bracket and shorter than half the step
            # before last (otherwise it may crawl).
            if abs(p) < abs(0.5 * q * before) and q * (a - x) < p < q * (b - x):
                step = p / q
                if (x + step) - a < 2.0 * tol or b - (x + step) < 2.0 * tol:
                    step = tol if x < mid else -tol
                golden = False
        if golden:
            last = (b - x) if x < mid else (a - x)
            step = _GOLDEN * last
        u = x + (step if abs(step) >= tol else math.copysign(tol, step))
        fu = float(f(u))
        evals += 1
        if fu <= fx:
            if u < x:
                b = x
            else:
                a = x
            v, fv, w, fw, x, fx = w, fw, x, fx, u, fu
        else:
            if u < x:
                a = u
            else:
                b = u
            if fu <= fw or w == x:
                v, fv, w, fw = w, fw, u, fu
            elif fu <= fv or v in (x, w):
                v, fv = u, fu
    return x, fx, evals
