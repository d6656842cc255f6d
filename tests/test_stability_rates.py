"""The bounded-rate certificate (stable/rates.py): known answers, an independent program.

Known answers (tests/rate_systems.py): a model conjugated by a nilpotent, where an
explicit degree-2 ``P(p)`` certifies every rate below 1 (a lower bound), and a rotation
in two (and three) parameters, where a periodic scheduling inside the box is unstable
(an upper bound, checked by simulating it). Between them, cvxpy on a dense grid of the
same inequality, written with ``P`` a polynomial of the *physical* parameters (its own
derivative, no chain rule), must be feasible at the certified rate and not at a rate a
little above. A third model has a critical rate known within a factor 1.053 (an
explicit degree-6 ``P(p)`` below it, a resonant sweep of the box above): ``max_rate`` at
degree 6 must land in between. Every certificate is resampled: the inequality's
eigenvalues at random scheduling values and rate vertices, ``dP/dp`` by finite differences
of ``P(p)``.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from rate_systems import (
    LAMBDA_1,
    LAMBDA_2,
    NU_HI,
    NU_LO,
    TILT_A0,
    TILT_N,
    TILT_Q,
    TILT_Q0,
    TILT_RANGE,
    conjugated,
    grows_on_the_circle,
    rotating,
    sampled_worst,
    sweep_monodromy,
    tilted,
    tilted_P,
    witness_rate,
)
from scipy.linalg import expm

import lpvid
from lpvid.model.frozen import frozen_A
from lpvid.stable import boxsos

pytest.importorskip("clarabel")

A0 = np.array([[-1.0, 0.0], [-1.0, -1.0]])
N = np.array([[0.0, 1.0], [0.0, 0.0]])


@pytest.fixture(scope="module")
def conj():
    """One parameter on (0, 3) (the chain rule's factor 2 / 3 matters)."""
    return conjugated(A0, [N], [(0.0, 3.0)])[0]


@pytest.fixture(scope="module")
def rot():
    """Two parameters on a box that is not [-1, 1]^2 (each s_k moves at half the p_k rate)."""
    return rotating(pairs=[(0.0, 4.0), (-2.0, 2.0)])


def _grid_delta(model, nu, per_axis):
    """Best delta of the inequality at grid points, ``P`` of degree 2 in the raw ``p`` (cvxpy)."""
    cp = pytest.importorskip("cvxpy")
    pairs = model.basis.domain
    n_params, n = len(pairs), model.n_states
    exps = [e for e in itertools.product(range(3), repeat=n_params) if sum(e) <= 2]
    Ps = {e: cp.Variable((n, n), symmetric=True) for e in exps}
    pts = np.array(list(itertools.product(*[np.linspace(lo, hi, per_axis) for lo, hi in pairs])))
    delta = cp.Variable()
    cons = []
    step = np.eye(n_params, dtype=int)
    for p, A in zip(pts, frozen_A(model, pts), strict=True):
        P = sum(Ps[e] * float(np.prod(p ** np.array(e))) for e in exps)
        dP = [
            sum(Ps[e] * (e[k] * float(np.prod(p ** (np.array(e) - step[k])))) for e in exps if e[k])
            for k in range(n_params)
        ]
        cons += [P >> np.eye(n), P << 1e7 * np.eye(n)]
        for s in itertools.product((-1.0, 1.0), repeat=n_params):
            L = A.T @ P + P @ A + sum(s[k] * nu[k] * dP[k] for k in range(n_params))
            cons.append(-0.5 * (L + L.T) >> delta * np.eye(n))
    prob = cp.Problem(cp.Maximize(delta), cons)
    prob.solve(solver="CLARABEL")
    assert prob.status.startswith("optimal")
    return float(delta.value)


def test_one_parameter_between_the_explicit_certificate_and_cvxpy(conj, rng):
    """Rejects a chain rule that is lost or doubled, a rate term dropped, a bisection that stops
    early: the rate sits above the known lower bound and within 10 % of the grid program's."""
    found = lpvid.max_rate(conj, rel_tol=0.02)
    assert found.rate.shape == (1,) and found.certificate is not None
    # An explicit P(p) = T(p)^-T P0 T(p)^-1 certifies every rate below 1 (module notes).
    assert found.rate[0] >= 1.0
    assert _grid_delta(conj, found.rate, 60) > 0
    assert _grid_delta(conj, 1.1 * found.rate, 60) < 0
    assert sampled_worst(conj, found.certificate, rng, 1000) >= found.certificate.mu * (1 - 1e-6)
    assert found.certificate.mu > 0 and found.certificate.mu_p > 0


@pytest.fixture(scope="module")
def tilt():
    return tilted()


def _no_root_inside(c, lo, hi):
    """A polynomial (coefficients ``c``, increasing powers) > 0 on [lo, hi], from its roots."""
    poly = np.polynomial.Polynomial(c)
    r = poly.roots()
    inside = r[(np.abs(r.imag) < 1e-9) & (r.real >= lo) & (r.real <= hi)]
    return inside.size == 0 and poly((lo + hi) / 2) > 0


def test_the_known_critical_rate_is_bracketed(tilt):
    """The bracket of rate_systems.tilted, independently of lpvid's certificate (numpy, scipy).

    Below: ``P(p) = q(p) (I - p N)^T Q0 (I - p N)`` certifies NU_LO (the argument's four
    corners and the bounds of q'/q, then the model's own inequality on a grid). Above: the
    sweep of the box at NU_HI is unstable (its monodromy, integrated with the model's A(p)).
    """
    lo, hi = TILT_RANGE
    assert NU_HI / NU_LO < 1.06
    # the argument: Q0 > 0, the four corners negative definite, LAMBDA_1 <= q'/q <= LAMBDA_2
    assert np.linalg.eigvalsh(TILT_Q0).min() > 0
    for s in (1.0, -1.0):
        M = TILT_A0 - s * NU_LO * TILT_N
        for lam in (LAMBDA_1, LAMBDA_2):
            L = M.T @ TILT_Q0 + TILT_Q0 @ M + lam * s * NU_LO * TILT_Q0
            assert np.linalg.eigvalsh(-L).min() > 1e-4
    q = np.polynomial.Polynomial(TILT_Q)
    assert _no_root_inside(q.coef, lo, hi)
    assert _no_root_inside((q.deriv() - LAMBDA_1 * q).coef, lo, hi)
    assert _no_root_inside((LAMBDA_2 * q - q.deriv()).coef, lo, hi)
    # the model's inequality with that P(p), on a grid (dP/dp checked by differences)
    for p in np.linspace(lo, hi, 301):
        P, dP = tilted_P(p)
        fd = (tilted_P(p + 1e-6)[0] - tilted_P(p - 1e-6)[0]) / 2e-6
        np.testing.assert_allclose(dP, fd, rtol=1e-6, atol=1e-7 * np.abs(P).max())
        A = frozen_A(tilt, np.array([[p]]))[0]
        assert np.linalg.eigvalsh(P).min() > 0
        for v in (NU_LO, -NU_LO):
            assert np.linalg.eigvalsh(-(A.T @ P + P @ A + v * dP)).min() > 0
    # the witness: x' = A(p(t)) x along the sweep grows, and as the conjugation says
    Phi = sweep_monodromy(tilt, NU_HI)
    assert np.abs(np.linalg.eigvals(Phi)).max() > 1.003
    tau = (hi - lo) / NU_HI
    M = expm((TILT_A0 + NU_HI * TILT_N) * tau) @ expm((TILT_A0 - NU_HI * TILT_N) * tau)
    np.testing.assert_allclose(
        np.sort_complex(np.linalg.eigvals(Phi)), np.sort_complex(np.linalg.eigvals(M)), rtol=1e-7
    )
    # frozen-stable: every A(p) is similar to A0
    assert lpvid.stability(tilt).stable


def test_max_rate_lands_in_the_known_bracket(tilt, rng):
    """Rejects a certificate that is unsound (above the unstable sweep: a rate term dropped,
    weakened or taken at one rate vertex only, a halved chain rule) or too conservative
    (below an explicit degree-6 P(p): a doubled chain rule, a rate term counted twice)."""
    tol = 0.02
    found = lpvid.max_rate(tilt, degree=6, rel_tol=tol)
    assert NU_LO / (1 + tol) <= found.rate[0] <= NU_HI
    cert = found.certificate
    assert cert.degree == 6 and cert.mu > 0 and cert.mu_p > 0
    assert sampled_worst(tilt, cert, rng, 500) >= cert.mu * (1 - 1e-6)
    # the bisection's promise: a factor 1 + rel_tol above the rate found is not certified
    assert lpvid.rate_stability(tilt, found.rate[0] * (1 + tol), degree=6)[0] is not True
    # the ends themselves, without the bisection
    assert lpvid.rate_stability(tilt, NU_LO, degree=6)[0] is True
    assert lpvid.rate_stability(tilt, NU_HI, degree=6)[0] is None


def test_one_parameter_fixed_rates(conj):
    """Rejects a verdict that is not monotone in the rate, or that ignores it."""
    assert lpvid.rate_stability(conj, 0.9)[0] is True
    assert lpvid.rate_stability(conj, 1e-6)[0] is True
    ok, cert, note = lpvid.rate_stability(conj, 1e4)
    assert ok is None and "not decided" in note
    # Frozen-stable (every A(p) is similar to A0) and not quadratically stable (exact for one p).
    rep = lpvid.stability(conj)
    assert rep.stable and rep.quadratic is False


def test_two_parameters_below_the_unstable_rotation(rot, rng):
    """Rejects an over-claimed rate (a lost factor 2 of dt/dp, rates in t units reported as p
    units): the certificate must stay below a scheduling shown to be unstable, and its own
    inequality must hold where it is sampled."""
    found = lpvid.max_rate(rot)
    assert found.rate.shape == (2,) and found.rate[0] == found.rate[1]  # direction hi - lo
    upper = 2.0 * witness_rate()  # |ds/dt| <= 2 w, |dp/dt| = 2 |ds/dt| on this box
    assert 0.2 * upper < found.rate[0] < upper
    # The witness is real: slightly faster than its rate the state grows, slower it decays.
    w = witness_rate() / 2.0
    assert grows_on_the_circle(rot, 1.05 * w, 20.0) > 5.0
    assert grows_on_the_circle(rot, 0.9 * w, 20.0) < 0.1
    assert sampled_worst(rot, found.certificate, rng, 1000) >= found.certificate.mu * (1 - 1e-6)


def test_two_parameters_tight_against_cvxpy(rot):
    """Rejects a conservative rate (a doubled chain rule, a multiplier dropped, the bisection
    stopping early): the grid program finds no P(p) a quarter above the certified rate."""
    found = lpvid.max_rate(rot)
    assert _grid_delta(rot, found.rate, 7) > 0
    assert _grid_delta(rot, 1.25 * found.rate, 7) < 0


def test_three_parameters(rng):
    """Rejects a rate box without all 2^3 vertices (the third parameter's rate ignored)."""
    rot3 = rotating(shift=0.2)
    found = lpvid.max_rate(rot3)
    # At s3 = 1 the rotation is unstable from |b - w| < sqrt(k^2 - 0.8^2).
    upper = 2.0 * (3.0 - np.sqrt(4.0 - 0.64))
    assert grows_on_the_circle(rot3, 1.05 * upper / 2, 20.0, extra=(1.0,)) > 5.0
    assert 0.2 * upper < found.rate[0] < upper
    assert sampled_worst(rot3, found.certificate, rng, 600) >= found.certificate.mu * (1 - 1e-6)


def test_the_rate_agrees_with_the_frozen_scan_and_the_quadratic_certificate():
    """Rejects rate verdicts that contradict the other checks: a frozen-unstable model is False
    for every rate, a quadratically stable one is certified at a huge rate and reported inf."""
    basis = lpvid.Polynomial(1, domain=(0.0, 1.0))
    one = [[[1.0]], [[0.0]]]
    quad = lpvid.LpvModel(
        [[[-2.0, 1.0], [-1.0, -2.0]], [[0.5, 0.0], [0.0, 0.5]]],
        np.zeros((2, 2, 1)),
        np.zeros((2, 1, 2)),
        basis=basis,
    )
    assert lpvid.rate_stability(quad, 1e6)[0] is True
    rep = lpvid.stability(quad, rate=True)
    assert rep.quadratic is True and np.all(np.isinf(rep.rate))
    assert "any rate" in rep.summary()
    bad = lpvid.LpvModel([[[-0.5]], [[1.0]]], one, one, basis=basis)  # a = -0.5 + s, > 0 at s > 0.5
    ok, cert, note = lpvid.rate_stability(bad, 1e-9)
    assert ok is False and cert is None and "unstable" in note
    rep = lpvid.stability(bad, rate=True)
    assert not rep.stable and rep.rate is None and "any rate" in rep.rate_note


def test_report_lines_and_fields(rot):
    rep = lpvid.stability(rot, rate=True)
    assert rep.quadratic is False and rep.rate.shape == (2,)
    assert rep.rate_certificate is not None and np.all(rep.rate_certificate.rate == rep.rate)
    lines = rep.summary().splitlines()
    assert len(lines) == 3 and lines[2].startswith("bounded rate: certified for |dp/dt| <=")
    assert (
        lpvid.stability(rot).rate is None and len(lpvid.stability(rot).summary().splitlines()) == 2
    )


def test_discrete_time_is_refused():
    basis = lpvid.Polynomial(1, domain=(0.0, 1.0))
    one = [[[1.0]], [[0.0]]]
    m = lpvid.LpvModel([[[0.5]], [[0.2]]], one, one, basis=basis, Ts=0.1)
    with pytest.raises(ValueError, match="model: the rate certificate is for continuous-time"):
        lpvid.rate_stability(m, 0.1)
    with pytest.raises(ValueError, match="model:"):
        lpvid.max_rate(m)
    rep = lpvid.stability(m, rate=True)
    assert rep.rate is None and "continuous-time" in rep.rate_note


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"rate": -1.0}, "rate:"),
        ({"rate": [0.1, 0.2]}, "rate:"),
        ({"rate": float("nan")}, "rate:"),
        ({"rate": 0.1, "degree": -1}, "degree:"),
        ({"rate": 0.1, "extra": 1.5}, "extra:"),
    ],
)
def test_bad_arguments(conj, kwargs, match):
    with pytest.raises(ValueError, match=match):
        lpvid.rate_stability(conj, **kwargs)


