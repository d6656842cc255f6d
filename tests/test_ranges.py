"""Scheduling ranges of stability statements (lpvid.stable.ranges): checks, grids, A(p).

Small direct checks against what the range and the model say; each test
names the wrong code it rejects.
"""

from __future__ import annotations

import numpy as np
import pytest

import lpvid
from lpvid.stable.ranges import as_convention, box_grid, check_range, polynomial_A, to_p


def _model(basis, n=2, seed=0):
    rng = np.random.default_rng(seed)
    k = len(basis) + 1
    A = 0.3 * rng.normal(size=(k, n, n))
    return lpvid.LpvModel(A, rng.normal(size=(k, n, 1)), rng.normal(size=(k, 1, n)), basis=basis)


def test_the_range_given_else_the_models_inside_the_domain():
    """Rejects the model's domain taken over a range given, or a range outside let through."""
    m = _model(lpvid.Polynomial(1, domain=(10.0, 20.0)))
    assert check_range(m, None) == [(10.0, 20.0)]
    assert check_range(m, (12.0, 15.0)) == [(12.0, 15.0)]
    # Slack relative to the domain's width (1e-9 of 10).
    assert check_range(m, (10.0 - 5e-9, 20.0 + 5e-9)) == [(10.0 - 5e-9, 20.0 + 5e-9)]
    for lo, hi in ((10.0 - 2e-8, 15.0), (12.0, 20.0 + 2e-8), (0.0, 30.0)):
        with pytest.raises(ValueError) as info:
            check_range(m, (lo, hi))
        assert str(info.value) == (
            f"p_range: ({lo:g}, {hi:g}) reaches outside the basis domain (10, 20), "
            "where the model is an extrapolation"
        )


def test_several_parameters_name_the_one_outside():
    """Rejects the parameter left unnamed or wrongly numbered in the refusal."""
    m = _model(lpvid.Polynomial(1, domain=[(0.0, 1.0), (-2.0, 2.0)]))
    assert check_range(m, None) == [(0.0, 1.0), (-2.0, 2.0)]
    with pytest.raises(ValueError, match=r"^p_range: \(-3, 1\) of parameter 1 reaches outside .*"):
        check_range(m, [(0.0, 1.0), (-3.0, 1.0)])
    with pytest.raises(ValueError, match=r"^p_range: \(0, 1.5\) of parameter 0 reaches outside"):
        check_range(m, [(0.0, 1.5), (-1.0, 1.0)])
    with pytest.raises(ValueError, match="^p_range: "):
        check_range(m, (0.0, 1.0))  # one pair for two parameters


def test_a_model_without_domain():
    """Rejects an LTI model asked for a range, or a basis without domain run without one."""
    lti = lpvid.LpvModel([[[0.5]]], [[[1.0]]], [[[1.0]]])
    assert check_range(lti, None) == [(0.0, 0.0)]
    free = _model(lpvid.Polynomial(2))
    with pytest.raises(ValueError) as info:
        check_range(free, None)
    assert str(info.value) == (
        "p_range: the model has no scheduling range (its basis has no domain); "
        "pass p_range=(lo, hi)"
    )
    assert check_range(free, (-3.0, 4.0)) == [(-3.0, 4.0)]  # any range then
    with pytest.raises(TypeError, match="^model: expected an LpvModel, got str$"):
        check_range("model", (0.0, 1.0))


def test_a_basis_not_finite_on_the_range_is_refused():
    """Rejects a range on which a basis function is infinite."""
    m = _model(lpvid.CustomBasis([lambda p: np.where(p > 0, 1.0, np.inf)]))
    assert check_range(m, (1.0, 2.0)) == [(1.0, 2.0)]
    with pytest.raises(ValueError, match="not finite"):
        check_range(m, (-1.0, 2.0))


def test_as_convention():
    """Rejects one pair returned as a list, or several as one pair."""
    assert as_convention([(0.0, 1.0)]) == (0.0, 1.0)
    assert as_convention([(0.0, 1.0), (2.0, 3.0)]) == [(0.0, 1.0), (2.0, 3.0)]


