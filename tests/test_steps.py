"""What identify adds for trust (lpvid.trust.steps), on a one-state model: fast.

finish and stable_fit against what their parts (lpvid.covariance,
lpvid.stability, the refit) say on their own; the summary lines from
known entries. Each test names the wrong code it rejects.
"""

from __future__ import annotations

import dataclasses
import types
import warnings

import numpy as np
import pytest

import lpvid
from lpvid.stable.enforce import STABLE_TOL, stabilised
from lpvid.trust.steps import finish, refit_line, stable_fit, trust_lines
from lpvid.trust.support import dropped_mask, refit

BASIS = lpvid.Polynomial(1, domain=(0.0, 1.0))
LINES = np.linspace(0.02, 0.45, 10)
P_ID = np.array([0.0, 0.5, 1.0])
P_VAL = np.array([0.25, 0.75])
RANGE = (0.0, 1.0)


def _model(a0=0.6, a1=0.2, b0=1.0, b1=0.0):
    """A(p) = a0 + a1 s (s = 2 p - 1): pole a0 + a1 s; C, D constant (their groups zero)."""
    A = np.array([[[a0]], [[a1]]])
    B = np.array([[[b0]], [[b1]]])
    C = np.array([[[1.0]], [[0.0]]])
    D = np.array([[[0.1]], [[0.0]]])
    return lpvid.LpvModel(A, B, C, D, basis=BASIS, Ts=1.0)


def _data(model, p, seed=0, rel=0.01):
    rng = np.random.default_rng(seed)
    G = model.frf(LINES, p)
    sigma = rel * np.abs(G)
    noise = sigma * (rng.standard_normal(G.shape) + 1j * rng.standard_normal(G.shape)) / np.sqrt(2)
    return lpvid.FrfData(p, LINES, G + noise, sigma=sigma, Ts=1.0)