def test_bad_max_rate_arguments(conj):
    with pytest.raises(ValueError, match="direction:"):
        lpvid.max_rate(conj, direction=[0.0])
    with pytest.raises(ValueError, match="rel_tol:"):
        lpvid.max_rate(conj, rel_tol=0.0)
    with pytest.raises(TypeError, match="model:"):
        lpvid.rate_stability("model", 0.1)


def test_too_large_a_program_is_refused_before_any_work(monkeypatch):
    """Rejects a size check that runs after the solver, or a message without the sizes."""
    n = 45
    rng = np.random.default_rng(3)
    A = -3.0 * np.eye(n) + 0.1 * rng.standard_normal((n, n))
    basis = lpvid.Polynomial(1, domain=[(0.0, 1.0)] * 3)
    X = np.stack([A] + [0.1 * np.eye(n)] * 3)
    m = lpvid.LpvModel(X, np.zeros((4, n, 1)), np.zeros((4, 1, n)), basis=basis)
    import clarabel

    def boom(*args):
        raise AssertionError("the solver was started")

    monkeypatch.setattr(clarabel, "DefaultSolver", boom)
    size = boxsos.program_size(n, 3, 1, 2, False)
    assert max(size["blocks"]) == n * 10 > boxsos.MAX_BLOCK
    with pytest.raises(MemoryError, match=r"blocks up to 450 x 450, 36 blocks"):
        lpvid.rate_stability(m, 0.1)
    rep = lpvid.stability(m, rate=True, quadratic=False)
    assert rep.rate is None and "too large" in rep.rate_note


