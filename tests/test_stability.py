"""Stability over the scheduling range: the continuum, the margin, the quadratic certificate."""

from __future__ import annotations

import sys

import numpy as np
import pytest

import lpvid
from lpvid import _core
from lpvid.model.frozen import frozen_A, stability_margin
from lpvid.stable.lyapunov import quadratic_stability
from lpvid.stable.ranges import polynomial_A
from lpvid.stable.scan import margins
from lpvid.testing import random_lpv


def _scalar(coefs, Ts=1.0, domain=(0.0, 1.0)):
    """x+ = a(p) x with a(p) = sum_i coefs[i] s^i, s the basis variable."""
    k = len(coefs)
    basis = lpvid.Polynomial(k - 1, domain=domain)
    A = np.array(coefs, dtype=float).reshape(k, 1, 1)
    B = np.zeros((k, 1, 1))
    B[0] = 1.0
    return lpvid.LpvModel(A, B, B.copy(), basis=basis, Ts=Ts)


def _affine(A1, A2, Ts):
    """A(p) from A1 at p = 0 to A2 at p = 1 (s = 2p - 1)."""
    n = A1.shape[0]
    basis = lpvid.Polynomial(1, domain=(0.0, 1.0))
    A = np.array([(A1 + A2) / 2, (A2 - A1) / 2])
    B = np.zeros((2, n, 1))
    B[0, 0] = 1.0
    C = np.zeros((2, 1, n))
    C[0, 0, 0] = 1.0
    return lpvid.LpvModel(A, B, C, basis=basis, Ts=Ts)


@pytest.mark.parametrize("discrete", [True, False])
def test_margin_rule_is_the_cores(rng, discrete):
    for _ in range(50):
        lam = rng.normal(size=4) + 1j * rng.normal(size=4)
        lam = np.concatenate([lam, lam.conj()])
        if discrete:
            lam *= 0.6
        py = float(stability_margin(lam, 1.0 if discrete else None))
        assert py == pytest.approx(_core.stability_margin(lam, discrete), rel=1e-14, abs=1e-15)
        stable = bool(np.all(lpvid.model.frozen.stable_poles(lam, 1.0 if discrete else None)))
        assert (py > 0) == stable


@pytest.mark.parametrize("Ts", [0.01, None])
def test_core_check_points_agree_with_numpy(rng, Ts):
    # The core's eigenvalues (nalgebra's Schur form) against LAPACK's through numpy.
    model = random_lpv(rng, n=6, r=1, l=2, nb=3, Ts=Ts)
    p = np.linspace(0, 1, 101)
    view = _core.ModelView((6, 1, 2, 3), model.theta, model.basis_values(p))
    pts = _core.FrozenRange(view, 10, Ts is not None, 0.0)
    core = pts.margins(model.theta)
    np.testing.assert_allclose(core, margins(model, p), rtol=1e-9, atol=1e-12)
    k, worst = pts.worst(model.theta)
    assert worst == pytest.approx(core.min()) and k == int(np.argmin(core))
    assert len(pts) == 101


def test_a_narrow_unstable_window_is_found():
    # a(s) = peak - c (s - s0)^2 with peak 1 + 1e-9: unstable for |s - s0| < 1e-4,
    # a window of 1e-4 in p, narrower than the spacing of a 2001-point grid.
    s0, c = 0.3123, 0.1
    m = _scalar([1 + 1e-9 - c * s0**2, 2 * c * s0, -c])
    rep = lpvid.stability(m, quadratic=False)
    assert not rep.stable and rep.method == "crossings"
    assert rep.margin == pytest.approx(-1e-9, rel=1e-3)
    assert rep.worst_p == pytest.approx((s0 + 1) / 2, abs=1e-6)
    # The crossings bracket the window.
    assert np.min(np.abs(rep.crossings - (s0 + 1) / 2 + 5e-5)) < 1e-6
    # A plain grid misses it; a dense one where it should be confirms it.
    assert margins(m, np.linspace(0, 1, 2001)).min() > 0
    p0 = (s0 + 1) / 2
    assert margins(m, np.linspace(p0 - 1e-4, p0 + 1e-4, 2001)).min() < 0


