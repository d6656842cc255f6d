"""Quadratic stability on a box of two and three parameters (stable/multi.py, stable/boxsos.py).

The certified bound is checked against the returned ``P`` on dense random samples of
the box, against solvers that return doctored answers (the bound must pay for them),
against cvxpy on the vertices (affine ``A``: the vertices decide), and on models the
certificate must refuse: a frozen model unstable in a window between the grid's points.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from rate_systems import model_of, rotating
from test_lyapunov import _doctor, _raise_eps_keeping_the_identity

import lpvid
from lpvid.stable.boxsos import solve_box
from lpvid.stable.multi import box_quadratic, polynomial_terms
from lpvid.stable.scan import margins

pytest.importorskip("clarabel")


def _random_terms(rng, n, n_params, discrete, spread):
    exps = [e for e in itertools.product(range(3), repeat=n_params) if 0 < sum(e) <= 2]
    if discrete:
        A0 = 0.4 * np.eye(n) + 0.1 * rng.standard_normal((n, n))
    else:
        S = rng.standard_normal((n, n))
        A0 = (S - S.T) - 2.0 * np.eye(n)
    terms = {(0,) * n_params: A0}
    for e in exps:
        terms[e] = spread * rng.standard_normal((n, n))
    return terms


def _at(terms, t):
    return sum(a * float(np.prod(t ** np.array(e))) for e, a in terms.items())


def _F(A, P, discrete):
    return np.block([[P, A.T @ P], [P @ A, P]]) if discrete else -(A.T @ P + P @ A)


def _sampled_min(terms, P, discrete, rng, count=3000):
    n_params = len(next(iter(terms)))
    t = rng.uniform(-1.0, 1.0, (count, n_params))
    t[: 2**n_params] = np.array(list(itertools.product((-1.0, 1.0), repeat=n_params)))
    return min(np.linalg.eigvalsh(_F(_at(terms, x), P, discrete)).min() for x in t)


@pytest.mark.parametrize("n_params", [2, 3])
@pytest.mark.parametrize("discrete", [False, True])
def test_certified_bound_holds_on_samples(rng, n_params, discrete):
    """Rejects a bound that is not a bound (a term of the residual or a Gram penalty lost,
    a wrong multiplier): F(t) >= mu I wherever it is sampled, and the claim is True."""
    terms = _random_terms(rng, 3, n_params, discrete, 0.08 if discrete else 0.3)
    q, cert, note = box_quadratic(terms, discrete)
    assert q is True and cert.mu > 0, note
    worst = _sampled_min(terms, cert.P, discrete, rng)
    assert cert.mu <= worst * (1 + 1e-9)
    assert np.linalg.eigvalsh(cert.P)[0] >= 1.0 - 1e-6


@pytest.mark.parametrize("frac", [0.3, 1.0])
def test_an_overstated_eps_is_paid_by_the_residual(monkeypatch, rng, frac):
    """Rejects a bound without the identity's residual (or in another norm)."""
    terms = _random_terms(rng, 2, 2, False, 0.3)

    def overstate(x, status, args):
        x[-1] += frac * abs(x[-1])
        return x, status

    _doctor(monkeypatch, overstate)
    sol = solve_box([(terms, np.zeros(2))], 2, 0, False, 1e6)
    P = sol.P[(0, 0)]
    worst = _sampled_min(terms, P, False, rng)
    assert sol.residual > 0.5 * frac * abs(sol.eps) / (1 + frac)
    assert sol.mu <= worst * (1 + 1e-9)


@pytest.mark.parametrize("discrete", [False, True])
def test_an_exact_identity_with_indefinite_gram_is_paid(monkeypatch, rng, discrete):
    """Rejects a Gram penalty without its count of monomials N_j (or without the multipliers'
    Gram matrices): eps raised, the identity kept exact, the Gram matrices indefinite."""
    terms = _random_terms(rng, 2, 2, discrete, 0.08 if discrete else 0.3)
    if not discrete:
        scale = max(np.linalg.norm(a, 2) for a in terms.values())
        terms = {e: a / scale for e, a in terms.items()}
    _doctor(monkeypatch, _raise_eps_keeping_the_identity(3, 0.5))
    sol = solve_box([(terms, np.zeros(2))], 2, 0, discrete, 1e6)
    P = sol.P[(0, 0)]
    worst = _sampled_min(terms, P, discrete, rng)
    assert sol.residual <= 1e-8 * np.linalg.norm(P, 2)
    assert sol.eps > worst * 1.2
    assert sol.mu <= worst * (1 + 1e-9)


def test_affine_dependence_agrees_with_cvxpy_on_the_vertices(rng):
    """For affine A(t) the vertices decide: the box's eps is at most the vertices' (cvxpy)
    and, here, within a few per cent of it (the relaxation is not loose)."""
    cp = pytest.importorskip("cvxpy")
    n = 3
    terms = _random_terms(rng, n, 2, False, 0.0)
    terms[(1, 0)] = 0.5 * rng.standard_normal((n, n))
    terms[(0, 1)] = 0.5 * rng.standard_normal((n, n))
    terms = {e: a for e, a in terms.items() if np.any(a)}
    scale = max(np.linalg.norm(a, 2) for a in terms.values())
    P = cp.Variable((n, n), symmetric=True)
    eps = cp.Variable()
    cons = [P >> np.eye(n), P << 1e6 * np.eye(n)]
    for t in itertools.product((-1.0, 1.0), repeat=2):
        A = _at(terms, np.array(t)) / scale
        cons.append(-(A.T @ P + P @ A) >> eps * np.eye(n))
    cp.Problem(cp.Maximize(eps), cons).solve(solver="CLARABEL")
    q, cert, _ = box_quadratic(terms, False)
    assert q is True
    assert cert.eps / scale <= eps.value * (1 + 1e-6)
    assert cert.eps / scale >= 0.95 * eps.value


