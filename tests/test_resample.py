"""Resampling: identify again on data simulated from the model returned (issue 58, item 2).

The noise model is checked against its statistics, the spread's rule on
stand-in models at known distances, and the whole on the model-reduction
community's synthetic system at three points against its known truth
(``benches/bench_few.py --resample 5`` measures the same over many draws).
"""

from __future__ import annotations

import dataclasses
import types
import warnings

import numpy as np
import pytest
from systems import SYNTHETIC as TRUE
from systems import SYNTHETIC_FIXED as FIXED
from systems import SYNTHETIC_FREQS as FREQS
from systems import SYNTHETIC_UNSEEN as UNSEEN
from systems import synthetic_data as _data

import lpvid
from lpvid.data.noise import circular_noise
from lpvid.pipeline.between import RESAMPLED_SCALE, Between, Member
from lpvid.pipeline.resample import simulated


def test_circular_noise_is_lpvid_noise_model():
    """|e|^2 / sigma^2 is exponential with mean 1; real and imaginary parts independent, alike."""
    rng = np.random.default_rng(1)
    sigma = 0.1 + rng.random((50, 40, 2, 1))
    e = np.concatenate([circular_noise(sigma, rng) / sigma for _ in range(50)]).ravel()
    n = e.size  # 200 000 draws: the means below are within 4 / sqrt(n) of theirs
    assert abs(np.mean(np.abs(e) ** 2) - 1.0) < 4 / np.sqrt(n)
    assert abs(np.mean(e.real**2) - 0.5) < 4 * np.sqrt(0.5) / np.sqrt(n)
    assert abs(np.mean(e.imag**2) - 0.5) < 4 * np.sqrt(0.5) / np.sqrt(n)
    assert abs(np.mean(e.real * e.imag)) < 4 * 0.5 / np.sqrt(n)
    assert circular_noise(sigma, np.random.default_rng(2)).shape == sigma.shape


def test_simulated_data_are_the_model_within_the_noise():
    """Same points, lines, sigma; the model's V_NLS on them is M on average (the noise floor)."""
    data = _data([0.02, 0.5, 1.0])
    rng = np.random.default_rng(3)
    costs = []
    for _ in range(40):
        sim = simulated(TRUE, data, rng)
        assert np.array_equal(sim.p, data.p) and np.array_equal(sim.freqs_hz, data.freqs_hz)
        assert np.array_equal(sim.sigma, data.sigma) and sim.Ts == data.Ts
        costs.append(lpvid.vnls(TRUE, sim))
    m = data.n_residuals  # V_NLS of the truth: mean M, standard deviation sqrt(M)
    assert abs(np.mean(costs) - m) < 4 * np.sqrt(m / len(costs))
    assert 0.5 < np.std(costs) / np.sqrt(m) < 1.5
    # the noise is the data's, around the model's own FRF: not the data's values
    G = TRUE.frf(FREQS, data.p)
    assert np.allclose(np.mean(np.abs(sim.G - G) ** 2 / data.sigma**2), 1.0, atol=0.05)


def _scaled(model, c):
    """The model's FRF times 1 + c (C and D scaled)."""
    return lpvid.LpvModel(
        model.A, model.B, model.C * (1 + c), model.D * (1 + c), basis=model.basis, Ts=model.Ts
    )