def test_a_window_only_the_crossings_reveal():
    # Continuous time, x' = a(s) x with a(s) = 1e-8 - (s - s0)^2: unstable only for
    # |s - s0| < 1e-4. The margin -a / |a| is +1 everywhere else, flat: no sampled
    # minimum points a local search at the window, so only the scan between the
    # computed crossings (s0 -+ 1e-4) can find it.
    s0 = 0.3055  # 5e-4 from the nearest point of the scan's grids and of the one below
    m = _scalar([1e-8 - s0**2, 2 * s0, -1.0], Ts=None)
    p0 = (s0 + 1) / 2
    assert margins(m, np.linspace(0, 1, 2001)).min() == 1.0  # a grid alone sees nothing
    assert margins(m, [p0]).item() == -1.0  # the truth: a > 0 at s0
    rep = lpvid.stability(m, quadratic=False)
    assert rep.method == "crossings" and not rep.stable
    assert rep.margin == -1.0 and abs(rep.worst_p - p0) < 0.5e-4
    np.testing.assert_allclose(np.sort(rep.crossings), [p0 - 0.5e-4, p0 + 0.5e-4], atol=1e-9)


def test_the_grid_method_trusts_its_refined_minimum():
    # A basis without the crossing test (a custom function): a(p) = 0.5 + (0.5 + 1e-6)
    # exp(-((p - p0) / 0.05)^2) exceeds 1 for |p - p0| < 1e-4 only, between two points
    # of the 2001-point grid over [0, 3] (spacing 1.5e-3). Every sampled margin is
    # positive; the local search from the smallest one finds the window, and the
    # verdict must follow it.
    p0 = 1.50075

    def bump(p):
        return np.exp(-(((p - p0) / 0.05) ** 2))

    m = lpvid.LpvModel(
        [[[0.5]], [[0.5 + 1e-6]]],
        [[[1.0]], [[0.0]]],
        [[[1.0]], [[0.0]]],
        basis=lpvid.CustomBasis([bump]),
        Ts=1.0,
        p_range=(0.0, 3.0),
    )
    assert margins(m, np.linspace(0.0, 3.0, 2001)).min() > 0
    rep = lpvid.stability(m, quadratic=False)
    assert rep.method == "grid" and not rep.stable
    assert rep.margin == pytest.approx(-1e-6, rel=1e-4)
    assert rep.worst_p == pytest.approx(p0, abs=1e-5)


def test_continuous_time_pair_crossing_the_axis():
    # A damped pair whose real part -0.02 + 0.05 (1 - 25 (s - 0.4)^2) is positive in a window.
    def A(s):
        sigma = -0.02 + 0.05 * (1 - 25 * (s - 0.4) ** 2)
        return np.array([[sigma, 10.0], [-10.0, sigma]])

    t = np.linspace(-1, 1, 3)
    vals = np.array([A(x) for x in t])
    coef = np.linalg.solve(np.vander(t, 3, increasing=True), vals.reshape(3, -1)).reshape(3, 2, 2)
    basis = lpvid.Polynomial(2, domain=(-1.0, 1.0))
    m = lpvid.LpvModel(
        coef,
        np.ones((3, 2, 1)) * [[[1.0], [0.0]], [[0.0], [0.0]], [[0.0], [0.0]]],
        np.ones((3, 1, 2)) * [[[1.0, 0.0]], [[0.0, 0.0]], [[0.0, 0.0]]],
        basis=basis,
    )
    rep = lpvid.stability(m, quadratic=False)
    half = np.sqrt(0.6 / 25)  # where the real part is zero: 1 - 25 d^2 = 0.4
    assert not rep.stable
    assert rep.worst_p == pytest.approx(0.4, abs=1e-6)
    assert rep.margin == pytest.approx(-0.03 / np.hypot(0.03, 10.0), rel=1e-6)
    for edge in (0.4 - half, 0.4 + half):
        assert np.min(np.abs(rep.crossings - edge)) < 1e-8
    ok = lpvid.stability(m, p_range=(-1.0, 0.1), quadratic=False)
    assert ok.stable and ok.p_range == (-1.0, 0.1)