@pytest.mark.parametrize(
    ("pairs", "max_points", "per_axis"),
    [
        ([(0.0, 1.0)], 50, 50),
        ([(2.0, 4.0), (-1.0, 1.0)], 50, 7),
        ([(0.0, 1.0), (0.0, 2.0), (1.0, 3.0)], 30, 3),
        ([(0.0, 1.0), (0.0, 2.0), (1.0, 3.0)], 5, 2),
        ([(0.0, 1.0)] * 4, 100, 3),
    ],
)
def test_box_grid(pairs, max_points, per_axis):
    """Rejects a grid with the wrong number of values per axis, or not spanning the box."""
    g = box_grid(pairs, max_points)
    assert g.shape == (per_axis ** len(pairs), len(pairs))
    for k, (lo, hi) in enumerate(pairs):
        np.testing.assert_allclose(np.unique(g[:, k]), np.linspace(lo, hi, per_axis))
    # Every combination once.
    assert len({tuple(r) for r in g}) == len(g)


def test_to_p_maps_the_unit_interval_onto_the_pair():
    """Rejects the affine map with a wrong offset or scale."""
    np.testing.assert_allclose(to_p([-1.0, 0.0, 0.5, 1.0], (2.0, 6.0)), [2.0, 4.0, 5.0, 6.0])


@pytest.mark.parametrize("kind", [lpvid.Polynomial, lpvid.Legendre])
def test_polynomial_A_reproduces_A_on_the_range(kind):
    """Rejects coefficients that do not give A(p) at t mapped from the range."""
    m = _model(kind(3, domain=(0.0, 10.0)), n=3)
    pair = (2.0, 7.0)
    coef = polynomial_A(m, [pair])
    assert coef.shape == (4, 3, 3)
    t = np.linspace(-1.0, 1.0, 9)
    direct = np.array([m.at(p)[0] for p in to_p(t, pair)])
    again = np.tensordot(np.vander(t, 4, increasing=True), coef, axes=1)
    np.testing.assert_allclose(again, direct, atol=1e-12 * np.abs(direct).max())


def test_polynomial_A_drops_trailing_zero_coefficients():
    """Rejects trailing zero coefficients kept, or nonzero ones dropped."""
    basis = lpvid.Polynomial(3, domain=(0.0, 1.0))
    m = _model(basis)
    A = m.A.copy()
    A[2:] = 0.0  # affine in p: degree 1 in t
    coef = polynomial_A(lpvid.LpvModel(A, m.B, m.C, basis=basis), [(0.0, 1.0)])
    assert coef.shape[0] == 2
    A[1:] = 0.0
    A[3] = 1e-3  # only the cubic term beside the constant
    assert polynomial_A(lpvid.LpvModel(A, m.B, m.C, basis=basis), [(0.0, 1.0)]).shape[0] == 4
    A[:] = 0.0
    zero = polynomial_A(lpvid.LpvModel(A, m.B, m.C, basis=basis), [(0.0, 1.0)])
    np.testing.assert_array_equal(zero, np.zeros((1, 2, 2)))


def test_polynomial_A_of_other_models():
    """Rejects a polynomial claimed for a custom basis or two parameters, or lost for LTI."""
    lti = lpvid.LpvModel([[[0.5, 0.1], [0.0, 0.3]]], [[[1.0], [0.0]]], [[[1.0, 0.0]]])
    np.testing.assert_array_equal(polynomial_A(lti, [(0.0, 0.0)]), lti.A[:1])
    assert polynomial_A(_model(lpvid.CustomBasis([np.sin])), [(0.0, 1.0)]) is None
    two = _model(lpvid.Polynomial(1, domain=[(0.0, 1.0), (0.0, 1.0)]))
    assert polynomial_A(two, [(0.0, 1.0), (0.0, 1.0)]) is None


@pytest.mark.parametrize("scale", [1e-4, 1.0, 1e4])
def test_polynomial_A_at_any_scale_of_A(scale):
    """Rejects a check or cut-off of trailing coefficients that is not relative to A's size."""
    # Over its own domain t is the scaled p: the coefficients in t are the model's A(k).
    # The cubic one is 1e-12 of the largest (kept), the quartic 1e-15 (counts as zero).
    basis = lpvid.Polynomial(4, domain=(0.0, 1.0))
    rel = [1.0, -0.5, 0.25, 1e-12, 1e-15]
    A = scale * np.array([[[r, 0.3 * r], [-0.2 * r, 0.9 * r]] for r in rel])
    B, C = np.ones((5, 2, 1)), np.ones((5, 1, 2))
    coef = polynomial_A(lpvid.LpvModel(A, B, C, basis=basis), [(0.0, 1.0)])
    assert coef is not None and coef.shape == (4, 2, 2)
    np.testing.assert_allclose(coef[:3], A[:3], rtol=1e-9)
    np.testing.assert_allclose(coef[3], A[3], rtol=1e-2, atol=1e-14 * scale)