def test_a_window_of_instability_between_the_grid_points_is_refused():
    """Rejects a certificate that trusts the grid: a(p) > 0 on a disc of radius 0.01 between
    the scan's grid points, so the grid sees a stable model, and no certificate may say so."""
    basis = lpvid.Polynomial(2, domain=[(-1.0, 1.0), (-1.0, 1.0)])
    c = np.zeros(2)  # between the points of the scan's axes (44 points, +-0.0233 nearest)

    def f(p):
        return np.array([[1e-4 - 4.0 * float(np.sum((np.asarray(p) - c) ** 2))]])

    m = model_of(f, 1, basis)
    grid = lpvid.stable.ranges.box_grid(basis.domain, 2001)
    assert margins(m, grid).min() > 0  # the grid alone would call every frozen model stable
    assert margins(m, c[None, :])[0] < 0
    q, _, note = box_quadratic(polynomial_terms(m, basis.domain), False)
    assert q is not True and "not decided" in note
    assert lpvid.rate_stability(m, 1e-3)[0] is not True
    rep = lpvid.stability(m, rate=True)
    assert rep.quadratic is not True and rep.rate is None


def test_the_rotation_is_not_quadratically_stable():
    """Frozen-stable (eigenvalues -1 +- sqrt(4 |s|^2 - 9)), but a fast enough rotation inside
    the box is unstable: no common P can exist, and the grid program proves it."""
    rep = lpvid.stability(rotating())
    assert rep.stable and rep.margin == pytest.approx(1 / np.sqrt(10), rel=1e-6)
    assert rep.quadratic is False and "grid of the box" in rep.note


@pytest.mark.parametrize("n_params", [2, 3])
def test_quadratic_true_implies_every_frozen_model_stable(rng, n_params):
    """The certificate and the scan agree on the models the certificate accepts."""
    for _ in range(3):
        terms = _random_terms(rng, 2, n_params, False, 0.6)
        q, _, _ = box_quadratic(terms, False)
        if q:
            t = rng.uniform(-1.0, 1.0, (500, n_params))
            assert all(np.linalg.eigvals(_at(terms, x)).real.max() < 0 for x in t)


def test_legendre_and_custom_bases():
    """Legendre on two parameters is polynomial (read exactly); a custom basis is not decided."""
    dom = [(0.0, 2.0), (1.0, 3.0)]
    leg = lpvid.Legendre(2, domain=dom)
    m = model_of(lambda p: np.array([[-2.0 + 0.3 * p[0] * p[1]]]), 1, leg)
    terms = polynomial_terms(m, dom)
    t = np.array([0.3, -0.7])
    p = np.array([1.3, 1.3])  # t mapped back onto the box
    assert _at(terms, t)[0, 0] == pytest.approx(-2.0 + 0.3 * p[0] * p[1], abs=1e-12)
    assert lpvid.stability(m).quadratic is True
    custom = lpvid.CustomBasis([lambda p: np.sin(p[:, 0]) * p[:, 1]], n_params=2)
    one = np.zeros((2, 1, 1))
    one[0] = 1.0
    mc = lpvid.LpvModel([[[-1.0]], [[0.1]]], one, one, basis=custom, p_range=dom)
    rep = lpvid.stability(mc)
    assert rep.quadratic is None and "polynomial" in rep.note


def test_a_parameter_on_the_log_scale_is_polynomial_in_its_log():
    """A(p) of a basis on the log scale is read as the polynomial in ``log10(p)`` it is: the
    terms and the verdict are those of the same coefficients on ``u = log10(p)`` (rejects a
    linear map of ``t`` onto ``p``, where A is no polynomial and the terms are refused)."""
    rot = rotating(pairs=[(-1.0, 1.0), (-1.0, 1.0)])
    log = lpvid.LpvModel(
        rot.A,
        rot.B,
        rot.C,
        basis=lpvid.Polynomial(
            rot.basis.degree, domain=[(0.5, 5.0), (-1.0, 1.0)], scale=["log", "linear"]
        ),
    )
    twin = lpvid.LpvModel(
        rot.A,
        rot.B,
        rot.C,
        basis=lpvid.Polynomial(
            rot.basis.degree, domain=[(np.log10(0.5), np.log10(5.0)), (-1.0, 1.0)]
        ),
    )
    pairs_log = [(0.5, 5.0), (-1.0, 1.0)]
    pairs_u = [(np.log10(0.5), np.log10(5.0)), (-1.0, 1.0)]
    mine, theirs = polynomial_terms(log, pairs_log), polynomial_terms(twin, pairs_u)
    assert mine is not None and set(mine) == set(theirs)
    for e in mine:
        np.testing.assert_allclose(mine[e], theirs[e], atol=1e-10)
    assert lpvid.stability(log).quadratic == lpvid.stability(twin).quadratic