def test_the_spread_of_resampled_models_is_the_scale_times_their_median_distance():
    data = _data([0.02, 0.5, 1.0])
    cs = [0.01, -0.02, 0.04, 0.005, -0.03]  # median distance 0.02 |G|
    between = Between(TRUE, data=data, resampled=[_scaled(TRUE, c) for c in cs])
    G = TRUE.frf(FREQS, UNSEEN)
    expect = RESAMPLED_SCALE * 0.02 * np.abs(G)
    np.testing.assert_allclose(between.spread(FREQS, UNSEEN), expect, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(
        between.relative_spread(FREQS, UNSEEN), RESAMPLED_SCALE * 0.02, rtol=1e-9
    )
    said = f"{RESAMPLED_SCALE:g} times the median distance of the 5 models identified again"
    assert said in between.summary() and "other fit(s) counted above" not in between.summary()
    assert "lpvid.resampled(result)" not in between.summary()  # done: no advice to do it
    assert between.worst()[0] == pytest.approx(RESAMPLED_SCALE * 0.02, rel=1e-9)
    # without them: the band and the committee (none here: no spread at all)
    assert not np.any(Between(TRUE, data=data).spread(FREQS, UNSEEN))


def _member(c: float, stable: bool = True) -> Member:
    """A fit of the committee whose FRF is the truth's times 1 + c."""
    return Member(0, 0, f"blocks:0, gamma {c}", _scaled(TRUE, c), 1.0, stable)


def test_the_resampled_spread_pools_the_runs_with_the_committees_voters():
    """The median is over the resampled models and the run's stable fits within the noise."""
    data = _data([0.02, 0.5, 1.0])
    runs = [_scaled(TRUE, c) for c in [0.01, -0.02, 0.04, 0.005, -0.03]]
    G = TRUE.frf(FREQS, UNSEEN)

    def median_of(between):
        rel = between.relative_spread(FREQS, UNSEEN) / RESAMPLED_SCALE
        np.testing.assert_allclose(rel, rel[0], rtol=1e-9)
        np.testing.assert_allclose(
            between.spread(FREQS, UNSEEN), RESAMPLED_SCALE * rel[0] * np.abs(G), rtol=1e-9
        )
        return rel[0]

    # three far voters: 0.005 0.01 0.02 0.03 0.04 0.1 0.2 0.3, median 0.035
    far = Between(TRUE, [_member(c) for c in (0.1, -0.2, 0.3)], data=data, resampled=runs)
    assert median_of(far) == pytest.approx(0.035)
    assert "and of the 3 other fit(s) counted above" in far.summary()
    # one near voter: 0.001 0.005 0.01 0.02 0.03 0.04, median 0.015
    near = Between(TRUE, [_member(0.001)], data=data, resampled=runs)
    assert median_of(near) == pytest.approx(0.015)
    # an unstable member is left out while a stable one counts
    mixed = Between(TRUE, [_member(0.001), _member(0.5, stable=False)], data=data, resampled=runs)
    assert median_of(mixed) == pytest.approx(0.015)
    assert "1 of them unstable between the points, left out of the spread" in mixed.summary()
    # when none is stable, every member counts (as in the committee's spread)
    unstable = Between(TRUE, [_member(0.5, stable=False)], data=data, resampled=runs)
    assert median_of(unstable) == pytest.approx(0.025)


@pytest.fixture(scope="module")
def three_points():
    data = _data([0.02, 0.45, 1.0], seed=5)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lpvid.ConvergenceWarning)
        res = lpvid.identify(data, 10, TRUE.basis, fixed=FIXED)
        again = lpvid.resampled(res)
    return res, again


def test_resampling_gives_a_spread_that_covers_the_truth_and_says_how_far(three_points):
    """At three points: the spread is at least the worst error and within ten times it.

    (This draw: 0.998-1.0 of the lines and points covered and the spread
    3.9-7.0 times the error over the seeds 0-3, both routes: the test asks
    0.8 and [1, 10], a margin for the last bits of other processors.)
    """
    res, again = three_points
    assert res.between.resampled == [] and len(again.between.resampled) == 5
    assert not res.between.determined and "lpvid.resampled(result)" in res.between.summary()
    assert again.model is res.model and again.timings["resample_s"] > 0
    G, Gt = res.model.frf(FREQS, UNSEEN), TRUE.frf(FREQS, UNSEEN)
    err = np.abs(G - Gt)
    spread = again.between.spread(FREQS, UNSEEN)
    assert np.mean(err <= spread) >= 0.8
    ref = np.linalg.norm(Gt.reshape(len(UNSEEN), -1), axis=1)
    worst_err = np.max(np.linalg.norm(err.reshape(len(UNSEEN), -1), axis=1) / ref)
    worst_spread = np.max(np.linalg.norm(spread.reshape(len(UNSEEN), -1), axis=1) / ref)
    assert 1.0 <= worst_spread / worst_err <= 10.0
    # the same seed, the same models; another seed, others
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lpvid.ConvergenceWarning)
        models = [m.theta for m in lpvid.resampled(res, 2).between.resampled]
        other = lpvid.resampled(res, 1, seed=1).between.resampled[0]
    assert all(
        np.array_equal(a, b.theta) for a, b in zip(models, again.between.resampled[:2], strict=True)
    )
    assert not np.array_equal(other.theta, models[0])


