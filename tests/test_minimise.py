"""Brent's bounded minimiser against scipy's and known minima."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import minimize_scalar

from lpvid._minimise import minimise_bounded

CASES = [
    # (function, a, b, the minimiser)
    (lambda x: (x - 0.3) ** 2, -1.0, 2.0, 0.3),
    (lambda x: abs(x - 0.71), 0.0, 1.0, 0.71),
    (lambda x: math.cos(x), 0.0, 5.0, math.pi),
    (lambda x: (x - 1e-3) ** 4, -1e-2, 1e-2, 1e-3),
    (lambda x: x * x * (x - 1.5), 0.2, 3.0, 1.0),
    (lambda x: math.exp(x), -1.0, 1.0, -1.0),  # at the lower bound
    (lambda x: -math.log(x), 0.5, 4.0, 4.0),  # at the upper bound
]


@pytest.mark.parametrize("case", range(len(CASES)))
def test_finds_the_minimiser_as_scipy_does(case: int) -> None:
    """The minimiser to the tolerance asked, in about as many evaluations as scipy's Brent."""
    f, a, b, truth = CASES[case]
    xatol = 1e-12 * (b - a)
    x, fx, evals = minimise_bounded(f, a, b, xatol)
    ref = minimize_scalar(f, bounds=(a, b), method="bounded", options={"xatol": xatol})
    assert fx == f(x)
    assert a < x < b
    tol = 1e-6 * (b - a) if truth in (a, b) else 1e-7 * (b - a)
    assert abs(x - truth) <= tol, (x, truth)
    assert abs(x - ref.x) <= tol
    assert fx <= float(ref.fun) + 1e-12 * (1.0 + abs(float(ref.fun)))
    assert evals <= int(ref.nfev) + 5, (evals, ref.nfev)


def test_counts_every_evaluation_and_stops_at_max_evals() -> None:
    """``evals`` is the number of calls; ``max_evals`` bounds it."""
    calls: list[float] = []

    def f(x: float) -> float:
        calls.append(x)
        return math.sin(3.0 * x) + 0.1 * x

    x, fx, evals = minimise_bounded(f, 0.0, 4.0, 1e-12)
    seen = list(calls)
    assert evals == len(seen) and x in seen and fx == min(f(c) for c in seen)
    calls.clear()
    _, _, evals = minimise_bounded(f, 0.0, 4.0, 1e-12, max_evals=4)
    assert evals == len(calls) == 4


def test_a_coarse_tolerance_takes_fewer_steps() -> None:
    """The stopping rule reads xatol: a coarse one stops early, within it of the minimiser."""
    f = lambda x: abs(x - 0.123456)  # noqa: E731
    fine = minimise_bounded(f, 0.0, 1.0, 1e-12)
    coarse = minimise_bounded(f, 0.0, 1.0, 1e-2)
    assert coarse[2] < fine[2]
    assert abs(coarse[0] - 0.123456) <= 1e-2
    assert abs(fine[0] - 0.123456) <= 1e-9


@pytest.mark.parametrize(
    ("a", "b", "xatol", "max_evals", "what"),
    [
        (1.0, 1.0, 1e-9, 10, "interval"),
        (2.0, 1.0, 1e-9, 10, "interval"),
        (0.0, np.inf, 1e-9, 10, "interval"),
        (np.nan, 1.0, 1e-9, 10, "interval"),
        (0.0, 1.0, 0.0, 10, "xatol"),
        (0.0, 1.0, np.nan, 10, "xatol"),
        (0.0, 1.0, 1e-9, 0, "max_evals"),
    ],
)
def test_refuses_what_it_cannot_search(
    a: float, b: float, xatol: float, max_evals: int, what: str
) -> None:
    """An empty or infinite interval, a tolerance that is not > 0, no evaluation allowed."""
    with pytest.raises(ValueError, match=what):
        minimise_bounded(lambda x: x, a, b, xatol, max_evals=max_evals)
