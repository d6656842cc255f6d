"""The common quadratic Lyapunov function (stable/lyapunov.py): verdicts, certificate, bound.

Checked against systems whose answer is known by construction, against cvxpy on the
vertex LMIs, against numpy eigenvalues of the returned certificate on a dense grid, and
against solvers that return doctored answers (the certificate must not trust them).
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from lpvid.stable import lyapunov
from lpvid.stable.lyapunov import _mat, _svec, quadratic_stability

clarabel = pytest.importorskip("clarabel")

T = np.linspace(-1.0, 1.0, 2001)  # dense grid of the scheduling variable, both ends in


def _A(coef, t):
    return sum(c * t**k for k, c in enumerate(coef))


def _worst(cert, coef):
    """Smallest eigenvalue of F(t) over the grid, from the returned P alone."""
    return min(np.linalg.eigvalsh(cert.inequality(_A(coef, t))).min() for t in T)


def _doctor(monkeypatch, edit):
    """Clarabel's answer passed through ``edit(x, status, solver_args) -> (x, status)``."""
    honest = clarabel.DefaultSolver

    class Doctored:
        def __init__(self, *args):
            self.args = args
            self.inner = honest(*args)

        def solve(self):
            sol = self.inner.solve()
            x, status = edit(np.array(sol.x, dtype=float), sol.status, self.args)
            return SimpleNamespace(x=x, status=status)

    monkeypatch.setattr(clarabel, "DefaultSolver", Doctored)


def _raise_eps_keeping_the_identity(n_p, frac):
    """eps raised by ``frac |eps|``, the Gram matrices moved so the equalities still hold.

    P is kept: the Gram matrices must then turn indefinite (eps was the best for P).
    """

    def edit(x, status, args):
        _, _, Acon, _, cones, _ = args
        Aeq = Acon[: cones[0].dim].toarray()
        delta = frac * abs(x[-1])
        dQ = np.linalg.lstsq(Aeq[:, n_p:-1], -Aeq[:, -1] * delta, rcond=None)[0]
        assert np.allclose(Aeq[:, n_p:-1] @ dQ, -Aeq[:, -1] * delta, atol=1e-12 * delta)
        x[n_p:-1] += dQ
        x[-1] += delta
        return x, status

    return edit


def test_svec_is_the_isometry_of_the_psd_triangle(rng):
    """Rejects a wrong off-diagonal factor in _svec (clarabel's cone needs sqrt 2)."""
    M = rng.standard_normal((4, 4))
    M = M + M.T
    N = rng.standard_normal((4, 4))
    N = N + N.T
    np.testing.assert_allclose(_mat(_svec(M), 4), M, rtol=1e-14, atol=1e-14)
    assert _svec(M) @ _svec(N) == pytest.approx(np.trace(M @ N), rel=1e-12)


# Families with one Gram matrix carrying the whole defect: the bound must be attained.
TIGHT = [
    (np.array([[[0.6, 0.3], [-0.2, 0.5]]]), True),  # degree 0, non-symmetric
    (np.array([[[-1.0, 2.0], [-0.5, -1.5]]]) * 3.0, False),
    (np.array([[[0.5]], [[0.3]]]), True),  # degree 1, t = 1 the only active vertex
    (np.array([[[-5.0]], [[3.0]]]), False),
]