def test_crossings_when_every_shift_is_singular():
    # x' = a(s) x with a(s) = s^3 - s / 4: a pole at 0 for s = 0 and s = -+1/2, the three
    # shifts of the companion form, so the generalised eigenvalue problem is solved. The
    # crossings are exactly s = -1/2, 0, 1/2 (p = 1/4, 1/2, 3/4); unstable where a > 0.
    m = _scalar([0.0, -0.25, 0.0, 1.0], Ts=None)
    rep = lpvid.stability(m, quadratic=False)
    assert rep.method == "crossings" and not rep.stable and rep.margin == -1.0
    np.testing.assert_allclose(np.sort(rep.crossings), [0.25, 0.5, 0.75], atol=1e-9)
    # A(s) that does not depend on s: no crossing at all; a pencil too large: the grid.
    flat = lpvid.stability(_scalar([0.5, 0.0]), quadratic=False)
    assert flat.method == "crossings" and flat.crossings.size == 0 and flat.stable
    n = 25  # 325 symmetric pairs, discrete degree 2: a pencil of 1300 rows > MAX_PENCIL
    A = np.zeros((3, n, n))
    A[0], A[2] = 0.5 * np.eye(n), 0.2 * np.eye(n)
    B = np.zeros((3, n, 1))
    B[0, 0] = 1.0
    big = lpvid.LpvModel(
        A, B, np.transpose(B, (0, 2, 1)), basis=lpvid.Polynomial(2, domain=(0, 1)), Ts=1.0
    )
    rep = lpvid.stability(big, quadratic=False)
    assert rep.method == "grid" and rep.stable and rep.margin == pytest.approx(0.3)


def test_report_fields_and_text():
    m = _scalar([0.5, 0.45])
    rep = lpvid.stability(m)
    assert rep.stable and rep.discrete and rep.quadratic is True
    assert rep.margin == pytest.approx(0.05) and rep.worst_p == pytest.approx(1.0)
    assert "stable over p in [0, 1]" in rep.summary() and "quadratically stable" in str(rep)
    assert rep.n_checked >= 200 and rep.seconds > 0


def test_summaries_in_words():
    # Discrete time, one parameter, crossings: a(s) = 0.5 + 0.45 s, margin 0.05 at p = 1.
    rep = lpvid.stability(_scalar([0.5, 0.45]), quadratic=False)
    assert rep.summary().splitlines() == [
        "frozen models stable over p in [0, 1]: smallest margin 0.05 (1 - spectral radius) at "
        f"p = 1 (exact crossing test, {rep.n_checked} frozen models)",
        "quadratic stability: not asked (quadratic=False)",
    ]
    # Continuous time, unstable, two parameters on the grid.
    basis = lpvid.Polynomial(1, domain=[(0.0, 1.0), (0.0, 2.0)])
    one = np.ones((3, 1, 1)) * [[[1.0]], [[0.0]], [[0.0]]]
    m = lpvid.LpvModel([[[-1.0]], [[1.5]], [[0.0]]], one, one, basis=basis)
    rep = lpvid.stability(m, quadratic=False)
    first = rep.summary().splitlines()[0]
    assert first == (
        "frozen models NOT stable over p in [0, 1] x [0, 2]: smallest margin -1 (smallest "
        f"-Re(pole)/|pole|) at p = {lpvid.stable.scan.format_p(rep.worst_p)} (grid with "
        f"refinement, {rep.n_checked} frozen models)"
    )
    assert lpvid.stable.scan.format_p([0.25, 2.0]) == "(0.25, 2)"
    assert lpvid.stable.scan.format_p(np.float64(0.125)) == "0.125"
    # One frozen model: an LTI model.
    lti = lpvid.LpvModel([[[0.5]]], [[[1.0]]], [[[1.0]]], Ts=1.0)
    assert lpvid.stability(lti, quadratic=False).summary().splitlines()[0] == (
        "the model does not depend on p and is stable: margin 0.5 (1 - spectral radius)"
    )
    unstable = lpvid.LpvModel([[[1.5]]], [[[1.0]]], [[[1.0]]], Ts=1.0)
    assert "does not depend on p and is NOT stable: margin -0.5" in str(lpvid.stability(unstable))