def test_where_to_measure_is_the_committees_whatever_the_resampling(three_points):
    """next_points follows this run's fits within the noise, not the resampled models."""
    res, again = three_points
    before, after = lpvid.suggest_points(res), lpvid.suggest_points(again)
    assert after.criterion == before.criterion == "committee"
    np.testing.assert_array_equal(after.points, before.points)
    np.testing.assert_array_equal(after.band, before.band)
    # the band the plan works on is the committee's spread, not the resampled one
    grid = after.grid if after.grid.ndim > 1 else after.grid[:, None]
    f = res.data.freqs_hz
    resampled = again.between.relative_spread(f, grid)
    assert not np.allclose(after.band, resampled, rtol=0.1)
    committee = dataclasses.replace(again.between, resampled=[])
    np.testing.assert_array_equal(after.band, committee.relative_spread(f, grid))
    # resampled models without a committee: the covariance's design, as without them
    alone = dataclasses.replace(again.between, members=[])
    plan = lpvid.suggest_points(dataclasses.replace(again, between=alone))
    assert plan.criterion != "committee"


def test_bad_arguments_are_refused_with_what_they_should_be(three_points):
    res, _ = three_points
    with pytest.raises(TypeError, match="IdentifyResult"):
        lpvid.resampled(res.model)
    with pytest.raises(ValueError, match="holds no problem"):
        lpvid.resampled(dataclasses.replace(res, problem=None))
    with pytest.raises(ValueError, match="time records"):
        lpvid.resampled(dataclasses.replace(res, problem=types.SimpleNamespace(time_data=1)))
    with pytest.raises(ValueError, match="draws"):
        lpvid.resampled(res, 0)
    with pytest.raises(TypeError, match="seed"):
        lpvid.resampled(res, 1, seed="x")
    with pytest.raises(TypeError, match="^progress: expected a callable"):
        lpvid.resampled(res, 1, progress=True)


def test_each_run_gets_its_own_simulated_data_and_validation_data(three_points, monkeypatch):
    """Validation data are simulated at their points too; the runs' warnings are said."""
    from lpvid.pipeline import resample

    res, _ = three_points
    val = _data([0.3, 0.7], seed=9)
    problem = dataclasses.replace(res.problem, validation=val)
    seen = []

    def identify(p):
        seen.append(p)
        warnings.warn(f"run {len(seen)} warned", lpvid.ConvergenceWarning, stacklevel=2)
        return types.SimpleNamespace(model=res.model)

    monkeypatch.setattr(resample, "identify", identify)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the runs' warnings are said, not raised
        again = lpvid.resampled(dataclasses.replace(res, problem=problem), 3)
    assert again.between.resampled_warned == ["run 1 warned", "run 2 warned", "run 3 warned"]
    assert "3 of those runs warned, the first: run 1 warned" in again.between.summary()
    assert len(seen) == 3 and all(p.order == 10 and p.basis is TRUE.basis for p in seen)
    for p in seen:
        assert np.array_equal(p.validation.p, val.p) and np.array_equal(p.data.p, res.data.p)
        assert not np.array_equal(p.validation.G, val.G)  # simulated, not the measured ones
        sim = p.validation.G - res.model.frf(val.freqs_hz, val.p)
        assert np.mean(np.abs(sim) ** 2 / val.sigma**2) < 2.0  # the noise, around the model
    assert not np.array_equal(seen[0].data.G, seen[1].data.G)  # a noise draw each
