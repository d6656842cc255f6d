"""The parts of lpvid.experiment.nextpoints: candidates, grids, noise, refusals and the summary.

Small and direct (the private helpers called on their own where that is
clearest); each test names the wrong code it rejects. The criterion itself
is checked against recomputed covariances in test_nextpoints.py.
"""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np
import pytest

import lpvid
from lpvid.experiment.nextpoints import Suggestion, _candidates, _noise, default_candidates
from lpvid.testing import noisy_data, one_group_lpv

RADIUS = np.sqrt(np.log(20.0))  # the 95 % band of a circular complex Gaussian


@pytest.fixture(scope="module")
def res():
    """A small identify result: one mode, affine in p, three points on [0, 1]."""
    true = one_group_lpv(0, n=2)
    lines = np.linspace(5.0, 60.0, 12)
    data = noisy_data(true, [0.0, 0.5, 1.0], lines, np.random.default_rng(0), 0.01)
    return lpvid.identify(data, 2, lpvid.Polynomial(1, domain=(0.0, 1.0)), fixed={"D": True})


def test_one_point_by_default(res):
    """Rejects next_points suggesting more than one point when k is not given."""
    pts = lpvid.next_points(res)
    assert pts.shape == (1,)
    s = lpvid.suggest_points(res)
    np.testing.assert_array_equal(pts, s.points)
    assert s.variance.shape == (2,) and len(s.summary().splitlines()) == 2


def test_the_summary_states_the_rms_band_now_and_after_each_point():
    """Rejects a summary with the wrong radius, the wrong variance or wrong numbering."""
    s = Suggestion(
        points=np.array([[0.25, 3.0], [0.75, 1.5]]),
        measured=np.zeros((2, 2)),
        grid=np.zeros((4, 2)),
        band=np.array([0.1, 0.4, 0.2, 0.3]),
        band_after=np.array([0.05, 0.1, 0.1, 0.1]),
        variance=np.array([0.04, 0.01, 0.0025]),
        p_range=[(0.0, 1.0), (0.0, 4.0)],
    )
    rms = [f"{RADIUS * v:.3g}" for v in (0.2, 0.1, 0.05)]
    assert s.summary().splitlines() == [
        f"where to measure next (RMS relative 95 % band over the range now {rms[0]}; "
        "the largest 0.4)",
        f"  1. p = 0.25, 3: RMS band -> {rms[1]}",
        f"  2. p = 0.75, 1.5: RMS band -> {rms[2]}",
    ]
    one = dataclasses.replace(s, points=np.array([0.5]), variance=np.array([1e-4, -1e-20]))
    lines = one.summary().splitlines()
    assert f"now {RADIUS * 0.01:.3g};" in lines[0]
    assert lines[1:] == ["  1. p = 0.5: RMS band -> 0"]  # a rounding below zero is zero


