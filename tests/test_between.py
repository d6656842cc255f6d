"""identify is right between the points: systems with a known truth (issue 30).

Every test here identifies a system of :mod:`lpvid.testing` whose scheduling
dependence is known, from FRFs with 1 % noise, and judges the model that
identify returns where nothing was measured: against the truth's FRF at
unseen scheduling values, and against the truth's own V_NLS on validation
data (the noise realisation's level). ``benches/bench_between.py`` runs the
same cases over more seeds and lines.
"""

from __future__ import annotations

import itertools
import warnings

import numpy as np
import pytest

import lpvid
from lpvid.testing import crossing_lpv, noisy_data, one_group_lpv, worst_relative_error

FIXED = {"D": True}
LINES = np.linspace(2.0, 100.0, 120)
UNSEEN = np.linspace(0.03, 0.97, 20)


def _identify(data, basis, validation=None, order=10, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("error", lpvid.ConvergenceWarning)  # the path converges
        return lpvid.identify(data, order, basis, validation=validation, fixed=FIXED, **kw)


def _ratio(model, data):
    return lpvid.vnls(model, data) / data.n_residuals


@pytest.mark.parametrize("seed", [0, 1])
def test_a_one_group_truth_is_kept_with_validation_data(seed):
    true = one_group_lpv(seed)
    rng = np.random.default_rng(100 + seed)
    data = noisy_data(true, np.linspace(0, 1, 5), LINES, rng, 0.01)
    val = noisy_data(true, [0.3, 0.7], LINES, rng, 0.01)
    res = _identify(data, true.basis, val)
    assert res.model.group_norms().nonzero() == true.group_norms().nonzero()  # A(1) alone
    # As good as the truth on the validation data, and right between the points.
    assert _ratio(res.model, val) <= 1.05 * _ratio(true, val)
    assert worst_relative_error(res.model, true, LINES, UNSEEN) < 0.015
    # Never worse than the path's choice (the refit is judged on the validation data).
    assert res.final.validation_vnls <= res.entry.validation_vnls
    assert lpvid.vnls(res.model, val) == res.final.validation_vnls


@pytest.mark.parametrize("seed", [0, 1])
def test_a_one_group_truth_is_kept_without_validation_data(seed):
    true = one_group_lpv(seed)
    data = noisy_data(true, np.linspace(0, 1, 6), LINES, np.random.default_rng(200 + seed), 0.01)
    res = _identify(data, true.basis)
    assert res.model.group_norms().nonzero() == true.group_norms().nonzero()
    assert res.model is res.entry.model and not res.refitted and "not refitted" in res.reason
    # Between the points about the noise level of the measurements (1 %),
    # better than the unregularised model.
    err = worst_relative_error(res.model, true, LINES, UNSEEN)
    assert err < 0.015
    assert err < worst_relative_error(res.entries[0].model, true, LINES, UNSEEN)


def test_more_data_never_hurts_much():
    # One more measured point, no validation data: the worst error at unseen
    # scheduling values stays within 1.5 times the error before on average
    # over the seeds and the points added, and within 3 times in the worst
    # case. (Landed main before the judged refit: up to 140 times worse,
    # 0.0017 -> 0.24; benches/bench_between.py --cases more.) An error below
    # the noise counts as the noise: the measurements' own error at the
    # points identify was given, in the same measure (0.012-0.018 here for
    # 1 % noise). Below it the model returned is one of several that fit
    # within the noise, and which one follows the last bits: seed 0's fifth
    # point took the error from 0.0129 to 0.0284 with numpy's OpenBLAS on
    # its Haswell kernel and from 0.0098 to 0.0375 on its Sandybridge kernel
    # (issue 59), 2.2 and 3.8 times, 1.6 and 2.1 times the noise before.
    ratios = []
    for seed, extra in itertools.product(range(2), (0.75, 0.1)):
        true = one_group_lpv(seed)
        rng = np.random.default_rng(300 + seed)
        full = noisy_data(true, [0.02, 0.5, 1.0, extra, 0.25], LINES, rng, 0.01)
        errs, noise = [], []
        for k in (3, 4, 5):
            data = full.subset(list(range(k)))
            res = _identify(data, true.basis)
            errs.append(worst_relative_error(res.model, true, LINES, UNSEEN))
            noise.append(_measured_error(data, true))
        for k in (1, 2):
            ratios.append(errs[k] / max(errs[k - 1], noise[k - 1]))
    assert np.mean(ratios) <= 1.5, ratios
    assert max(ratios) <= 3, ratios


def _measured_error(data, true):
    """worst_relative_error of the measurements themselves: the noise in that measure."""
    G, Gt = data.G, true.frf(data.freqs_hz, data.p)
    err = np.linalg.norm((G - Gt).reshape(len(G), -1), axis=1)
    return float(np.max(err / np.linalg.norm(Gt.reshape(len(Gt), -1), axis=1)))


@pytest.mark.parametrize("n_params", [2, 3])
def test_crossing_modes_on_several_scheduling_parameters(n_params):
    true = crossing_lpv(n_params, modes=3, damping=0.03)
    f = np.linspace(4.0, 100.0, 60)
    rng = np.random.default_rng(400 + n_params)
    grid = np.array(list(itertools.product([0.0, 0.5, 1.0], repeat=n_params)))
    data = noisy_data(true, grid, f, rng, 0.01)
    val = noisy_data(true, rng.uniform(0.1, 0.9, size=(4, n_params)), f, rng, 0.01)
    res = _identify(data, true.basis, val, order=6)
    kept, truth = res.model.group_norms().nonzero(), true.group_norms().nonzero()
    assert all(set(truth[x]) <= set(kept[x]) for x in truth)  # every group the truth needs
    assert res.entry.n_groups <= true.group_norms().count() + 2  # and few others
    assert _ratio(res.model, val) <= 1.05 * _ratio(true, val)
    unseen = rng.uniform(0.05, 0.95, size=(20, n_params))
    assert worst_relative_error(res.model, true, f, unseen) < 0.01
    assert res.final.validation_vnls <= res.entry.validation_vnls


def test_the_reweighting_ends_when_only_the_coordinates_slide():
    # After the groups are found, the l2,1 steps slide along state
    # transformations that inflate ||A(0)|| (lowering the relative magnitude
    # of A(1)) while the response at the data stays put: the fit ends there
    # even with the V_NLS test off (dvnls_min=0), not at its iteration limit.
    true = one_group_lpv(3)
    data = noisy_data(true, np.linspace(0, 1, 6), LINES, np.random.default_rng(2003), 0.01)
    start = _identify(data, true.basis, refit=False).nls.model
    settings = lpvid.L21Settings(max_outer=10, dvnls_min=0.0)
    fit = lpvid.fit_l21(start, data, 0.1, settings, FIXED, warn=False)
    assert fit.stop == "settled" and fit.outer_iterations < settings.max_outer
    assert fit.nonzero_groups == true.group_norms().nonzero()


def test_the_answer_is_a_property_of_the_data_not_of_the_last_bits():
    # Issue 31: landed main returned models validating at 2.66 and 2.02-2.07
    # times the floor for the same data multiplied by (1 + 1e-12 noise). Here
    # the same perturbations leave the choices as they were (gamma, groups,
    # the refit kept or not) and the validation V_NLS of the model returned
    # within 1 % (measured: 4e-6 and 0.6 %, a tenth of the noise in the
    # validation V_NLS: the fits slide along directions the data barely see).
    true = one_group_lpv(0)
    rng = np.random.default_rng(100)
    data = noisy_data(true, np.linspace(0, 1, 5), LINES, rng, 0.01)
    val = noisy_data(true, [0.3, 0.7], LINES, rng, 0.01)
    runs = []
    for seed in (None, 1, 2):
        d = data
        if seed is not None:
            wobble = 1 + 1e-12 * np.random.default_rng(seed).standard_normal(data.G.shape)
            d = lpvid.FrfData(data.p, data.freqs_hz, data.G * wobble, data.sigma)
        res = _identify(d, true.basis, val)
        choices = (res.entry.gamma, res.entry.nonzero_groups, res.refitted)
        runs.append((*choices, _ratio(res.model, val)))
    first = runs[0]
    for run in runs[1:]:
        assert run[:3] == first[:3]
        assert run[3] == pytest.approx(first[3], rel=1e-2)


def test_twin_starts_that_stop_short_tie_whatever_the_last_bits():
    # The starts' fits stop when a step buys less than START_FTOL of V_NLS,
    # short of the minimum they share: smile:pairwise and its continuation
    # twin ended 2.4e-3 apart in validation V_NLS on the second of these
    # draws, and with a cost tie of 1e-3 (not ten times START_FTOL) that
    # draw chose the twin and moved the model between the points by 1.8e-4.
    true = one_group_lpv(0)
    f = np.linspace(2.0, 100.0, 200)
    rng = np.random.default_rng(1000)
    data = noisy_data(true, [0.0, 0.25, 0.5, 0.75, 1.0, 0.6], f, rng, 0.01).subset(range(5))
    val = noisy_data(true, [0.3, 0.7], f, rng, 0.01)
    base = _identify(data, true.basis, val)
    wobble = np.random.default_rng(7)
    for _ in range(2):
        G = data.G * (1 + 1e-12 * wobble.standard_normal(data.G.shape))
        res = _identify(lpvid.FrfData(data.p, f, G, sigma=data.sigma), true.basis, val)
        assert (res.start, res.entry.gamma) == (base.start, base.entry.gamma)
        assert worst_relative_error(res.model, base.model, f, UNSEEN) < 1e-8
