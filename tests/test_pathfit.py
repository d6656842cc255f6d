"""The l2,1 path of identify keeps interpolating (issue 15's goals on the built-in sets).

Both built-in sets have one scheduling point per coefficient matrix, so a
state transformation at one point alone is flat at the data; the path must
not trade the model between the points for smaller groups.
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

import lpvid
from lpvid.fit.timecost import check_time_data
from lpvid.pipeline.path import path_mode
from lpvid.testing import noisy_data, random_lpv

MAKERS = {"stage": lpvid.datasets.positioning_stage, "gantry": lpvid.datasets.gantry}


def _identify(name: str, with_validation: bool) -> tuple[lpvid.IdentifyResult, np.ndarray]:
    ds = MAKERS[name]()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lpvid.ConvergenceWarning)
        res = lpvid.identify(
            ds.identification,
            ds.order,
            ds.basis,
            validation=ds.validation if with_validation else None,
            fixed=ds.fixed,
            refit=False,
        )
    val = np.array([lpvid.vnls(e.model, ds.validation) for e in res.entries])
    return res, val / ds.validation.n_residuals


@pytest.fixture(scope="module")
def runs():
    """identify on each built-in set, with and without its validation data (judged on it after)."""
    return {(s, v): _identify(s, v) for s in MAKERS for v in (True, False)}


@pytest.fixture(params=[(s, v) for s in MAKERS for v in (True, False)])
def run(request, runs):
    name, with_validation = request.param
    return (name, with_validation, *runs[name, with_validation])


def test_validation_does_not_grow_along_a_guarded_path(run):
    _, with_validation, _, val = run
    if not with_validation:
        return  # a plain warm path: the choice below keeps what the first fits found
    path = val[1:]  # gamma falling
    for k in range(1, path.size):
        assert path[k] <= 1.1 * path[:k].min(), (k, path)


def test_the_choice_simplifies_and_keeps_interpolating(run, runs):
    name, with_validation, res, val = run
    chosen, nls = res.entry, res.entries[0]
    assert chosen.n_groups < nls.n_groups
    if with_validation:
        assert val[res.chosen] <= 1.1 * val.min()
        if name == "gantry":  # no worse than before the path was guarded: 5 groups at 1.42
            assert chosen.n_groups <= 5 and val[res.chosen] <= 1.02 * 1.4188
        return
    # Without validation data the path runs warm and the knee takes, for its
    # number of groups, the most regularised fit within the noise of the best.
    slack = lpvid.fit.judge.noise_slack(chosen.noise_floor)
    same = [e for e in res.entries if e.n_groups == chosen.n_groups]
    best = min(e.vnls for e in same)
    assert chosen.vnls <= best + slack
    assert all(e.gamma <= chosen.gamma for e in same if e.vnls <= best + slack)
    assert not any(e.pinned for e in res.entries)
    # Judged afterwards: better than the unregularised model, and within 5 % of
    # the model chosen with the validation data.
    with_val, val_with = runs[name, True]
    assert val[res.chosen] < val[0]
    assert val[res.chosen] <= 1.05 * val_with[with_val.chosen]


def test_pinned_fits_are_said(run):
    _, _, res, _ = run
    rows = res.table().splitlines()[1:]
    for row, e in zip(rows, res.entries, strict=True):
        assert ("(pinned)" in row) == e.pinned


def _data(model: lpvid.LpvModel, p: list[float], rng: np.random.Generator) -> lpvid.FrfData:
    return noisy_data(model, np.array(p), np.linspace(1.0, 40.0, 25), rng, rel_noise=0.01)


def test_the_path_is_plain_warm_where_nothing_is_flat(rng):
    model = random_lpv(rng, n=2, r=1, l=1, nb=2)
    exact = _data(model, [0.1, 0.5, 0.9], rng)
    more = _data(model, [0.1, 0.4, 0.6, 0.9], rng)
    assert path_mode(model, exact, None, None) == "warm"
    assert path_mode(model, exact, exact, None) == "guarded"
    assert path_mode(model, more, None, None) == "warm"
    assert path_mode(model, more, more, None) == "warm"
    # Time records along a moving p see the model between the points.
    u, p = rng.normal(size=300), rng.uniform(size=300)
    record = lpvid.TimeData(u, p, model.simulate(u, p), dt=model.Ts, sigma=0.01)
    assert path_mode(model, exact, None, check_time_data(exact, record)) == "warm"


def test_pinning_changes_nothing_where_nothing_is_flat(rng):
    model = random_lpv(rng, n=2, r=1, l=1, nb=2)
    data = _data(model, [0.1, 0.4, 0.6, 0.9], rng)
    start = model.with_theta(model.theta + 0.02 * rng.normal(size=model.theta.size))
    free = lpvid.fit_l21(start, data, 0.05, warn=False)
    pinned = lpvid.fit_l21(start, data, 0.05, warn=False, pinned=True)
    np.testing.assert_array_equal(free.model.theta, pinned.model.theta)
    assert free.n_iter == pinned.n_iter


def test_pinning_keeps_the_model_between_the_points(rng):
    # At three points for a quadratic basis the warm fit may move the model
    # between the points for free; the pinned fit moves it less, at the same
    # cost at the data.
    model = random_lpv(rng, n=2, r=1, l=1, nb=2)
    data = _data(model, [0.1, 0.5, 0.9], rng)
    nls = lpvid.fit_nls(model, data, warn=False).model
    between = np.linspace(0.1, 0.9, 17)
    freqs = np.linspace(1.0, 40.0, 25)

    def moved(m: lpvid.LpvModel) -> float:
        return float(np.abs(m.frf(freqs, between) - nls.frf(freqs, between)).max())

    free = lpvid.fit_l21(nls, data, 0.1, warn=False)
    pinned = lpvid.fit_l21(nls, data, 0.1, warn=False, pinned=True)
    assert moved(pinned.model) < moved(free.model)
    assert pinned.vnls <= 1.05 * free.vnls


def test_pinned_must_be_a_flag(rng):
    model = random_lpv(rng, n=2, r=1, l=1, nb=2)
    data = _data(model, [0.1, 0.5, 0.9], rng)
    with pytest.raises(TypeError, match=r"^pinned: expected True or False, got str"):
        lpvid.fit_l21(model, data, 0.1, pinned="yes")


def test_the_report_says_which_fits_were_pinned(run, tmp_path):
    _, _, res, _ = run
    report = lpvid.report.markdown.write_report(res, tmp_path, figures=False)
    rows = json.loads((tmp_path / "result.json").read_text())["path"]
    assert [r["pinned"] for r in rows] == [e.pinned for e in res.entries]
    said = "(pinned): the fit kept its steps off" in report.read_text()
    assert said == any(e.pinned for e in res.entries)


def test_a_pinned_sweep_is_the_chain_of_pinned_fits(rng):
    model = random_lpv(rng, n=2, r=1, l=1, nb=2)
    data = _data(model, [0.1, 0.5, 0.9], rng)
    path = lpvid.l21_path(model, data, [0.01, 0.1], warn=False, pinned=True)
    first = lpvid.fit_l21(model, data, 0.1, warn=False, pinned=True)
    second = lpvid.fit_l21(first.model, data, 0.01, warn=False, pinned=True)
    assert [r.gamma for r in path.results] == [0.1, 0.01]
    np.testing.assert_array_equal(path.results[0].model.theta, first.model.theta)
    np.testing.assert_array_equal(path.results[1].model.theta, second.model.theta)
    free = lpvid.l21_path(model, data, [0.1], warn=False)
    assert not np.array_equal(free.results[0].model.theta, first.model.theta)