def test_an_indefinite_gram_matrix_costs_the_certificate(monkeypatch):
    # An LTI model (degree 0: F - eps I = Q0). A solver that returns eps + 0.5 and
    # Q0 - 0.5 I keeps the identity exact, but Q0 is then indefinite: the certified mu must
    # pay for it and stay a lower bound of F, which P alone decides.
    clarabel = pytest.importorskip("clarabel")
    from lpvid.stable import lyapunov

    honest = clarabel.DefaultSolver
    A = np.array([[[0.6, 0.3], [-0.3, 0.6]]])
    n_p, q = 3, 4  # svec(P) of a 2 x 2 matrix, the blocks of the discrete form are 4 x 4

    class Shifting:
        def __init__(self, *args):
            self.inner = honest(*args)

        def solve(self):
            sol = self.inner.solve()
            x = np.array(sol.x, dtype=float)
            x[-1] += 0.5
            x[n_p : n_p + q * (q + 1) // 2] -= 0.5 * lyapunov._svec(np.eye(q))
            return type("Solution", (), {"x": x, "status": sol.status})()

    monkeypatch.setattr(clarabel, "DefaultSolver", Shifting)
    _, cert, _ = quadratic_stability(A, True)
    truth = np.linalg.eigvalsh(cert.inequality(A[0])).min()
    assert cert.residual < 1e-6 * np.linalg.norm(cert.P, 2)  # the identity still holds
    assert cert.mu <= truth * (1 + 1e-9)


def test_an_lmi_too_large_is_not_decided():
    q, cert, note = quadratic_stability(np.zeros((2, 201, 201)), True)  # blocks of 402
    assert q is None and cert is None
    assert note == "not decided: the LMI is too large (blocks over 400)"


def test_bad_ranges_are_named():
    m = _scalar([0.5, 0.45])
    with pytest.raises(
        ValueError, match=r"^p_range: \(-0\.5, 1\) reaches outside the basis domain"
    ):
        lpvid.stability(m, p_range=(-0.5, 1.0))
    with pytest.raises(ValueError, match=r"^p_range: every pair needs lo < hi"):
        lpvid.stability(m, p_range=(1.0, 0.0))
    with pytest.raises(ValueError, match=r"^p_range: 2 pairs given for 1 scheduling parameters"):
        lpvid.stability(m, p_range=[(0.0, 1.0), (0.0, 1.0)])
    free = lpvid.LpvModel(m.A, m.B, m.C, basis=lpvid.Polynomial(1), Ts=1.0)
    with pytest.raises(ValueError, match=r"^p_range: the model has no scheduling range"):
        lpvid.stability(free)
    assert lpvid.stability(free, p_range=(0.0, 1.0), quadratic=False).stable
    with pytest.raises(TypeError, match=r"^model: expected an LpvModel, got str"):
        lpvid.stability("model")
    # An LTI model needs no range.
    lti = lpvid.LpvModel([[[0.5, 0.2], [-0.2, 0.5]]], [[[1.0], [0.0]]], [[[1.0, 0.0]]], Ts=1.0)
    rep = lpvid.stability(lti)
    assert rep.stable and rep.margin == pytest.approx(1 - np.hypot(0.5, 0.2))
    assert rep.quadratic is True


def test_range_checks_at_the_domain_and_an_lti_report():
    from lpvid.stable.ranges import check_range, polynomial_A

    m = _scalar([0.5, 0.45], domain=(2.0, 4.0))
    # A relative slack of 1e-9 of the domain's width (2e-9 here), on both sides.
    assert check_range(m, (2.0 - 1.5e-9, 4.0 + 1.5e-9)) == [(2.0 - 1.5e-9, 4.0 + 1.5e-9)]
    for bad in [(2.0 - 3e-9, 4.0), (2.0, 4.0 + 3e-9)]:
        with pytest.raises(ValueError, match=r"^p_range: \(.*\) reaches outside the basis domain "):
            check_range(m, bad)
    two = lpvid.LpvModel(
        np.zeros((3, 1, 1)),
        np.zeros((3, 1, 1)),
        np.zeros((3, 1, 1)),
        basis=lpvid.Polynomial(1, domain=[(0.0, 1.0), (0.0, 1.0)]),
    )
    with pytest.raises(ValueError, match=r"^p_range: \(0, 2\) of parameter 1 reaches outside"):
        check_range(two, [(0.0, 1.0), (0.0, 2.0)])
    lti = lpvid.LpvModel([[[0.5]]], [[[1.0]]], [[[1.0]]], Ts=1.0)
    assert check_range(lti, None) == [(0.0, 0.0)] and lpvid.stability(lti).p_range == (0.0, 0.0)
    # A(p) of a cubic basis that is only linear: degree 1 after the zero terms are dropped.
    cubic = _scalar([0.5, 0.3, 0.0, 0.0])
    coef = polynomial_A(cubic, [(0.0, 1.0)])
    assert coef.shape == (2, 1, 1) and coef[1, 0, 0] == pytest.approx(0.3)
    assert lpvid.stability(cubic).certificate.degree == 1


def test_other_bases_use_the_grid_and_leave_quadratic_open():
    basis = lpvid.CustomBasis([np.sin])
    m = lpvid.LpvModel(
        [[[0.5]], [[0.6]]],
        [[[1.0]], [[0.0]]],
        [[[1.0]], [[0.0]]],
        basis=basis,
        Ts=1.0,
        p_range=(0.0, 3.0),
    )
    rep = lpvid.stability(m)
    # a(p) = 0.5 + 0.6 sin p peaks at p = pi / 2 with 1.1.
    assert rep.method == "grid" and not rep.stable
    assert rep.worst_p == pytest.approx(np.pi / 2, abs=1e-5)
    assert rep.margin == pytest.approx(-0.1, abs=1e-9)
    assert rep.quadratic is False


@pytest.mark.parametrize("end", [0.0, 3.0])
def test_the_grid_refines_a_window_next_to_an_end(monkeypatch, end):
    # As above, the window 3e-4 from an end of [0, 3], inside the last interval of the grid:
    # the sampled margin is smallest at the end itself, and the search between the end
    # and its neighbour finds the window. n_checked counts every frozen model evaluated.
    from lpvid.stable import scan as module

    p0 = end + (3e-4 if end == 0.0 else -3e-4)

    def bump(p):
        return np.exp(-(((p - p0) / 0.05) ** 2))

    m = lpvid.LpvModel(
        [[[0.5]], [[0.5 + 1e-6]]],
        [[[1.0]], [[0.0]]],
        [[[1.0]], [[0.0]]],
        basis=lpvid.CustomBasis([bump]),
        Ts=1.0,
        p_range=(0.0, 3.0),
    )
    counted = []
    real = module.margins

    def counting(model, p):
        out = real(model, p)
        counted.append(out.size)
        return out

    monkeypatch.setattr(module, "margins", counting)
    rep = lpvid.stability(m, quadratic=False)
    assert not rep.stable and rep.margin == pytest.approx(-1e-6, rel=1e-4)
    assert rep.worst_p == pytest.approx(p0, abs=1e-6)
    assert rep.n_checked == sum(counted) > counted[0] == 2001


def test_two_parameters():
    basis = lpvid.Polynomial(1, domain=[(0.0, 1.0), (0.0, 1.0)])
    # a = 0.5 + 0.2 s1 + 0.25 s2: largest at the corner (1, 1) with 0.95.
    m = lpvid.LpvModel(
        [[[0.5]], [[0.2]], [[0.25]]],
        [[[1.0]], [[0.0]], [[0.0]]],
        [[[1.0]], [[0.0]], [[0.0]]],
        basis=basis,
        Ts=1.0,
    )
    rep = lpvid.stability(m)
    assert rep.stable and rep.method == "grid"
    np.testing.assert_allclose(rep.worst_p, [1.0, 1.0])
    assert rep.margin == pytest.approx(0.05)
    # Several parameters: the sum of squares on the box (issue 62); |a| <= 0.95 with P = 1.
    assert rep.quadratic is True and "box of 2 parameters" in rep.note


def test_two_parameters_refine_between_the_grid_points(monkeypatch):
    # Continuous time, a pair sigma(s) +- 1j with sigma = -0.1 - 300 |s - s0|^2: the least
    # damped place s0 = (0.123, -0.377) lies between the points of the grid (spacing 0.047);
    # the margin there is 0.1 / sqrt(1.01), 0.3 above it at the nearest grid point.
    from lpvid.stable import scan as module

    c, (u, v) = 300.0, (0.123, -0.377)
    eye, rot = np.eye(2), np.array([[0.0, 1.0], [-1.0, 0.0]])
    # Basis 1, s1, s2, s1^2, s1 s2, s2^2.
    A = [(-0.1 - c * (u * u + v * v)) * eye + rot, 2 * c * u * eye, 2 * c * v * eye]
    A += [-c * eye, 0 * eye, -c * eye]
    B = np.zeros((6, 2, 1))
    B[0, 0] = 1.0
    basis = lpvid.Polynomial(2, domain=[(0.0, 1.0), (0.0, 1.0)])
    m = lpvid.LpvModel(np.array(A), B, np.transpose(B, (0, 2, 1)), basis=basis)
    counted = []
    real = module.margins

    def counting(model, p):
        out = real(model, p)
        counted.append(out.size)
        return out

    monkeypatch.setattr(module, "margins", counting)
    rep = lpvid.stability(m, quadratic=False)
    assert rep.method == "grid" and rep.stable
    assert rep.margin == pytest.approx(0.1 / np.sqrt(1.01), rel=1e-9)
    np.testing.assert_allclose(rep.worst_p, [(u + 1) / 2, (v + 1) / 2], atol=1e-6)
    assert rep.n_checked == sum(counted) > counted[0] == 44**2


def test_box_grid():
    from lpvid.stable.ranges import box_grid

    pts = box_grid([(0.0, 1.0), (-2.0, 2.0)], 2001)  # floor(sqrt(2001)) = 44 per axis
    assert pts.shape == (44 * 44, 2)
    np.testing.assert_allclose(pts[:2], [[0.0, -2.0], [0.0, -2.0 + 4.0 / 43]])
    np.testing.assert_allclose(pts[-1], [1.0, 2.0])
    assert box_grid([(0.0, 1.0)] * 3, 5).shape == (8, 3)  # never fewer than 2 per axis


def test_quadratic_false_when_switching_destabilises():
    # Frozen models stable on the whole range, but the product A(0) A(1) has
    # spectral radius > 1: no common Lyapunov matrix exists (switching diverges).
    A1 = np.array([[0.5, 0.95], [0.0, 0.5]])
    A2 = np.array([[0.5, 0.0], [0.95, 0.5]])
    assert np.max(np.abs(np.linalg.eigvals(A1 @ A2))) > 1.3
    rep = lpvid.stability(_affine(A1, A2, Ts=1.0))
    assert rep.stable and rep.margin == pytest.approx(0.025)
    assert rep.quadratic is False and "not quadratically stable" in rep.note


def test_quadratic_false_in_continuous_time_matches_shorten_narendra():
    # Both vertices Hurwitz and every convex combination too, but A1 + g A2^-1 is
    # not Hurwitz for some g > 0: no common quadratic Lyapunov function (a
    # necessary condition of Shorten and Narendra).
    A1 = np.array([[-1.0, 3.0], [0.0, -1.0]])
    A2 = np.array([[0.0, 2.0], [-2.0, -1.0]])
    gs = np.logspace(-3, 3, 301)
    worst = max(np.max(np.linalg.eigvals(A1 + g * np.linalg.inv(A2)).real) for g in gs)
    assert worst > 0
    rep = lpvid.stability(_affine(A1, A2, Ts=None))
    assert rep.stable and rep.quadratic is False


@pytest.mark.parametrize("Ts", [1.0, None])
def test_quadratic_certificate_is_checked_independently(Ts):
    # A polynomial family with a common Lyapunov matrix; check the returned P
    # on a fine grid, independently of the solver and of the identity.
    if Ts is None:
        coefs = [[[-1.0, 2.0], [-2.0, -1.0]], [[0.3, 0.5], [-0.5, 0.2]], [[0.0, 0.4], [-0.1, 0.1]]]
    else:
        coefs = [[[0.6, 0.3], [-0.3, 0.6]], [[0.1, 0.05], [0.0, -0.1]], [[0.05, 0.0], [0.02, 0.0]]]
    basis = lpvid.Polynomial(2, domain=(0.0, 1.0))
    B = np.zeros((3, 2, 1))
    B[0, 0] = 1.0
    m = lpvid.LpvModel(np.array(coefs), B, np.transpose(B, (0, 2, 1)), basis=basis, Ts=Ts)
    rep = lpvid.stability(m)
    assert rep.quadratic is True
    cert = rep.certificate
    assert cert.mu > 0 and np.linalg.eigvalsh(cert.P).min() > 0
    # The sum-of-squares identity, recomputed, holds to the solver's accuracy.
    assert cert.residual <= 1e-6 * np.linalg.norm(cert.P, 2) and cert.mu <= cert.eps
    for A in frozen_A(m, np.linspace(0, 1, 401)):
        F = cert.inequality(A)
        assert np.linalg.eigvalsh(0.5 * (F + F.T)).min() >= cert.mu * (1 - 1e-9)
        if Ts is not None:
            assert np.linalg.eigvalsh(cert.P - A.T @ cert.P @ A).min() > 0
        else:
            assert np.linalg.eigvalsh(A.T @ cert.P + cert.P @ A).max() < 0


@pytest.mark.parametrize(
    "scale, discrete, best",
    [
        ([0.5, 0.45], True, 0.05),  # degree 1: vertices
        ([0.5, 0.2, 0.25], True, 0.05),  # degree 2, max |s(t)| = 0.95 at t = 1
        ([0.5, 0.2, 0.1, 0.15], True, 0.05),  # degree 3
        ([-1.0, -0.5, -0.3], False, 2 * (1 - 0.5**2 / (4 * 0.3))),  # 2 min a(t)
    ],
)
def test_the_lmi_reaches_the_known_optimum(scale, discrete, best):
    # A(t) = s(t) R (discrete, R a rotation) or s(t) I + 3 J (continuous, J skew): with
    # I <= P <= kappa I the best eps is kappa (1 - max |s|), or 2 kappa min(-s), at P = kappa I.
    # The representation is exact: the solver must reach it, not only a feasible point.
    from lpvid.stable.lyapunov import KAPPA

    R = np.array([[np.cos(0.7), -np.sin(0.7)], [np.sin(0.7), np.cos(0.7)]])
    J = np.array([[0.0, 1.0], [-1.0, 0.0]])
    coef = np.array([c * (R if discrete else np.eye(2)) for c in scale])
    if not discrete:
        coef[0] += 3 * J
    q, cert, _ = quadratic_stability(coef, discrete)
    assert q is True and cert.eps == pytest.approx(KAPPA * best, rel=1e-6)
    np.testing.assert_allclose(cert.P, KAPPA * np.eye(2), rtol=0, atol=1e-5 * KAPPA)


def test_unstable_frozen_model_is_not_quadratically_stable():
    rep = lpvid.stability(_scalar([0.5, 0.6]))
    assert not rep.stable and rep.quadratic is False and rep.certificate is None


def test_without_clarabel_quadratic_is_none(monkeypatch):
    monkeypatch.setitem(sys.modules, "clarabel", None)
    rep = lpvid.stability(_scalar([0.5, 0.45]))
    assert rep.stable and rep.quadratic is None
    assert rep.note == 'not decided: the LMI needs the clarabel package (pip install "lpvid[lmi]")'
    q, cert, note = quadratic_stability(np.array([[[0.5]]]), True)
    assert q is None and cert is None


@pytest.mark.parametrize("Ts", [1.0, None])
def test_the_certificate_does_not_trust_the_solver(monkeypatch, Ts):
    # A solver that overstates its eps by 0.5: the identity it returns no longer holds,
    # and the certified bound must still be a true lower bound of F(t), checked on a
    # fine grid; on a family with no common Lyapunov matrix it must certify nothing.
    clarabel = pytest.importorskip("clarabel")
    honest = clarabel.DefaultSolver

    class Overstating:
        def __init__(self, *args):
            self.inner = honest(*args)

        def solve(self):
            sol = self.inner.solve()
            x = np.array(sol.x, dtype=float)
            x[-1] += 0.5  # eps is the last variable
            return type("Solution", (), {"x": x, "status": sol.status})()

    monkeypatch.setattr(clarabel, "DefaultSolver", Overstating)
    A1 = np.array([[0.6, 0.3], [-0.3, 0.6]]) if Ts else np.array([[-1.0, 2.0], [-2.0, -1.0]])
    A2 = A1 + (np.array([[0.1, 0.05], [0.0, -0.1]]) if Ts else np.array([[0.3, 0.5], [-0.5, 0.2]]))
    m = _affine(A1, A2, Ts)
    q, cert, _ = quadratic_stability(polynomial_A(m, [(0.0, 1.0)]), Ts is not None)
    worst = min(
        np.linalg.eigvalsh(0.5 * (F + F.T)).min()
        for F in (cert.inequality(A) for A in frozen_A(m, np.linspace(0, 1, 201)))
    )
    assert cert.mu <= worst * (1 + 1e-9)
    # Switching destabilises this pair (test above): overstated eps or not, no certificate.
    S1 = np.array([[0.5, 0.95], [0.0, 0.5]])
    q, cert, _ = quadratic_stability(polynomial_A(_affine(S1, S1.T, 1.0), [(0.0, 1.0)]), True)
    assert q is not True