@pytest.mark.parametrize("coef, discrete", TIGHT)
def test_an_exact_identity_with_indefinite_gram_is_paid_in_full(monkeypatch, coef, discrete):
    """Rejects Gram weights or the penalty's w (m + 1) that under- or over-state the defect."""
    n = coef.shape[1]
    _doctor(monkeypatch, _raise_eps_keeping_the_identity(n * (n + 1) // 2, 0.2))
    _, cert, _ = quadratic_stability(coef, discrete)
    worst = _worst(cert, coef)
    scale = np.linalg.norm(cert.P, 2) * max(np.linalg.norm(a, 2) for a in coef)
    assert cert.residual <= 1e-9 * scale  # the doctored answer keeps the identity
    assert cert.eps - worst > 0.1 * abs(worst)  # and overstates eps
    # The defect sits in one Gram matrix at one end (t = 1): mu is exactly F's minimum.
    assert cert.mu == pytest.approx(worst, abs=1e-9 * scale)


@pytest.mark.parametrize("discrete", [True, False])
@pytest.mark.parametrize("d", [2, 3])
def test_higher_degrees_with_indefinite_gram_stay_bounds(monkeypatch, discrete, d):
    """Rejects a penalty that forgets a Gram weight or the (m + 1) of Z^T Z at degrees 2, 3."""
    if discrete:
        coef = [[[0.5, 0.2], [-0.1, 0.4]], [[0.2, 0.0], [0.1, 0.15]], [[0.1, 0.05], [0.0, 0.1]]]
        coef += [[[0.05, 0.0], [0.0, 0.04]]]
    else:
        coef = [[[-2.0, 1.0], [-1.0, -1.5]], [[0.8, 0.3], [0.0, 0.6]], [[0.3, 0.0], [0.2, 0.4]]]
        coef += [[[0.2, 0.1], [0.0, 0.3]]]
    coef = np.array(coef[: d + 1])
    _doctor(monkeypatch, _raise_eps_keeping_the_identity(3, 0.5))
    _, cert, _ = quadratic_stability(coef, discrete)
    worst = _worst(cert, coef)
    assert cert.eps > worst * 1.2
    assert cert.mu <= worst + 1e-9 * abs(worst)


@pytest.mark.parametrize("coef, discrete", TIGHT)
def test_an_overstated_eps_alone_is_paid_by_the_residual(monkeypatch, coef, discrete):
    """Rejects a residual in another norm or not in the model's units (continuous time)."""

    def overstate(x, status, args):
        x[-1] += 0.3 * abs(x[-1])
        return x, status

    _doctor(monkeypatch, overstate)
    _, cert, _ = quadratic_stability(coef, discrete)
    worst = _worst(cert, coef)
    scale = np.linalg.norm(cert.P, 2) * max(np.linalg.norm(a, 2) for a in coef)
    # The identity fails by exactly the overstatement, in the spectral norm.
    assert cert.residual == pytest.approx(cert.eps - worst, abs=1e-5 * scale)
    assert cert.mu == pytest.approx(worst, abs=1e-5 * scale)


@pytest.mark.parametrize("c", [1e-9, 1e8])
def test_continuous_time_verdict_and_bound_follow_the_time_unit(c):
    """Rejects a normalisation of A that is lost (c A: eps, mu scale by c, P does not)."""
    coef = np.array([[[-2.0, 1.0], [-1.0, -1.5]], [[0.8, 0.3], [0.0, 0.6]]])
    ref_q, ref, _ = quadratic_stability(coef, False, kappa=100.0)
    q, cert, _ = quadratic_stability(c * coef, False, kappa=100.0)
    assert q is ref_q is True
    assert cert.eps == pytest.approx(c * ref.eps, rel=1e-6)
    assert cert.mu == pytest.approx(c * ref.mu, rel=1e-6)
    assert cert.mu == pytest.approx(cert.eps, rel=1e-6)  # honest solver: nothing to pay
    np.testing.assert_allclose(cert.P, ref.P, rtol=0, atol=1e-5 * 100.0)


def _skew_minus_pd(rng, n):
    S = rng.standard_normal((n, n))
    K = rng.standard_normal((n, n))
    return S - S.T, K @ K.T


@pytest.mark.parametrize("discrete", [True, False])
def test_known_quadratically_stable_families(rng, discrete):
    """Rejects a certificate that is not one: P > 0 and F(t) >= mu > 0 checked on a grid."""
    n, kappa = 3, 50.0
    if discrete:
        # ||A0|| + ||A1|| < 1: P = I already works, F(t) >= 1 - ||A(t)||.
        A0, A1 = rng.standard_normal((2, n, n))
        A0 *= 0.6 / np.linalg.norm(A0, 2)
        A1 *= 0.3 / np.linalg.norm(A1, 2)
        floor = kappa * min(1 - np.linalg.norm(A0 + t * A1, 2) for t in T)
    else:
        # A_i = S_i - K_i (S_i skew, K_i >= 0) with K0 -+ K1 > 0: P = I, F(t) = 2 K(t).
        S0, K0 = _skew_minus_pd(rng, n)
        S1, K1 = _skew_minus_pd(rng, n)
        K0 = K0 + (np.linalg.eigvalsh(K1).max() + 0.5) * np.eye(n)
        A0, A1 = S0 - K0, S1 - K1
        floor = kappa * 2 * min(np.linalg.eigvalsh(K0 + s * K1).min() for s in (-1, 1))
    coef = np.array([A0, A1])
    q, cert, note = quadratic_stability(coef, discrete, kappa=kappa)
    assert q is True and note.startswith("quadratically stable")
    assert cert.kappa == kappa and cert.degree == 1 and cert.discrete is discrete
    lam = np.linalg.eigvalsh(cert.P)
    assert lam[0] > 1 - 1e-6 and lam[-1] < kappa * (1 + 1e-6)
    assert cert.eps >= floor * (1 - 1e-6)  # at least what P = kappa I gives
    assert 0 < cert.mu <= _worst(cert, coef) * (1 + 1e-9)
    for t in T[::50]:
        A = _A(coef, t)
        if discrete:
            assert np.linalg.eigvalsh(cert.P - A.T @ cert.P @ A).min() > 0
        else:
            assert np.linalg.eigvalsh(A.T @ cert.P + cert.P @ A).max() < 0


def _cvxpy_eps(coef, discrete, kappa):
    """Best eps of the vertex LMIs (degree 1) with I <= P <= kappa I, by cvxpy."""
    cp = pytest.importorskip("cvxpy")
    n = coef.shape[1]
    P = cp.Variable((n, n), symmetric=True)
    eps = cp.Variable()
    cons = [P >> np.eye(n), P << kappa * np.eye(n)]
    for s in (-1.0, 1.0):
        A = coef[0] + s * coef[1]
        F = cp.bmat([[P, A.T @ P], [P @ A, P]]) if discrete else -(A.T @ P + P @ A)
        F = 0.5 * (F + F.T)
        cons.append(F >> eps * np.eye(F.shape[0]))
    prob = cp.Problem(cp.Maximize(eps), cons)
    prob.solve(solver="CLARABEL")
    assert prob.status == "optimal"
    return eps.value


SWITCHED = [
    # Frozen-stable everywhere, but the switching product A(-1) A(1) has radius > 1.
    (np.array([[[0.5, 0.475], [0.475, 0.5]], [[0.0, -0.475], [0.475, 0.0]]]), True, False),
    # Shorten & Narendra: both vertices Hurwitz, no common quadratic Lyapunov function.
    (np.array([[[-0.5, 2.5], [-1.0, -1.0]], [[0.5, -0.5], [-1.0, 0.0]]]), False, False),
    (
        np.array([[[0.5, 0.3, 0.0], [-0.2, 0.4, 0.1], [0.0, 0.2, -0.3]], 0.2 * np.eye(3)]),
        True,
        True,
    ),
    (
        np.array([[[-1.0, 3.0, 0.0], [-1.0, -2.0, 1.0], [0.0, -1.0, -1.5]], 0.5 * np.eye(3)]),
        False,
        True,
    ),
]


@pytest.mark.parametrize("coef, discrete, expected", SWITCHED)
def test_the_best_eps_agrees_with_cvxpy(coef, discrete, expected):
    """Rejects a wrong LMI (bounds on P, equality rows): the verdict and eps match cvxpy's."""
    kappa = 100.0
    for s in (-1.0, 1.0):  # every frozen model stable: the question is the switching
        ev = np.linalg.eigvals(coef[0] + s * coef[1])
        assert (np.abs(ev).max() < 1) if discrete else (ev.real.max() < 0)
    best = _cvxpy_eps(coef, discrete, kappa)
    q, cert, note = quadratic_stability(coef, discrete, kappa=kappa)
    assert bool(best > 0) is expected and q is expected
    scale = kappa * max(np.linalg.norm(a, 2) for a in coef)
    assert cert.eps == pytest.approx(best, abs=1e-5 * scale)
    lam = np.linalg.eigvalsh(cert.P)  # the verdict rests on a P inside the searched set
    assert lam[0] > 1 - 1e-6 and lam[-1] < kappa * (1 + 1e-6)
    if not expected:
        form = "P - A(p)^T P A(p)" if discrete else "-(A(p)^T P + P A(p))"
        assert note == (
            "not quadratically stable: no Lyapunov matrix with I <= P <= 100 I makes "
            f"{form} positive over the range (best eps = {cert.eps:.3g}; the sum-of-squares "
            "form is exact for polynomial dependence on one parameter)"
        )


@pytest.mark.parametrize("discrete", [True, False])
def test_the_note_states_the_certified_inequality(discrete):
    """Rejects a note naming the other time domain's inequality."""
    coef = np.array([[[0.5]], [[0.3]]]) if discrete else np.array([[[-5.0]], [[3.0]]])
    q, cert, note = quadratic_stability(coef, discrete, kappa=1e3)
    ineq = (
        f"[[P, A(p)^T P], [P A(p), P]] >= {cert.mu:.3g} I (hence P - A(p)^T P A(p) > 0)"
        if discrete
        else f"-(A(p)^T P + P A(p)) >= {cert.mu:.3g} I"
    )
    assert q is True
    assert note == (
        f"quadratically stable: a Lyapunov matrix P with I <= P <= 1000 I and {ineq} for "
        "every p in the range (certified from the recomputed sum-of-squares identity, "
        "A(p) of degree 1)"
    )


def test_a_small_valid_certificate_is_still_a_certificate(monkeypatch):
    """Rejects a test of mu or P against 1 instead of 0: P / 1000 proves the same."""

    def shrink(x, status, args):
        return x / 1000.0, status

    _doctor(monkeypatch, shrink)
    coef = np.array([[[0.5]], [[0.3]]])
    q, cert, _ = quadratic_stability(coef, True, kappa=10.0)
    assert np.linalg.eigvalsh(cert.P).max() < 0.1 and 0 < cert.mu < 0.01
    assert cert.mu <= _worst(cert, coef) * (1 + 1e-9)
    assert q is True


@pytest.mark.parametrize("frac, expected", [(0.9, None), (1.1, False)])
def test_negative_eps_is_false_beyond_a_millionth_of_the_scale(monkeypatch, frac, expected):
    """Rejects another threshold than -1e-6 ||P|| (1 + sum ||A_k||) (spectral norms)."""
    A0 = np.array([[0.5, 0.3, 0.1], [-0.2, 0.4, 0.3], [0.1, 0.2, -0.3]])
    A1 = np.array([[0.2, -0.1, 0.2], [0.1, 0.15, -0.1], [0.2, 0.1, 0.1]])
    P = np.diag([3.0, 3.0, 2.0])  # ||P||_2 = 3, far from its Frobenius norm
    size = 3.0 * (1 + np.linalg.norm(A0, 2) + np.linalg.norm(A1, 2))
    eps = -frac * lyapunov._EPS_TOL * size

    def answer(x, status, args):
        x = np.zeros_like(x)
        x[:6] = _svec(P)
        x[-1] = eps
        return x, clarabel.SolverStatus.Solved

    _doctor(monkeypatch, answer)
    q, cert, note = quadratic_stability(np.array([A0, A1]), True)
    assert q is expected
    assert note.startswith("not decided" if expected is None else "not quadratically stable")


@pytest.mark.parametrize("status", ["MaxIterations", "AlmostSolved"])
def test_only_a_solved_lmi_decides(monkeypatch, status):
    """Rejects decisions on an unfinished solve, and refusing a nearly solved one."""

    def mark(x, _, args):
        return x, getattr(clarabel.SolverStatus, status)

    _doctor(monkeypatch, mark)
    q, cert, note = quadratic_stability(np.array([[[0.5]], [[0.3]]]), True)
    if status == "AlmostSolved":
        assert q is True and cert is not None
    else:
        assert q is None and cert is None
        assert note == "not decided: the LMI solver stopped with status MaxIterations"


def test_blocks_up_to_the_limit_are_attempted(monkeypatch):
    """Rejects a limit on the block size that excludes the limit itself."""
    monkeypatch.setattr(lyapunov, "MAX_BLOCK", 4)
    A = np.array([[[0.5, 0.2], [0.0, 0.4]]])  # discrete, degree 0: one block of 4
    assert quadratic_stability(A, True)[0] is True
    q, cert, note = quadratic_stability(np.concatenate([A, 0.1 * A, 0.1 * A]), True)  # 8
    assert q is None and note == "not decided: the LMI is too large (blocks over 4)"


def test_the_solver_prints_nothing(capfd):
    """Rejects a verbose solver writing its log to the user's terminal."""
    quadratic_stability(np.array([[[0.5]], [[0.3]]]), True)
    out, err = capfd.readouterr()
    assert out == "" and err == ""
