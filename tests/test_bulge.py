"""A fit whose frozen FRF rises between the points far above all measured leaves the committee.

One mode, measured at the ends of the range only. The calm model keeps its
damping over the range; the bulging one has the same frozen models at both
ends but its damping falls to almost nothing in the middle, with the
mode's frequency on a measured line: the points cannot tell them apart.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import lpvid
from lpvid.pipeline import bulge as bulge_module
from lpvid.pipeline import fewpoints
from lpvid.pipeline.result import PathEntry
from lpvid.pipeline.routes import Route
from lpvid.testing import noisy_data

F0 = 10.0  # Hz, a measured line
FREQS = np.linspace(2.0, 30.0, 57)  # 0.5 Hz apart: F0 is among them
BASIS = lpvid.Polynomial(2, domain=(0.0, 1.0))
FIXED = {"D": True}


def mode(sigma_mid: float, sigma_end: float = -0.3 * 2 * np.pi * F0) -> lpvid.LpvModel:
    """``A(s) = A0 + s^2 A2``: decay ``sigma_mid`` at s = 0 (p = 0.5), ``sigma_end`` at the ends."""
    w = 2 * np.pi * F0
    A0 = np.array([[sigma_mid, w], [-w, sigma_mid]])
    A2 = (sigma_end - sigma_mid) * np.eye(2)
    zero = np.zeros((2, 2))
    B = [np.array([[1.0], [0.0]]), np.zeros((2, 1)), np.zeros((2, 1))]
    C = [np.array([[0.0, 1.0]]), np.zeros((1, 2)), np.zeros((1, 2))]
    D = [np.zeros((1, 1))] * 3
    return lpvid.LpvModel([A0, zero, A2], B, C, D, basis=BASIS)


CALM = mode(-0.3 * 2 * np.pi * F0)
BULGY = mode(-1e-4 * 2 * np.pi * F0)


def _data(points=(0.0, 1.0), seed=0):
    return noisy_data(CALM, list(points), FREQS, np.random.default_rng(seed), 0.01)


def _norm_direct(model, p):
    """``||C (j w I - A(p))^-1 B||`` over the lines, by numpy alone."""
    s = 2 * p - 1
    A = model.A[0] + s * model.A[1] + s * s * model.A[2]
    G = [model.C[0] @ np.linalg.solve(2j * np.pi * f * np.eye(2) - A, model.B[0]) for f in FREQS]
    return float(np.linalg.norm(np.array(G)))


def test_the_rise_is_the_frozen_norm_over_the_largest_measured_one():
    data = _data()
    top = max(np.linalg.norm(data.G[q]) for q in range(data.n_points))
    calm, bulgy = bulge_module.bulge(CALM, data), bulge_module.bulge(BULGY, data)
    # the calm model's norm is the same everywhere: at most the noise above the measured
    assert calm.ratio == pytest.approx(_norm_direct(CALM, float(calm.at[0])) / top, rel=1e-9)
    assert 0.9 < calm.ratio < 1.1 and not calm.bulges
    # the bulging one peaks at p = 0.5, a thousand times above
    assert float(bulgy.at[0]) == pytest.approx(0.5)
    assert bulgy.ratio == pytest.approx(_norm_direct(BULGY, 0.5) / top, rel=1e-9)
    assert bulgy.ratio > 100 and bulgy.bulges
    assert "p = 0.5 is" in bulgy.describe() and "no point sees" in bulgy.describe()
    # the points cannot tell them apart
    assert lpvid.vnls(BULGY, data) == pytest.approx(lpvid.vnls(CALM, data), rel=1e-9)


def test_a_singular_frozen_model_rises_without_bound_where_it_is_singular():
    undamped = mode(0.0)  # a pole on the imaginary axis at p = 0.5, on a measured line
    got = bulge_module.bulge(undamped, _data())
    assert got.ratio == np.inf and float(got.at[0]) == pytest.approx(0.5)


def _route(model, data, name):
    v = lpvid.vnls(model, data)
    entry = PathEntry(0.0, model, v, data.n_residuals, None, None, 1, {}, 0.0)
    return Route(name, None, [], [entry], 0, f"the {name} route", FIXED)


def test_a_bulging_member_leaves_the_committee_unless_every_one_bulges():
    data = _data()
    local = lpvid.identify_lti(data, 2, strictly_proper=True)
    routes = [_route(BULGY, data, "first"), _route(CALM, data, "blocks:0")]
    i, k, _, others = fewpoints.choose_route(routes, data, None, 0.05, local)
    assert (i, k) == (1, 0) and others == []  # without the rule: the first, a tie
    # every member bulges: they all stay, and the first of the tie is returned
    both = [routes[0], _route(BULGY, data, "blocks:0")]
    i, k, _, others = fewpoints.choose_route(both, data, None, 0.05, local)
    assert (i, k) == (0, 0) and len(others) == 1
    # with validation data the validation judges: the rule is not applied
    val = _data([0.25, 0.75], seed=1)
    for r in routes:
        r.entries[0] = PathEntry(
            0.0, r.entry.model, r.entry.vnls, data.n_residuals,
            lpvid.vnls(r.entry.model, val), val.n_residuals, 1, {}, 0.0,
        )  # fmt: skip
    i, _, _, others = fewpoints.choose_route(routes, data, val, 0.05, local)
    assert i == 1 and len(others) == 1  # the calm model validates far better


def test_identify_warns_when_the_model_it_returns_bulges(monkeypatch):
    """Every model made to bulge (the limit lowered): said in the reason and warned."""
    data = _data((0.0, 0.5, 1.0))
    monkeypatch.setattr(bulge_module, "BULGE", 1e-6)
    with pytest.warns(lpvid.ConvergenceWarning, match="not to be trusted between the points"):
        res = lpvid.identify(data, 2, BASIS, fixed=FIXED)
    assert "it bulges" in res.reason
    # validation data judge between the points: no such warning
    val = _data([0.25, 0.75], seed=1)
    with warnings.catch_warnings(record=True) as got:
        warnings.simplefilter("always")
        res = lpvid.identify(data, 2, BASIS, fixed=FIXED, validation=val)
    assert not any("not to be trusted" in str(w.message) for w in got)
    assert "bulges" not in res.reason