def test_program_size_formula():
    """The size stated in the module notes, on a case counted by hand."""
    # n = 8, two parameters, A of degree 2, P of degree 2: m = 2, M(2) = 6, M(1) = 3, M(4) = 15.
    size = boxsos.program_size(8, 2, 2, 2, False)
    # four vertices: a block of 48 and two of 24; P(p) - I: m = 1, a block of 24, two of 8.
    assert size["blocks"] == [48, 24, 24] * 4 + [24, 8, 8]
    assert size["equations"] == 4 * 36 * 15 + 36 * 6


def test_the_certificate_derivative_is_the_chain_rule(rot, rng):
    """Rejects dP_at without the factor 2 / (hi - lo) (or on the wrong parameter)."""
    cert = lpvid.max_rate(rot, rel_tol=0.5).certificate
    for _ in range(5):
        p = rng.uniform([0.0, -2.0], [4.0, 2.0])
        for k in range(2):
            h = np.eye(2)[k] * 1e-6
            fd = (cert.P_at(p + h) - cert.P_at(p - h)) / 2e-6
            np.testing.assert_allclose(
                cert.dP_at(p)[k], fd, rtol=1e-6, atol=1e-6 * np.abs(fd).max()
            )
        A = frozen_A(rot, p[None, :])[0]
        v = cert.rate * np.array([1.0, -1.0])
        assert np.linalg.eigvalsh(cert.inequality(A, p, v)).min() >= cert.mu * (1 - 1e-9)


