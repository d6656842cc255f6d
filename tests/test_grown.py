"""Starts grown over the points, and when identify tries them (issue 58, item 1)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import lpvid
from lpvid.data.schedule import propagation_order
from lpvid.fit.cost import vnls_value
from lpvid.initial import grown
from lpvid.initial.grown import grown_everywhere, grown_start
from lpvid.pipeline import misfit
from lpvid.testing import noisy_data, one_group_lpv, worst_relative_error

FIXED = {"D": True}


def _measured(true, points, freqs, draw):
    """One FRF per value, its noise drawn from the draw and the value's bits (as bench_plan.py)."""
    return lpvid.FrfData.stack(
        [
            noisy_data(
                true,
                [p],
                freqs,
                np.random.default_rng(
                    [7000 + draw, int.from_bytes(np.float64(p).tobytes(), "little")]
                ),
                0.01,
            )
            for p in points
        ]
    )


@pytest.fixture(scope="module")
def small():
    """A one-group system of order 2 at five points, and its local models."""
    true = one_group_lpv(0, n=2)
    f = np.linspace(5, 60, 40)
    data = noisy_data(true, [0.0, 0.2, 0.45, 0.7, 1.0], f, np.random.default_rng(3), 0.01)
    local = lpvid.identify_lti(data, 2, strictly_proper=True)
    return true, f, data, local


def test_local_models_of_some_points_carry_their_figures(small):
    _, _, data, local = small
    sub = local.subset([3, 1])
    np.testing.assert_array_equal(sub.p, local.p[[3, 1]])
    np.testing.assert_array_equal(sub.vnls, local.vnls[[3, 1]])
    assert sub[0] is local[3] and len(sub) == 2
    with pytest.raises(ValueError, match="indices in 0..4"):
        local.subset([5])


def test_a_grown_start_fits_every_point_from_the_walk_of_its_root(small, monkeypatch):
    true, f, data, local = small
    joined = []

    def fit_nls(model, points, *args, **kwargs):
        joined.append(list(points.p))
        return lpvid.fit_nls(model, points, *args, **kwargs)

    monkeypatch.setattr(grown, "fit_nls", fit_nls)
    c = grown_start(data, 2, true.basis, FIXED, local, None, 100, 1e-10, 4)
    # after the seed (the root's two nearest points and itself), one point more a fit
    assert joined == [[0.2, 0.45, 0.7, 1.0], [0.0, 0.2, 0.45, 0.7, 1.0]]
    walk = [int(q) for q in propagation_order(data.p_rows, 4)[0]]
    assert walk == [4, 3, 2, 1, 0]
    assert c.name == "grown@4" and "points [2, 3, 4]" in c.note and "[1, 0] joined" in c.note
    assert c.noise_floor == data.n_residuals
    # its V_NLS is the model's on every point, evaluated anew
    assert c.vnls == pytest.approx(vnls_value(c.model, data), rel=1e-9)
    assert c.vnls < 1.2 * data.n_residuals
    assert c.model.p_range == [0.0, 1.0]
    assert worst_relative_error(c.model, true, f, np.linspace(0.05, 0.95, 10)) < 0.02


def test_no_growth_where_the_first_fit_has_every_point(small):
    true, _, data, local = small
    three, local3 = data.subset([0, 2, 4]), local.subset([0, 2, 4])
    assert grown_everywhere(three, 2, true.basis, FIXED, local3, ftol=1e-4) == []
    names = [c.name for c in grown_everywhere(data, 2, true.basis, FIXED, local, ftol=1e-4)]
    assert names == [f"grown@{q}" for q in range(5)]


def test_a_root_whose_growth_meets_a_point_it_cannot_evaluate_gives_no_start(small, monkeypatch):
    true, _, data, local = small

    def vnls_value(model, points):  # the model so far overflows at the fourth point to join
        return np.inf if points.n_points == 4 else lpvid.fit.cost.vnls_value(model, points)

    monkeypatch.setattr(grown, "vnls_value", vnls_value)
    assert grown_start(data, 2, true.basis, FIXED, local, None, 100, 1e-10, 4) is None
    assert grown_everywhere(data, 2, true.basis, FIXED, local, ftol=1e-4) == []


def test_a_far_start_is_judged_against_the_local_models_level(small):
    _, _, data, local = small
    floor = data.n_residuals
    ref = max(1.0, misfit.local_level(local))
    assert misfit.far_fit(1.1 * ref * floor, floor, local) is None
    said = misfit.far_fit(1.3 * ref * floor, floor, local)
    assert said is not None and "times its noise floor" in said
    # local models that fit worse raise the level the model is judged against
    worse = lpvid.LocalModels(
        list(local), local.p, vnls=1.5 * local.vnls, noise_floor=local.noise_floor
    )
    level = misfit.local_level(worse)
    assert level > 1.2
    assert misfit.far_fit(1.15 * level * floor, floor, worse) is None
    assert misfit.far_fit(1.25 * level * floor, floor, worse) is not None


def test_identify_grows_starts_only_when_the_best_start_is_far(small, monkeypatch):
    true, _, data, _ = small
    plain = lpvid.identify(data, 2, true.basis, fixed=FIXED)
    monkeypatch.setattr(misfit, "FAR", 0.0)  # every fit is far: grown starts, and still far
    with pytest.warns(lpvid.ConvergenceWarning, match="after starts grown over the points too"):
        tried = lpvid.identify(data, 2, true.basis, fixed=FIXED)
    assert "still far: the model sat at" in tried.reason
    assert not any(c.name.startswith("grown@") for c in plain.candidates)
    assert [c.name for c in tried.candidates if c.name.startswith("grown@")] == [
        f"grown@{q}" for q in range(5)
    ]
    assert "starts grown over the points were tried" in tried.reason
    assert "starts grown" not in plain.reason


def test_where_every_start_missed_the_basin_a_grown_one_finds_it():
    """``one_group_lpv(20)`` at eight points: local models at some points miss one of three
    close modes, and every start of the usual routes ended 1.40 times above the floor (0.032
    off between the points)."""
    true = one_group_lpv(20)
    f = np.linspace(2, 100, 120)
    data = _measured(true, [0.0, 0.12, 0.3, 0.5, 0.692, 0.8, 0.86, 1.0], f, 20)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lpvid.ConvergenceWarning)
        res = lpvid.identify(data, 10, true.basis, fixed=FIXED)
    usual = [c for c in res.candidates if not c.name.startswith("grown@")]
    assert min(c.vnls for c in usual) > 1.3 * data.n_residuals
    assert res.start.startswith("grown@")
    assert res.entry.vnls < 1.05 * data.n_residuals
    assert worst_relative_error(res.model, true, f, np.linspace(0.01, 0.99, 20)) < 0.01