def _quiet(fn, *args, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        return fn(*args, **kwargs)


def test_finish_without_refit_describes_the_model_on_its_support():
    """Rejects the held parameters, the covariance or the stability of another model or mask."""
    true = _model()
    data = _data(true, P_ID)
    fixed = {"D": True}
    done = _quiet(finish, true, 0.0, data, fixed, 1e-6, p_range=RANGE)
    assert done.model is true and done.refit is None and done.refitted is False
    assert done.stability.quadratic is None  # the quadratic test is not run here
    assert done.note == "not refitted (unregularised model chosen)"
    held = lpvid.fixed_mask(true, fixed) | dropped_mask(true, 1e-6, RANGE)
    assert held.sum() == 4  # D(0), D(1) fixed, B(1), C(1) dropped
    np.testing.assert_array_equal(done.fixed, held)
    cov = lpvid.covariance(true, data, held, warn=False)
    np.testing.assert_allclose(done.covariance.theta, cov.theta, rtol=1e-12, atol=0)
    assert done.covariance.n_free == int((~held).sum())
    rep = lpvid.stability(true, RANGE, quadratic=False)
    assert done.stability.stable and done.stability.margin == pytest.approx(rep.margin)
    # Two points for affine B and C: a direction the data cannot tell, left out without a
    # warning here (the summary says it: trust_lines).
    two = _model(b1=0.3)
    two = two.with_theta(np.where(np.arange(8) == 5, 0.2, two.theta))  # C(1) = 0.2
    flat = _quiet(finish, two, 0.0, _data(two, P_ID[[0, 2]]), fixed, 1e-6, p_range=RANGE)
    assert flat.covariance.n_unidentified == 1
    # gamma > 0 with refit=False says so.
    other = _quiet(finish, true, 0.1, data, fixed, 1e-6, do_refit=False, p_range=RANGE)
    assert other.note == "not refitted (refit=False)" and other.refit is None


def test_finish_keeps_a_refit_that_validates_better():
    """Rejects the refit's model, mask or note lost on the way to the result."""
    true = _model()
    shrunk = _model(b0=0.8)  # what an l2,1 penalty leaves: shrunk towards zero
    data, val = _data(true, P_ID), _data(true, P_VAL, seed=1)
    done = _quiet(
        finish, shrunk, 0.1, data, {"D": True}, 1e-6, validation=val, p_range=RANGE, stable=True
    )
    assert done.refitted and done.refit is not None and done.model is done.refit.model
    assert done.note.startswith("refitted on the support (validation V_NLS ")
    assert lpvid.vnls(done.model, val) < 0.5 * lpvid.vnls(shrunk, val)
    held = lpvid.fixed_mask(true, {"D": True}) | dropped_mask(shrunk, 1e-6, RANGE)
    np.testing.assert_array_equal(done.fixed, held)
    assert np.all(done.model.theta[held] == shrunk.theta[held])
    cov = lpvid.covariance(done.model, data, held, warn=False)
    np.testing.assert_allclose(done.covariance.theta, cov.theta, rtol=1e-10, atol=0)
    # Without validation data the refit is not run.
    alone = _quiet(finish, shrunk, 0.1, data, {"D": True}, 1e-6, p_range=RANGE)
    assert alone.refit is None and alone.model is shrunk and alone.note.startswith("not refitted")


def test_finish_warns_about_unstable_frozen_models():
    """Rejects the warning dropped, or the place and margin it names."""
    bad = _model(a0=0.9)  # pole 1.1 at p = 1
    data = _data(bad, P_ID)
    rep = lpvid.stability(bad, RANGE, quadratic=False)
    assert not rep.stable
    with pytest.warns(lpvid.ConvergenceWarning) as record:
        done = finish(bad, 0.0, data, {"D": True}, 1e-6, p_range=RANGE)
    (w,) = [r for r in record if issubclass(r.category, lpvid.ConvergenceWarning)]
    assert str(w.message) == (
        "the chosen model has unstable frozen models on the scheduling range (at p = "
        f"{lpvid.stable.scan.format_p(rep.worst_p)}, margin {rep.margin:.3g}); "
        "identify(..., stable=True) keeps them stable"
    )
    assert not done.stability.stable


def test_stable_fit_keeps_a_stable_fit_and_replaces_an_unstable_one():
    """Rejects stable fits replaced, or unstable (or barely stable) ones kept."""
    true = _model()
    data = _data(true, P_ID)
    fit = lpvid.fit_nls(true, data, {"D": True})
    assert stable_fit(fit, data, {"D": True}, 1e-6, RANGE) is fit
    for a0 in (0.9, 0.8 - 5e-7):  # pole 1.1, and 1 - 5e-7 (stable, margin below STABLE_TOL)
        start = _model(a0=a0)
        rep = lpvid.stability(start, RANGE, quadratic=False)
        assert rep.margin < STABLE_TOL and rep.stable == (a0 < 0.8)
        out = stable_fit(dataclasses.replace(fit, model=start), data, {"D": True}, 1e-6, RANGE)
        assert out is not fit and isinstance(out, lpvid.FitResult)
        after = lpvid.stability(out.model, RANGE, quadratic=False)
        assert after.stable and after.margin >= STABLE_TOL
        # Refitted on the data: close to the truth's V_NLS, not the start's.
        assert out.vnls < 3 * data.n_residuals


def _time_records(model=None, p_range=RANGE, seed=3, samples=300):
    """Time records of a model a little off the truth (B(0) = 1.1): they pull a fit."""
    model = _model(b0=1.1) if model is None else model
    rng = np.random.default_rng(seed)
    u, p = rng.standard_normal(samples), np.linspace(*p_range, samples)
    return lpvid.TimeData(u, p, model.simulate(u, p), dt=1.0)


def test_finish_passes_the_validation_figure_and_the_time_records_to_the_refit():
    """Rejects the validation V_NLS or the time records given dropped on the way to the refit."""
    true, shrunk = _model(), _model(b0=0.8)
    data, val, td = _data(true, P_ID), _data(true, P_VAL, seed=1), _time_records()
    args = (shrunk, 0.1, data, {"D": True}, 1e-6)
    with_td = _quiet(finish, *args, validation=val, p_range=RANGE, time_data=td)
    direct, _ = refit(shrunk, data, {"D": True}, p_range=RANGE, warn=False, time_data=td)
    plain = _quiet(finish, *args, validation=val, p_range=RANGE)
    np.testing.assert_allclose(with_td.refit.model.theta, direct.model.theta, rtol=1e-9)
    assert np.max(np.abs(with_td.refit.model.theta - plain.refit.model.theta)) > 1e-6
    # The validation V_NLS given is the one the refit is judged against.
    given = 0.5 * lpvid.vnls(shrunk, val)
    told = _quiet(finish, *args, validation=val, validation_vnls=given, p_range=RANGE)
    assert f"validation V_NLS {given:.6g} -> " in told.note and told.refitted
    low = _quiet(finish, *args, validation=val, validation_vnls=1e-9, p_range=RANGE)
    assert not low.refitted and low.model is shrunk and "validated no better" in low.note


def _narrow():
    """A(p) = 0.5 + 0.1 p + 0.6 p^2 on the domain (-1, 1): unstable at p = 1; stable on
    (0, 0.05), where its A(2) group is small (below 1e-2 of A, above 1e-6)."""
    basis = lpvid.Polynomial(2, domain=(-1.0, 1.0))
    A = np.array([[[0.5]], [[0.1]], [[0.6]]])
    B = np.array([[[1.0]], [[0.0]], [[0.0]]])
    C = np.array([[[1.0]], [[0.0]], [[0.0]]])
    D = np.array([[[0.1]], [[0.0]], [[0.0]]])
    return lpvid.LpvModel(A, B, C, D, basis=basis, Ts=1.0)


NARROW = (0.0, 0.05)


def test_the_range_given_decides_the_support_and_the_stability_statement():
    """Rejects the support, the threshold or the stability taken over the domain, not the range."""
    m = _narrow()
    data = _data(m, np.array([0.0, 0.025, 0.05]))
    held = lpvid.fixed_mask(m, {"D": True}) | dropped_mask(m, 1e-2, NARROW)
    assert not np.array_equal(dropped_mask(m, 1e-2, NARROW), dropped_mask(m, 1e-2, None))
    assert not np.array_equal(dropped_mask(m, 1e-2, NARROW), dropped_mask(m, 1e-6, NARROW))
    for gamma in (0.0, 0.1):  # not refitted: unregularised, or without validation data
        done = _quiet(finish, m, gamma, data, {"D": True}, 1e-2, p_range=NARROW)
        np.testing.assert_array_equal(done.fixed, held)
        assert done.stability.stable and done.stability.p_range == NARROW
    assert not lpvid.stability(m, quadratic=False).stable  # over the whole domain


def test_stable_fit_refits_on_the_range_with_the_threshold_and_time_records():
    """Rejects the replacement started, thresholded or fitted without what it was given."""
    truth = _narrow().with_theta(_narrow().theta * [1.4, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1])
    data = _data(truth, np.array([0.0, 0.025, 0.05]))
    unstable = _narrow().with_theta(_narrow().theta * [2.1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1])
    assert not lpvid.stability(unstable, NARROW, quadratic=False).stable
    fit = lpvid.fit_nls(truth, data, {"D": True})
    td = _time_records(truth.with_theta(truth.theta * 1.02), NARROW)
    out = stable_fit(dataclasses.replace(fit, model=unstable), data, {"D": True}, 1e-2, NARROW, td)
    start = stabilised(unstable, NARROW)
    direct, held = refit(
        start,
        data,
        {"D": True},
        threshold=1e-2,
        p_range=NARROW,
        stable=True,
        warn=False,
        time_data=td,
    )
    np.testing.assert_allclose(out.model.theta, direct.model.theta, rtol=1e-9, atol=1e-12)
    assert np.all(out.model.A[2] == 0.0)  # the small A(2) group dropped at 1e-2
    alone = stable_fit(dataclasses.replace(fit, model=unstable), data, {"D": True}, 1e-2, NARROW)
    assert np.max(np.abs(alone.model.theta - out.model.theta)) > 1e-6  # the records count


def _entry(vnls, validation=None):
    return types.SimpleNamespace(vnls=vnls, validation_vnls=validation)


def test_refit_line():
    """Rejects the refit line's figures, the validation part or the verdict garbled."""
    assert refit_line(_entry(12.5), _entry(10.25), True) == (
        "refit on the support (dropped groups fixed at zero): V_NLS 12.5 -> 10.25; kept"
    )
    assert refit_line(_entry(12.5, 30.0), _entry(10.25, 31.5), False) == (
        "refit on the support (dropped groups fixed at zero): V_NLS 12.5 -> 10.25; "
        "validation V_NLS 30 -> 31.5; not kept, the path's model returned"
    )
    line = refit_line(_entry(12.5, 30.0), _entry(10.25), False)  # one validation figure only
    assert "validation" not in line


def test_trust_lines():
    """Rejects lines left out, or added for what has nothing to say."""
    true = _model()
    data = _data(true, P_ID)
    report = lpvid.stability(true, RANGE, quadratic=False)
    # B(1) nonzero: a scale of the state that varies with p changes the FRF.
    other = _model(b1=0.3)
    cov = lpvid.covariance(other, _data(other, P_ID), {"D": True})
    assert cov.n_unidentified == 0
    assert trust_lines(_entry(1.0), None, False, cov, None) == []
    assert trust_lines(_entry(1.0), None, False, None, report) == [report.summary().splitlines()[0]]
    lines = trust_lines(_entry(2.0), _entry(1.0), True, None, None)
    assert lines == [refit_line(_entry(2.0), _entry(1.0), True)]
    # B and C constant: a scale of the state affine in p leaves the FRF unchanged to first
    # order (B T and C / T stay affine), a direction the data cannot tell.
    flat = lpvid.covariance(true, data, {"D": True}, warn=False)
    assert flat.n_unidentified > 0
    (line,) = trust_lines(_entry(1.0), None, False, flat, None)
    assert line.startswith(
        f"covariance: rank {flat.rank}; {flat.n_unidentified} parameter direction(s) leave "
        "the FRF at every identification point unchanged"
    )