def _doctored_P(monkeypatch, n, edit):
    """Clarabel's answer with the coefficients of P(t) (the first unknowns) edited."""
    from test_lyapunov import _doctor

    k = n * (n + 1) // 2

    def change(x, status, args):
        edit(x, k)
        return x, status

    _doctor(monkeypatch, change)


def test_every_rate_vertex_is_paid_for(monkeypatch, conj, rng):
    """Rejects a bound taken at one vertex of the rate box only: dP/dt shifted so that the
    vertex v = -nu loses, the other vertex's identity kept exact by its Gram matrices (the
    certificate need not certify: its bound must be a bound all the same)."""
    from test_lyapunov import _doctor

    from lpvid.stable import boxsos as box
    from lpvid.stable.lyapunov import _svec

    k = 3  # unknowns of one 2 x 2 coefficient P_b
    rows = len(box.monomials(4, 1)) * 3  # equations of one vertex (m = 2, q = 2)

    def edit(x, status, args):
        _, _, Acon, _, cones, _ = args
        Aeq = Acon[: cones[0].dim].toarray()
        dx = np.zeros_like(x)
        dx[k : 2 * k] = -0.05 * np.abs(x[:k]).max() * _svec(np.eye(2))
        last = slice(rows, 2 * rows)  # the vertex v = +nu, last in the program
        cols = [j for j in range(3 * k, x.size - 1) if np.any(Aeq[last, j])]
        dq = np.linalg.lstsq(Aeq[last][:, cols], -Aeq[last] @ dx, rcond=None)[0]
        dx[cols] = dq
        assert np.allclose(Aeq[last] @ dx, 0.0, atol=1e-9 * np.abs(x).max())
        return x + dx, status

    _doctor(monkeypatch, edit)
    # A fast rate: the rate term outweighs what the shift does through A(p).
    _, cert, _ = lpvid.rate_stability(conj, 300.0)
    assert cert.mu <= sampled_worst(conj, cert, rng, 1000) * (1 + 1e-9)


