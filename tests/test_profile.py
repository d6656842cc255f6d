"""The spread's band checked beyond first order (lpvid.trust.profile, issue 58).

The check narrows the first-order band along a direction only where V_NLS
rises faster than first order says; that is checked against an
independent minimiser (scipy's least squares) of V_NLS with the same
quantity held, and the band is left as it is where first order holds.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.optimize import least_squares

import lpvid
from lpvid.testing import noisy_data, one_group_lpv
from lpvid.trust.profile import HOLDS, LEVEL, Z95, BandCheck, checked_band
from lpvid.trust.silent import seen_covariance

TRUE = one_group_lpv(0, n=2)
FREQS = np.linspace(5, 60, 40)
FIXED = {"D": True}


def _identify(points, seed):
    data = noisy_data(TRUE, points, FREQS, np.random.default_rng(seed), 0.01)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lpvid.ConvergenceWarning)
        return lpvid.identify(data, 2, TRUE.basis, fixed=FIXED)


@pytest.fixture(scope="module")
def narrowed():
    """Four points where one leading direction of the band is narrowed (measured: 0.35)."""
    return _identify([0.0, 0.3, 0.6, 1.0], 0)


def _independent_profile(res, d, a, t):
    """min over changes keeping a^T theta of V_NLS at theta + t d, by scipy (from theta + t d)."""
    model, data = res.model, res.data
    free = ~res.between.held
    an = a / np.linalg.norm(a)
    # an orthonormal basis of the free parameters' changes orthogonal to a
    Q = np.linalg.svd(np.eye(free.sum()) - np.outer(an, an))[0][:, :-1]
    base = model.theta.copy()
    base[free] += t * d[free]

    def residual(y):
        th = base.copy()
        th[free] += Q @ y
        r = (model.with_theta(th).frf(data.freqs_hz, data.p) - data.G) / data.sigma
        return np.concatenate([r.real.ravel(), r.imag.ravel()])

    fit = least_squares(residual, np.zeros(Q.shape[1]), method="lm", xtol=1e-14, ftol=1e-14)
    return float(np.sum(fit.fun**2))


def test_a_narrowed_direction_is_one_the_data_reject_beyond_its_reach(narrowed):
    b = narrowed.between
    check = b.check
    assert check is not None and np.any(check.scales < 1.0)
    j = int(np.argmin(check.scales))
    d = check.steps[j]
    seen, free, _ = seen_covariance(narrowed.model, narrowed.data, b.held)
    a = np.zeros_like(d)
    a[free] = np.linalg.pinv(seen[np.ix_(free, free)], rcond=1e-13, hermitian=True) @ d[free]
    reach = check.scales[j] * Z95
    # the band along it is the reach's: a^T C a is 1 first order (d is one standard deviation)
    assert a @ seen @ a == pytest.approx(1.0, rel=1e-6)
    assert a @ b.band.theta @ a == pytest.approx(check.scales[j] ** 2, rel=1e-6)
    least = _independent_profile(narrowed, d, a[free], 0.0)
    beyond = reach * np.sqrt(2.0)  # the first doubling that failed (the reach is the middle)
    rises = [_independent_profile(narrowed, s * d, a[free], beyond) - least for s in (1, -1)]
    assert min(rises) > LEVEL  # both signs: the data reject the step scipy too
    # and allow the last step the climb passed, on one side at least
    inside = reach / np.sqrt(2.0)
    allowed = [_independent_profile(narrowed, s * d, a[free], inside) - least for s in (1, -1)]
    assert min(allowed) <= LEVEL
    # and first order would have allowed it: the band was wider than V_NLS allows
    assert beyond <= Z95 * (1 + 1e-12)


def test_the_check_only_narrows_and_says_so(narrowed):
    b = narrowed.between
    seen, _, _ = seen_covariance(narrowed.model, narrowed.data, b.held)
    first = lpvid.Covariance(**{**vars(b.band), "theta": seen})
    f, p = FREQS, np.linspace(0, 1, 11)
    before, after = first.frf_std(f, p), b.band.frf_std(f, p)
    assert np.all(after <= before * (1 + 1e-9) + 1e-300)
    assert np.max(before / np.maximum(after, 1e-300)) > 1.5  # narrowed somewhere visibly
    assert "V_NLS rises faster than first order" in narrowed.summary()


def test_where_first_order_holds_the_band_is_kept_to_the_bit():
    res = _identify(list(np.linspace(0, 1, 8)), 1)
    b = res.between
    check = b.check
    assert check is not None and len(check.scales) and np.all(check.scales == 1.0)
    # V_NLS's even part at 1.96 standard deviations told it: two evaluations a direction
    # (and the model's Gauss-Newton pieces once)
    assert check.evaluations == 1 + 2 * len(check.scales)
    seen, _, _ = seen_covariance(res.model, res.data, b.held)
    assert np.array_equal(b.band.theta, seen)
    assert "V_NLS rises faster" not in res.summary()


def test_first_order_holds_within_the_stated_margin():
    # under first order the rise at 1.96 standard deviations is LEVEL exactly: a margin
    # above it keeps directions where the model is linear from being narrowed by a last bit
    assert HOLDS * LEVEL > 1.5 * Z95**2 / 2
    assert abs(Z95**2 / 2 - LEVEL) < 1e-12


def test_an_empty_band_is_returned_as_it_is(narrowed):
    cov = narrowed.between.band
    zero = lpvid.Covariance(**{**vars(cov), "theta": np.zeros_like(cov.theta)})
    out, check = checked_band(zero, narrowed.data, narrowed.between.held)
    assert out is zero and len(check.scales) == 0 and check.evaluations == 0


def test_the_description_says_where_it_narrowed():
    steps = np.zeros((3, 4))
    held = BandCheck(np.ones(3), np.array([0.5, 0.3, 0.2]), steps)
    assert held.describe() == "first order holds along the band's 3 leading direction(s)"
    some = BandCheck(np.array([0.25, 1.0, 0.5]), np.array([0.5, 0.3, 0.2]), steps)
    said = some.describe()
    assert "along 2 of the band's 3" in said and "(70% of its variance" in said
    assert "factors 0.25 to 0.5" in said


@pytest.mark.parametrize("lapack_gives_up", [False, True])
def test_the_settled_test_form_is_the_pseudo_inverse_even_where_least_squares_gives_up(
    monkeypatch, lapack_gives_up
):
    # g^T h^+ g, the Gauss-Newton gain that says whether a model sits at
    # V_NLS's least, of a symmetric h of rank 5 in 8: against numpy's pinv,
    # also when LAPACK's least squares raises (as OpenBLAS's did on a finite
    # 320 x 320 h of one_group_lpv at three points).
    from lpvid.trust import profile

    rng = np.random.default_rng(3)
    J = rng.standard_normal((5, 8)) * np.array([1e3, 1, 1e-2, 1, 10, 1, 1, 1])
    h = J.T @ J
    g = rng.standard_normal(8)
    expected = g @ np.linalg.pinv(h, rcond=1e-12, hermitian=True) @ g
    if lapack_gives_up:

        def gives_up(*args, **kwargs):
            raise np.linalg.LinAlgError("SVD did not converge in Linear Least Squares")

        monkeypatch.setattr(profile.np.linalg, "lstsq", gives_up)
    assert profile._pinv_form(h, g) == pytest.approx(expected, rel=1e-8)