@pytest.mark.parametrize(("n_params", "per_axis"), [(1, 101), (2, 21), (3, 9), (4, 5), (5, 5)])
def test_the_default_grid_less_the_measured_values(n_params, per_axis):
    """Rejects a grid of the wrong size for 1 to 5 parameters, or measured values kept."""
    pairs = [(2.0, 6.0)] + [(-1.0, 1.0)] * (n_params - 1)
    axes = [np.linspace(lo, hi, per_axis) for lo, hi in pairs]
    grid = np.array(list(itertools.product(*axes)))
    measured = grid[[0, len(grid) // 2]] + 1e-12  # within the slack
    rows = default_candidates(pairs if n_params > 1 else pairs[0], measured)
    assert rows.shape == (per_axis**n_params - 2, n_params)
    left = {tuple(r) for r in grid} - {tuple(grid[0]), tuple(grid[len(grid) // 2])}
    assert {tuple(r) for r in rows} == left


def test_default_candidates_take_measured_values_as_data_p_holds_them():
    """Rejects measured values of one parameter refused as (N,), or of three dimensions taken."""
    rows = default_candidates((0.0, 1.0), [0.0, 0.5])  # data.p of one parameter: (N,)
    np.testing.assert_array_equal(rows[:, 0], np.delete(np.linspace(0.0, 1.0, 101), [0, 50]))
    with pytest.raises(ValueError, match="^measured: "):
        default_candidates((0.0, 1.0), np.zeros((2, 1, 1)))


def test_candidates_in_a_range_away_from_zero():
    """Rejects candidates scaled to the range with the wrong offset or width."""
    pairs = [(2.0, 6.0)]
    got = _candidates([6.0, 2.0, 4.0, 6.0, 2.0 + 1e-12], pairs)
    np.testing.assert_array_equal(got, [[6.0], [2.0], [4.0], [2.0 + 1e-12]])  # repeats once
    np.testing.assert_array_equal(_candidates(3.0, pairs), [[3.0]])  # one value
    np.testing.assert_array_equal(_candidates([[3.0], [5.0]], pairs), [[3.0], [5.0]])
    for bad in (1.9, 6.5, 7.0, -2.0):
        with pytest.raises(ValueError, match="^candidates: 1 value"):
            _candidates([4.0, bad], pairs)
    with pytest.raises(ValueError, match="^candidates: "):
        _candidates(np.full((2, 1, 1), 3.0), pairs)
    with pytest.raises(ValueError, match="^candidates: expected at least one scheduling value"):
        _candidates(np.zeros(0), pairs)
    with pytest.raises(ValueError, match="^candidates: .*NaN"):
        _candidates([3.0, np.nan], pairs)


def test_the_refusal_lists_the_values_outside():
    """Rejects the values outside, their separators, the count left out or the range garbled."""
    pairs = [(0.0, 1.0)]
    with pytest.raises(ValueError) as info:
        _candidates([0.5, -1, -2, -3, -4, -5, -6, -7], pairs)
    message = str(info.value)
    assert message.startswith("candidates: 7 value(s) outside the scheduling range (0, 1), ")
    assert message.endswith(": -1; -2; -3; -4; -5 and 2 more")
    for n, tail in ((5, ": -1; -2; -3; -4; -5"), (6, ": -1; -2; -3; -4; -5 and 1 more")):
        with pytest.raises(ValueError) as info:
            _candidates(-np.arange(1.0, n + 1), pairs)
        assert str(info.value).endswith(tail), str(info.value)
    with pytest.raises(ValueError) as info:
        _candidates([[0.5, 2.0], [0.5, 0.5], [-0.5, 0.25]], [(0.0, 1.0), (0.0, 1.0)])
    message = str(info.value)
    assert "2 value(s) outside the scheduling range (0, 1), (0, 1), " in message
    assert message.endswith(": 0.5, 2; -0.5, 0.25")


def test_the_default_noise_is_that_of_the_nearest_point_on_the_scaled_range():
    """Rejects the nearest measured point found on unscaled or wrongly scaled values."""
    # p in (2, 3) x (0, 100): the candidate (2.9, 30) is nearest (2, 0) in the raw
    # numbers, nearest (3, 100) once each parameter is scaled to its range.
    p = np.array([[2.0, 0.0], [3.0, 100.0]])
    f = np.array([1.0, 2.0])
    sigma = np.array([1.0, 5.0])[:, None, None, None] * np.ones((2, 2, 1, 1))
    data = lpvid.FrfData(p, f, np.ones((2, 2, 1, 1)), sigma=sigma)
    pairs = [(2.0, 3.0), (0.0, 100.0)]
    got = _noise(data, np.array([[2.9, 30.0], [2.1, 10.0]]), pairs, None)
    np.testing.assert_array_equal(got[:, :, 0, 0], [[5.0, 5.0], [1.0, 1.0]])


def test_a_given_noise_must_be_positive_and_fit_the_lines():
    """Rejects a zero sigma accepted, or the refusals naming another argument."""
    data = lpvid.FrfData([0.0, 1.0], [1.0, 2.0], np.ones((2, 2, 1, 1)), sigma=1.0)
    cands = np.array([[0.5]])
    np.testing.assert_array_equal(
        _noise(data, cands, [(0.0, 1.0)], 0.3), np.full((1, 2, 1, 1), 0.3)
    )
    for bad in (0.0, [[[0.2]], [[0.0]]], -1.0):
        with pytest.raises(ValueError, match="^sigma: standard deviations must be > 0"):
            _noise(data, cands, [(0.0, 1.0)], bad)
    with pytest.raises(ValueError, match="^sigma: .*NaN"):
        _noise(data, cands, [(0.0, 1.0)], np.nan)


def test_a_result_without_a_usable_covariance_is_refused_saying_why(res):
    """Rejects refusals that do not name what was given or what is missing."""
    with pytest.raises(ValueError) as info:
        lpvid.next_points(dataclasses.replace(res, covariance=None))
    message = str(info.value)
    assert message.startswith("result: has no parameter covariance (result.covariance is None)")
    assert "the suggestion is computed from it; lpvid.identify sets it" in message
    with pytest.raises(TypeError, match=r"^result\.covariance: expected an lpvid\.Covariance, "):
        lpvid.next_points(dataclasses.replace(res, covariance={}))
    with pytest.raises(TypeError, match="got dict$"):
        lpvid.next_points(dataclasses.replace(res, covariance={}))
    with pytest.raises(TypeError, match="^result: expected the IdentifyResult .* got Covariance$"):
        lpvid.next_points(res.covariance)