def test_an_indefinite_P_is_not_a_certificate(monkeypatch, conj):
    """Rejects a verdict without P(p) > 0 (its sum of squares dropped, or mu_P not asked)."""
    from lpvid.stable.lyapunov import _svec

    def edit(x, k):
        x[:k] -= 3.0 * _svec(np.eye(2))

    _doctored_P(monkeypatch, 2, edit)
    ok, cert, _ = lpvid.rate_stability(conj, 0.5)
    assert cert.mu > 0  # the derivative's inequality alone would still pass
    assert ok is not True and cert.mu_p < 0


def test_the_report_computes_small_programs_only(conj):
    """``rate="small"`` (the report's choice): seconds, not minutes; the note says how to ask."""
    rep = lpvid.stability(conj, rate="small")
    assert rep.rate is not None and rep.rate[0] >= 1.0
    big = rotating(pairs=[(0.0, 1.0)] * 2)
    n = 10
    X = np.zeros((3, n, n))
    for i in range(0, n, 2):
        X[:, i : i + 2, i : i + 2] = big.A
    wide = lpvid.LpvModel(X, np.zeros((3, n, 1)), np.zeros((3, 1, n)), basis=big.basis)
    rep = lpvid.stability(wide, rate="small", quadratic=False)
    assert rep.rate is None and "lpvid.max_rate(model) computes it" in rep.rate_note
    with pytest.raises(ValueError, match="rate:"):
        lpvid.stability(conj, rate="yes")


