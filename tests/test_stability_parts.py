"""The parts of lpvid.stable.scan against analytic answers.

The crossing test is checked on A(t) = T blockdiag(lambda_k(t)) T^-1 whose eigenvalue
functions are known polynomials, so the exact crossings are the real roots in [-1, 1]
of lambda_i + lambda_j (continuous time) or lambda_i lambda_j - 1 (discrete time).
The refinement is checked on models whose margin is a function chosen in closed form.
"""

from __future__ import annotations

import time

import numpy as np
import pytest
from numpy.polynomial import polynomial as P

import lpvid
from lpvid.stable import scan as module
from lpvid.stable.scan import (
    _crossings,
    _fmt_range,
    _guardian,
    _refine_1d,
    _refine_nd,
    _symmetric_part,
    format_p,
    margins,
)

# ---------------------------------------------------------------- A(t) with known poles


def _coef(reals, pairs, seed=7):
    """Coefficients (d+1, n, n) of A(t) = T blockdiag(...) T^-1.

    reals: polynomials (increasing powers) of the real eigenvalues; pairs: (a, b) with a a
    polynomial and b a constant, the eigenvalues a(t) +- j b.
    """
    d = max(len(c) for c in reals + [a for a, _ in pairs]) - 1
    n = len(reals) + 2 * len(pairs)
    D = np.zeros((d + 1, n, n))
    for k, c in enumerate(reals):
        D[: len(c), k, k] = c
    for q, (a, b) in enumerate(pairs):
        i = len(reals) + 2 * q
        D[: len(a), i, i] = a
        D[: len(a), i + 1, i + 1] = a
        D[0, i, i + 1], D[0, i + 1, i] = b, -b
    T = np.random.default_rng(seed).normal(size=(n, n)) + 2 * np.eye(n)
    Ti = np.linalg.inv(T)
    return np.array([T @ Dk @ Ti for Dk in D])


def _eig_polys(reals, pairs, discrete):
    """The polynomials whose real roots are the exact crossings (i <= j)."""
    polys = []
    for i, ci in enumerate(reals):
        for cj in reals[i:]:
            polys.append(P.polysub(P.polymul(ci, cj), [1.0]) if discrete else P.polyadd(ci, cj))
    for a, b in pairs:  # a pole pair with itself: |lambda|^2 = 1 or 2 Re lambda = 0
        polys.append(P.polyadd(P.polymul(a, a), [b * b - 1.0]) if discrete else 2 * np.asarray(a))
    return polys


def _exact_crossings(reals, pairs, discrete):
    roots = []
    for poly in _eig_polys(reals, pairs, discrete):
        for r in P.polyroots(poly):
            # Every root is either real or clearly complex: the test means what it says.
            assert abs(r.imag) < 1e-12 or abs(r.imag) > 0.05
            if abs(r.imag) < 1e-12 and abs(r.real) <= 1.0:
                roots.append(r.real)
    return np.array(sorted(roots))


def _same_set(got, want, tol):
    """Every value of one set is within tol of one of the other."""
    got, want = np.asarray(got), np.asarray(want)
    assert got.size and want.size
    assert np.max(np.min(np.abs(got[:, None] - want[None, :]), axis=1)) < tol
    assert np.max(np.min(np.abs(want[:, None] - got[None, :]), axis=1)) < tol


# Continuous time: 2 l1 = 0 at t = 0.375, l1 + l3 = 0 at t = -0.346, 2 l3 = 0 at t = -1.5
# (outside), l2 + l3 = 0 at 0.5 +- 0.5j (complex, not a crossing), the pair at +-0.471.
CT_REALS = [[-0.3, 0.8], [-1.0, 0.0, -0.5], [0.75, 0.5]]
CT_PAIRS = [([0.2, 0.0, -0.9], 2.0)]
# Discrete time: l1^2 = 1 at 0.833, the pair |lambda| = 1 at +-0.962, l1 l2 = 1 outside.
DT_REALS = [[0.5, 0.6], [-0.3, 0.0, 0.2]]
DT_PAIRS = [([0.0, 0.9], 0.5)]


@pytest.mark.parametrize(
    ("reals", "pairs", "discrete"),
    [(CT_REALS, CT_PAIRS, False), (DT_REALS, DT_PAIRS, True)],
)
def test_crossings_are_the_exact_roots(reals, pairs, discrete):
    """Rejects a companion form or root filter that adds, loses or moves a crossing."""
    coef = _coef(reals, pairs)
    want = _exact_crossings(reals, pairs, discrete)
    got = _crossings(coef, discrete)
    assert got.min() >= -1.0 and got.max() <= 1.0
    _same_set(got, want, 1e-9)


