"""lpvid.trust.enforce.stabilised in continuous time, against the poles computed by hand.

A(p) = [[a p + c, w], [-w, a p + c]] has the poles ``a p + c +- j w``: the
largest real part and the largest magnitude over p in [-1, 1] are at the
ends, so the shift the docstring promises is known in closed form.
"""

from __future__ import annotations

import numpy as np
import pytest

import lpvid
from lpvid.trust.enforce import stabilised

BASIS = lpvid.Polynomial(1, domain=(-1.0, 1.0))


def _rotating(
    a: float, c: float, w: float, d: float = 0.0, basis: lpvid.Basis = BASIS
) -> lpvid.LpvModel:
    """Continuous time, poles ``a p + c +- j w`` (``d`` adds a skew part to A(1))."""
    A = np.zeros((2, 2, 2))
    A[0] = [[c, w], [-w, c]]
    A[1] = [[a, d], [-d, a]]
    B = np.zeros((2, 2, 1))
    B[0] = [[1.0], [0.5]]
    B[1] = [[0.2], [0.0]]
    C = np.zeros((2, 1, 2))
    C[0] = [[1.0, 0.0]]
    C[1] = [[0.0, 0.3]]
    return lpvid.LpvModel(A, B, C, basis=basis, p_range=(-1.0, 1.0))


def _poles(model: lpvid.LpvModel, p: np.ndarray) -> np.ndarray:
    """Eigenvalues of A(p) = A0 + psi(p) A1 by numpy, one row per p."""
    psi = model.basis(np.asarray(p, dtype=float))[:, 0]
    return np.array([np.linalg.eigvals(model.A[0] + s * model.A[1]) for s in psi])


@pytest.mark.parametrize("margin", [1e-3, 0.3])
def test_continuous_shift_is_the_promised_one(margin):
    """Only A(0) moves, by -alpha I, alpha = max Re(pole) + margin max |pole| over the range."""
    m = _rotating(a=0.8, c=0.2, w=1.5, d=0.4)
    p = np.linspace(-1.0, 1.0, 401)
    before = _poles(m, p)
    # The poles a p + c +- j (w + d p): extremes at the ends of the range.
    re_max = 0.8 + 0.2
    abs_max = abs(complex(1.0, 1.9))
    assert np.max(before.real) == pytest.approx(re_max, rel=1e-12)
    assert np.max(np.abs(before)) == pytest.approx(abs_max, rel=1e-12)
    alpha = re_max + margin * abs_max
    s = stabilised(m, margin=margin)
    np.testing.assert_allclose(s.A[0], m.A[0] - alpha * np.eye(2), rtol=0, atol=1e-12 * alpha)
    np.testing.assert_array_equal(s.A[1], m.A[1])
    for name in "BCD":
        np.testing.assert_array_equal(getattr(s, name), getattr(m, name))
    after = _poles(s, p)
    # Every pole left of -margin times the largest pole magnitude (before the shift).
    assert np.max(after.real) <= -margin * abs_max * (1 - 1e-9)
    rep = lpvid.stability(s, quadratic=False)
    assert rep.stable and rep.margin > 0


def test_continuous_range_wider_than_the_model():
    """The range asked for is the one made stable, not the model's own."""
    # psi(p) = p / 2 on the domain (-2, 2): poles p - 0.5 +- j, stable only for p < 0.5.
    m = _rotating(a=2.0, c=-0.5, w=1.0, basis=lpvid.Polynomial(1, domain=(-2.0, 2.0)))
    assert lpvid.stability(m, (-1.0, 0.25), quadratic=False).stable
    s = stabilised(m, (-2.0, 2.0), margin=0.01)
    p = np.linspace(-2.0, 2.0, 801)
    before = _poles(m, p)
    alpha = np.max(before.real) + 0.01 * np.max(np.abs(before))
    assert alpha == pytest.approx(1.5 + 0.01 * abs(complex(-2.5, 1.0)), rel=1e-12)
    np.testing.assert_allclose(s.A[0], m.A[0] - alpha * np.eye(2), atol=1e-12)
    assert lpvid.stability(s, (-2.0, 2.0), quadratic=False).stable


def test_continuous_stable_enough_is_returned_unchanged():
    """A model already stable with the margin asked for is the same object."""
    m = _rotating(a=0.1, c=-1.0, w=0.5)
    assert stabilised(m, margin=1e-3) is m
    # Stable, but closer to the boundary than asked: moved.
    moved = stabilised(m, margin=0.99)
    assert moved is not m
    assert np.max(_poles(moved, np.linspace(-1, 1, 101)).real) < np.max(
        _poles(m, np.linspace(-1, 1, 101)).real
    )


def test_discrete_scaling_is_the_promised_one():
    """Discrete time: every coefficient of A scaled by (1 - margin) / rho, B, C, D kept."""
    k = len(BASIS) + 1
    A = np.zeros((k, 2, 2))
    A[0] = [[0.9, 0.3], [-0.3, 0.9]]
    A[1] = [[0.2, 0.0], [0.0, 0.2]]
    B, C = np.ones((k, 2, 1)), np.ones((k, 1, 2))
    m = lpvid.LpvModel(A, B, C, basis=BASIS, Ts=0.1, p_range=(-1.0, 1.0))
    rho = abs(complex(1.1, 0.3))  # at p = 1
    s = stabilised(m, margin=0.05)
    np.testing.assert_allclose(s.A, m.A * (0.95 / rho), rtol=1e-9)
    np.testing.assert_array_equal(s.B, m.B)
    np.testing.assert_array_equal(s.C, m.C)
    rep = lpvid.stability(s, quadratic=False)
    assert rep.margin == pytest.approx(0.05, rel=1e-6)