def test_a_basis_on_the_log_scale_takes_the_rate_at_the_low_end(conj, rng):
    """The rate of ``p`` on the log scale against the same coefficients on ``u = log10(p)``.

    ``|du/dt| = |dp/dt| / (p ln 10) <= nu / (lo ln 10)``: the certificate for the model of
    ``u`` at ``nu_u`` holds for the log-scale model at ``nu_u lo ln 10``, which is what the
    program takes (rejects the linear chain rule on the log scale, which would claim rates
    ``(hi - lo) / ((log10 hi - log10 lo) lo ln 10)`` = 3.9 times larger here).
    """
    lo, hi = 0.5, 5.0
    log = lpvid.LpvModel(
        conj.A, conj.B, conj.C, basis=lpvid.Polynomial(2, domain=(lo, hi), scale="log")
    )
    twin = lpvid.LpvModel(
        conj.A, conj.B, conj.C, basis=lpvid.Polynomial(2, domain=(np.log10(lo), np.log10(hi)))
    )
    tol = 0.02
    on_u = lpvid.max_rate(twin, rel_tol=tol).rate[0]
    found = lpvid.max_rate(log, rel_tol=tol)
    expected = on_u * lo * np.log(10.0)
    assert expected / (1 + tol) ** 2 <= found.rate[0] <= expected * (1 + tol) ** 2
    cert = found.certificate
    assert cert.scales == ("log",)
    # the certificate holds with the exact chain rule everywhere in the box
    assert sampled_worst(log, cert, rng, 500) >= cert.mu * (1 - 1e-6)
    for p in (0.6, 2.0, 4.9):
        h = 1e-6 * p
        fd = (cert.P_at(p + h) - cert.P_at(p - h)) / (2 * h)
        np.testing.assert_allclose(cert.dP_at(p)[0], fd, rtol=1e-6, atol=1e-6 * np.abs(fd).max())
    # the report's stability and the quadratic certificate see the same model as the twin's
    assert lpvid.stability(log).quadratic == lpvid.stability(twin).quadratic