def test_crossings_with_every_shift_singular():
    """Rejects a broken generalised eigenvalue problem (the guardian singular at 0, -+1/2)."""
    # Continuous: 2 l1 = 2 (t^3 - t / 4) vanishes at the three shifts; degree 3.
    reals = [[0.0, -0.25, 0.0, 1.0], [-1.0, 0.3]]
    pairs = [([-0.2, 0.5], 1.5)]
    coef = _coef(reals, pairs)
    _same_set(_crossings(coef, False), _exact_crossings(reals, pairs, False), 1e-9)
    # Discrete: l1^2 - 1 = t (t + 2) and l2^2 - 1 = 4 t^2 - 1 vanish at the shifts; degree 4.
    reals = [[1.0, 1.0], [0.0, 2.0], [-0.2, 0.0, 0.4]]
    coef = _coef(reals, [])
    _same_set(_crossings(coef, True), _exact_crossings(reals, [], True), 1e-9)
    # Without the similarity: exactly singular guardian matrices.
    D = np.zeros((2, 3, 3))
    D[0] = np.diag([0.0, 0.5, -0.5])
    D[1] = np.eye(3)
    _same_set(_crossings(D, False), [-0.5, -0.25, 0.0, 0.25, 0.5], 1e-12)


def test_crossings_pick_a_regular_shift():
    """Rejects choosing the shift by anything but the conditioning of A's guardian there."""
    # x' = t x: the guardian 2 t is exactly singular at the first shift t0 = 0.
    np.testing.assert_array_equal(_crossings(np.array([[[0.0]], [[1.0]]]), False), [0.0])
    np.testing.assert_array_equal(_crossings(np.array([[[0.0]], [[1.0]]]), True), [-1.0, 1.0])


@pytest.mark.parametrize("end", [-1.0, 1.0])
def test_a_crossing_at_an_end_is_reported_inside_the_range(end):
    """Rejects dropping a crossing computed just past an end, or reporting it outside."""
    # 2 l(t) = 0 at t = end (1 + 1e-10): a pole on the axis at the end of the range.
    root = end * (1 + 1e-10)
    reals = [[-2.0 * root, 2.0], [-3.0, 0.5]]
    got = _crossings(_coef(reals, []), False)
    assert got.min() >= -1.0 and got.max() <= 1.0
    assert np.min(np.abs(got - end)) < 1e-12


def test_the_pencil_limit_is_inclusive(monkeypatch):
    """Rejects treating a pencil of exactly MAX_PENCIL rows as too large."""
    coef = np.array([[[0.0]], [[-0.25]], [[0.0]], [[1.0]]])  # degree 3, one row each
    monkeypatch.setattr(module, "MAX_PENCIL", 3)
    _same_set(_crossings(coef, False), [-0.5, 0.0, 0.5], 1e-12)
    monkeypatch.setattr(module, "MAX_PENCIL", 2)
    assert _crossings(coef, False) is None


# ---------------------------------------------------------------- the guardian map


def test_symmetric_part_is_an_orthonormal_basis_of_the_symmetric_matrices():
    """Rejects wrong weights or positions in the basis of vec of symmetric matrices."""
    rng = np.random.default_rng(3)
    for n in (1, 2, 4):
        Q = _symmetric_part(n)
        assert Q.shape == (n * (n + 1) // 2, n * n)
        np.testing.assert_allclose(Q @ Q.T, np.eye(Q.shape[0]), atol=1e-15)
        S = rng.normal(size=(n, n))
        S = S + S.T
        v = S.reshape(-1, order="F")
        np.testing.assert_allclose(Q.T @ (Q @ v), v, atol=1e-13)  # spans every symmetric S
        K = rng.normal(size=(n, n))
        np.testing.assert_allclose(Q @ (K - K.T).reshape(-1, order="F"), 0.0, atol=1e-13)


@pytest.mark.parametrize("discrete", [False, True])
def test_guardian_eigenvalues_are_the_pair_sums_or_products(discrete):
    """Rejects a guardian polynomial whose eigenvalues are not lambda_i (+ or *) lambda_j."""
    reals, pairs = (DT_REALS, DT_PAIRS) if discrete else (CT_REALS, CT_PAIRS)
    coef = _coef(reals, pairs)
    L = _guardian(coef, discrete)
    d = coef.shape[0] - 1
    assert len(L) == (2 * d if discrete else d) + 1
    for t in (-0.7, 0.2, 0.9):
        lam = np.linalg.eigvals(sum(c * t**k for k, c in enumerate(coef)))
        i, j = np.triu_indices(lam.size)
        want = lam[i] * lam[j] - 1 if discrete else lam[i] + lam[j]
        got = np.linalg.eigvals(sum(x * t**k for k, x in enumerate(L)))
        _same_set(np.sort_complex(got), np.sort_complex(want), 1e-9)


@pytest.mark.parametrize("discrete", [False, True])
def test_guardian_drops_zero_terms(discrete):
    """Rejects a guardian padded with zero coefficients (a larger pencil than needed)."""
    A0 = np.array([[0.5, 0.2], [-0.1, 0.3]])
    assert len(_guardian(np.array([A0, 0 * A0]), discrete)) == 1


def test_an_integrator_has_margin_zero():
    """Rejects failing on a guardian that is zero for every t (x+ = x: every pole at 1)."""
    m = lpvid.LpvModel([[[1.0]]], [[[1.0]]], [[[1.0]]], Ts=1.0)
    assert _guardian(m.A[:1], True)[0].shape == (1, 1)
    rep = lpvid.stability(m, quadratic=False)
    assert not rep.stable and rep.margin == 0.0 and rep.crossings.size == 0


# ---------------------------------------------------------------- refinement


def _margin_model(g, p_range=(0.0, 1.0), n_params=1):
    """A discrete scalar model x+ = (1 - g(p)) x: its margin is g(p) (for 0 < g < 1)."""
    basis = lpvid.CustomBasis([lambda p: 1.0 - g(p)], n_params=n_params)
    one = [[[1.0]], [[0.0]]]
    return lpvid.LpvModel([[[0.0]], [[1.0]]], one, one, basis=basis, Ts=1.0, p_range=p_range)


def _dip(p, c, w, depth):
    return depth * np.exp(-(((p - c) / w) ** 2))


def _refine(g, ps):
    m = _margin_model(g)
    ms = margins(m, ps[:, None])
    np.testing.assert_allclose(ms, g(ps), atol=1e-15)  # the model's margin is g
    return ps, ms, _refine_1d(m, ps, ms)


def _argmin(g, lo, hi):
    """Where g is smallest on [lo, hi]: three ever finer grids."""
    for _ in range(3):
        x = np.linspace(lo, hi, 2001)
        k = int(np.argmin(g(x)))
        lo, hi = x[max(k - 1, 0)], x[min(k + 1, x.size - 1)]
    return x[k]


GRID = np.linspace(0.0, 1.0, 41)  # spacing 0.025


@pytest.mark.parametrize("mirror", [False, True])
def test_the_deepest_dip_is_refined_though_sampled_fifth(mirror):
    """Rejects refining anything but the five smallest sampled local minima (no slopes, no
    end that is not a minimum)."""

    # A base rising from 0.5 to 0.8; dips at the samples 0.025 (to 0.3), 0.3, 0.45, 0.6
    # (to 0.35, 0.4, 0.45) and a narrow one to about 0.1 between the samples 0.8 and 0.825,
    # sampled at 0.64 only. The end p = 0 (0.46) is not a local minimum but would push the
    # narrow dip out of the five refined.
    def g0(p):
        out = 0.5 + 0.3 * p - _dip(p, 0.025, 0.02, 0.2075)
        for c, to in ((0.3, 0.35), (0.45, 0.4), (0.6, 0.45)):
            out = out - _dip(p, c, 0.02, 0.5 + 0.3 * c - to)
        return out - _dip(p, 0.8081, 0.006, 0.64)

    def g(p):
        return g0(1.0 - p) if mirror else g0(p)

    ps, ms, (best_p, best_m, evals) = _refine(g, GRID)
    truth = _argmin(g0, 0.8, 0.825)
    end, near = (ms[::-1], ms[::-1][32:34]) if mirror else (ms, ms[32:34])
    assert end[1] < end[0] < near.min() and np.sort(ms)[3] < end[0]  # as designed
    assert best_p == pytest.approx(1.0 - truth if mirror else truth, abs=1e-6)
    assert best_m == pytest.approx(g0(truth), abs=1e-9) and best_m < 0.2 and evals > 0


@pytest.mark.parametrize("mirror", [False, True])
def test_a_dip_between_the_end_samples_is_found(mirror):
    """Rejects ranking or bracketing an end minimum by any sample but the end itself."""

    # A base rising from 0.5; a bump at p = 0.025 (to 0.61) makes the end p = 0 a local
    # minimum (0.5), and a narrow dip to about 0.06 lies between p = 0 and 0.025. Five more
    # minima, sampled at 0.4, 0.45, 0.52, 0.55, 0.56: the end ranks third, its neighbour
    # p = 0.025 would rank sixth.
    def g0(p):
        out = 0.5 + 0.3 * p + _dip(p, 0.025, 0.008, 0.1) - _dip(p, 0.0125, 0.003, 0.45)
        for c, to in ((0.3, 0.4), (0.45, 0.45), (0.6, 0.52), (0.75, 0.55), (0.9, 0.56)):
            out = out - _dip(p, c, 0.02, 0.5 + 0.3 * c - to)
        return out

    def g(p):
        return g0(1.0 - p) if mirror else g0(p)

    ps, ms, (best_p, best_m, _) = _refine(g, GRID)
    truth = _argmin(g0, 0.0, 0.025)
    end = ms[::-1] if mirror else ms
    assert end[0] < end[1] and np.sum(end[[12, 18, 24, 30, 36]] < end[0]) == 2  # designed
    assert best_p == pytest.approx(1.0 - truth if mirror else truth, abs=1e-6)
    assert best_m == pytest.approx(g0(truth), abs=1e-9) and best_m < 0.1


def test_a_dip_left_of_the_sampled_minimum():
    """Rejects searching around the wrong sample of a local minimum."""

    def g(p):
        return 0.6 + 0.2 * (p - 0.5) ** 2 - _dip(p, 0.5 - 0.00625, 0.004, 0.5)

    ps, ms, (best_p, best_m, _) = _refine(g, GRID)
    assert np.argmin(ms) == 20  # the sample p = 0.5, right of the dip
    truth = _argmin(g, 0.475, 0.5)
    assert best_p == pytest.approx(truth, abs=1e-6) and best_m == pytest.approx(g(truth), abs=1e-9)


def test_few_samples():
    """Rejects skipping the search with three samples, or not keeping the smaller of two."""

    def g(p):
        return 0.5 + 0.4 * (p - 0.3) ** 2

    _, _, (best_p, best_m, evals) = _refine(g, np.array([0.0, 0.5, 1.0]))
    assert best_p == pytest.approx(0.3, abs=1e-6) and best_m == pytest.approx(0.5, abs=1e-12)
    assert evals > 0
    _, _, out = _refine(g, np.array([1.0, 0.5]))
    assert out == (0.5, pytest.approx(0.516), 0)


def test_a_repeated_sample_does_not_stop_the_search():
    """Rejects ending the search at a minimum whose neighbours coincide (a repeated p)."""

    def g(p):
        return 0.3 + 0.4 * (1.0 - p) - _dip(p, 0.4881, 0.01, 0.5)

    ps = np.concatenate([GRID, [1.0]])  # p = 1 twice: the smallest sample, an end
    _, ms, (best_p, best_m, _) = _refine(g, ps)
    assert np.argsort(ms)[2] not in (40, 41)  # the dip ranks after both copies of the end
    truth = _argmin(g, 0.475, 0.5)
    assert best_p == pytest.approx(truth, abs=1e-6) and best_m == pytest.approx(g(truth), abs=1e-9)


def test_a_kink_between_samples_is_located_to_many_digits():
    """Rejects a loose tolerance in the search (a kink, where parabolas do not help)."""

    def g(p):
        return 0.5 + 0.3 * np.abs(p - 0.4537)

    _, _, (best_p, best_m, _) = _refine(g, GRID)
    assert best_p == pytest.approx(0.4537, abs=1e-7)
    assert best_m == pytest.approx(0.5, abs=3e-8)


def test_two_parameters_refine_from_the_smallest_samples():
    """Rejects a search from anywhere but the grid points with the smallest margins."""
    # A shallow dip at the corner (0, 0) to 0.4, the deepest (to 0.05) at c between the
    # points of the 44 x 44 grid.
    c = np.array([0.7103, 0.6291])

    def g(p):
        p = np.atleast_2d(p)
        r2 = np.sum((p - c) ** 2, axis=1)
        return 0.5 - 0.1 * np.exp(-np.sum(p**2, axis=1) / 0.04) - 0.45 * np.exp(-r2 / 4e-4)

    m = _margin_model(g, [(0.0, 1.0), (0.0, 1.0)], n_params=2)
    rep = lpvid.stability(m, quadratic=False)
    assert rep.method == "grid" and rep.stable and rep.crossings.shape == (0,)
    assert rep.margin == pytest.approx(0.05, abs=1e-9)
    np.testing.assert_allclose(rep.worst_p, c, atol=1e-5)
    # The same from _refine_nd with a coarse grid of its own.
    pts = np.array([[0.0, 0.0], [0.7, 0.6], [1.0, 1.0]])
    best_p, best_m, evals = _refine_nd(m, pts, g(pts), [(0.0, 1.0), (0.0, 1.0)])
    assert best_m == pytest.approx(0.05, abs=1e-9) and evals > 0
    np.testing.assert_allclose(best_p, c, atol=1e-5)


# ---------------------------------------------------------------- the report


def test_only_the_range_is_checked():
    """Rejects scan points outside the range (between the crossings and beyond an end)."""
    # Continuous time, x' = sigma(t) x with w = t^2 - 1/4 and sigma = -1e-8 - w^2 + w^3:
    # stable on [-1, 1] (the margin is 1: a real pole), unstable for |t| > 1.118. The pole
    # comes within 1e-8 of the axis at t = -+1/2, which the crossing test reports (complex
    # roots -+1/2 +- 1e-4 j).
    w = P.polysub(P.polypow([0.0, 0.0, 1.0], 1), [0.25])
    sigma = P.polyadd(P.polysub(P.polypow(w, 3), P.polypow(w, 2)), [-1e-8])
    basis = lpvid.Polynomial(6, domain=(-1.0, 1.0))
    A = sigma.reshape(7, 1, 1)
    B = np.zeros((7, 1, 1))
    B[0] = 1.0
    m = lpvid.LpvModel(A, B, B.copy(), basis=basis)
    assert margins(m, [-1.25, 1.25]).max() == -1.0
    rep = lpvid.stability(m, quadratic=False)
    assert rep.method == "crossings" and rep.stable and rep.margin == 1.0
    np.testing.assert_allclose(np.sort(rep.crossings), [-0.5, 0.5], atol=1e-6)
    assert -1.0 <= rep.worst_p <= 1.0


def test_report_of_a_grid_check():
    """Rejects a grid report without an empty crossings array, or with a wrong time."""
    basis = lpvid.CustomBasis([np.sin])
    one = [[[1.0]], [[0.0]]]
    m = lpvid.LpvModel([[[0.5]], [[0.3]]], one, one, basis=basis, Ts=1.0, p_range=(0.0, 3.0))
    start = time.perf_counter()
    rep = lpvid.stability(m)
    elapsed = time.perf_counter() - start
    assert rep.method == "grid" and isinstance(rep.crossings, np.ndarray)
    assert rep.crossings.shape == (0,)
    assert 0.0 < rep.seconds <= elapsed
    # a(p) = 0.5 + 0.3 sin p: stable, margin 0.2 at pi / 2; quadratic stability open.
    assert rep.margin == pytest.approx(0.2, abs=1e-12)
    assert rep.note == (
        "quadratic stability not decided: the LMI certificate covers polynomial "
        "dependence (Polynomial, Legendre bases)"
    )


def test_the_note_names_the_unstable_point():
    """Rejects a note on quadratic stability that does not say where a model is unstable."""
    basis = lpvid.Polynomial(1, domain=(0.0, 2.0))
    one = [[[1.0]], [[0.0]]]
    # a(p) = 0.5 + 0.6 s, s = p - 1: largest, 1.1, at p = 2.
    rep = lpvid.stability(lpvid.LpvModel([[[0.5]], [[0.6]]], one, one, basis=basis, Ts=1.0))
    assert not rep.stable and rep.worst_p == pytest.approx(2.0, abs=1e-9)
    assert rep.note == "not quadratically stable: the frozen model at p = 2 is unstable"


def test_ranges_and_points_in_words():
    """Rejects a wrong text for a range or a scheduling point."""
    assert _fmt_range((0.0, 1.5)) == "[0, 1.5]"
    assert _fmt_range([(0.0, 1.0), (-2.0, 2.5)]) == "[0, 1] x [-2, 2.5]"
    assert _fmt_range((0.25, 0.25)) == "(0.25)"
    assert _fmt_range([(1.0, 1.0), (-3.0, -3.0)]) == "(1, -3)"
    assert format_p(0.123456789) == "0.123457" and format_p([0.5]) == "0.5"
    assert format_p(np.array([1.0 / 3.0, 2])) == "(0.3333, 2)"
