"""lpvid.stable.enforce.stabilised in continuous time, against the poles computed by hand.

A(p) = [[a p + c, w], [-w, a p + c]] has the poles ``a p + c +- j w``: the
largest real part and the largest magnitude over p in [-1, 1] are at the
ends, so the shift the docstring promises is known in closed form.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

import lpvid
from lpvid.stable.enforce import (
    BOX_POINTS,
    CHECK_POINTS,
    MAX_ROUNDS,
    check_points,
    run_stable,
    stabilised,
)

BASIS = lpvid.Polynomial(1, domain=(-1.0, 1.0))


def _rotating(
    a: float,
    c: float,
    w: float,
    d: float = 0.0,
    basis: lpvid.Basis = BASIS,
    p_range: tuple[float, float] = (-1.0, 1.0),
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
    D = np.zeros((2, 1, 1))
    D[0, 0, 0], D[1, 0, 0] = 0.1, -0.05
    return lpvid.LpvModel(
        A, B, C, D, basis=basis, p_range=p_range, info={"made by": "test_enforce"}
    )


def _poles(model: lpvid.LpvModel, p: np.ndarray) -> np.ndarray:
    """Eigenvalues of A(p) = A0 + psi(p) A1 by numpy, one row per p."""
    psi = model.basis(np.asarray(p, dtype=float))[:, 0]
    return np.array([np.linalg.eigvals(model.A[0] + s * model.A[1]) for s in psi])


@pytest.mark.parametrize("margin", [1e-3, 0.3])
def test_continuous_shift_is_the_promised_one(margin):
    """Only A(0) moves, by -alpha I, alpha = max Re(pole) + margin max |pole| over the range."""
    # On (-0.5, 1) (not the basis domain): the extremes are at p = 1.
    m = _rotating(a=0.8, c=-0.3, w=1.5, d=0.4, p_range=(-0.5, 1.0))
    p = np.linspace(-0.5, 1.0, 401)
    before = _poles(m, p)
    # The poles a p + c +- j (w + d p): extremes at the ends of the range.
    re_max = 0.8 - 0.3
    abs_max = abs(complex(0.5, 1.9))
    assert np.max(before.real) == pytest.approx(re_max, rel=1e-12)
    assert np.max(np.abs(before)) == pytest.approx(abs_max, rel=1e-12)
    alpha = re_max + margin * abs_max
    s = stabilised(m, margin=margin)
    np.testing.assert_allclose(s.A[0], m.A[0] - alpha * np.eye(2), rtol=0, atol=1e-12 * alpha)
    np.testing.assert_array_equal(s.A[1], m.A[1])
    for name in "BCD":
        np.testing.assert_array_equal(getattr(s, name), getattr(m, name))
    assert s.p_range == m.p_range and s.info == m.info and s.Ts is None
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


def _two_parameter() -> lpvid.LpvModel:
    """Discrete time, A(p) = A0 + p1 A1 + p2 A2 over the box [-1, 1] x [0, 2]."""
    basis = lpvid.Polynomial(1, domain=[(-1.0, 1.0), (0.0, 2.0)])
    k = len(basis) + 1
    A = np.zeros((k, 2, 2))
    A[0] = [[0.5, 0.2], [-0.1, 0.4]]
    A[1] = [[0.1, 0.0], [0.05, -0.1]]
    A[2] = [[0.0, 0.1], [0.0, 0.15]]
    B, C = np.ones((k, 2, 1)), np.ones((k, 1, 2))
    return lpvid.LpvModel(A, B, C, basis=basis, Ts=1.0, p_range=[(-1.0, 1.0), (0.0, 2.0)])


def _frozen_margins(model: lpvid.LpvModel, pts: np.ndarray) -> np.ndarray:
    """1 - spectral radius of A(p) at every row of pts, by numpy."""
    psi = model.basis(pts)
    return np.array(
        [
            1.0 - np.max(np.abs(np.linalg.eigvals(model.A[0] + np.tensordot(s, model.A[1:], 1))))
            for s in psi
        ]
    )


def test_check_points_cover_the_box_of_two_parameters():
    """Several parameters: the core checks a grid over the whole box, plus the extra points."""
    m = _two_parameter()
    pairs = [(-1.0, 1.0), (0.0, 2.0)]
    points = check_points(m, pairs, [])
    side = int(np.floor(np.sqrt(BOX_POINTS)))
    assert len(points) == side * side
    g = np.linspace(-1.0, 1.0, side)
    h = np.linspace(0.0, 2.0, side)
    grid = np.array([(a, b) for a in g for b in h])
    got = np.sort(points.margins(m.theta))
    np.testing.assert_allclose(got, np.sort(_frozen_margins(m, grid)), rtol=1e-9, atol=1e-12)
    extra = [np.array([0.123, 1.777]), np.array([-0.9, 0.05])]
    more = check_points(m, pairs, extra)
    assert len(more) == side * side + 2
    with_extra = np.sort(more.margins(m.theta))
    want = np.sort(_frozen_margins(m, np.concatenate([grid, np.array(extra)])))
    np.testing.assert_allclose(with_extra, want, rtol=1e-9, atol=1e-12)


def test_check_points_of_one_parameter_with_extra_points():
    """One parameter: CHECK_POINTS evenly over the range, an extra point added exactly once."""
    m = _rotating(a=0.8, c=-2.0, w=1.5)
    points = check_points(m, [(-1.0, 1.0)], [])
    assert len(points) == CHECK_POINTS
    more = check_points(m, [(-1.0, 1.0)], [0.1234, 1.0])  # 1.0 is already a check point
    assert len(more) == CHECK_POINTS + 1
    p = np.unique(np.concatenate([np.linspace(-1.0, 1.0, CHECK_POINTS), [0.1234]]))
    psi = m.basis(p)[:, 0]
    poles = np.array([np.linalg.eigvals(m.A[0] + s * m.A[1]) for s in psi])
    want = np.min(-poles.real / np.abs(poles), axis=1)
    np.testing.assert_allclose(more.margins(m.theta), want, rtol=1e-9)


def test_run_stable_gives_up_after_its_rounds_naming_the_last_place():
    """A fit that keeps leaving the stable set: MAX_ROUNDS runs, the last place named."""
    m = _rotating(a=0.8, c=-2.0, w=1.5)
    calls: list[int] = []
    # Unstable at p = 1, then at p = -1, then at p = 1 again: the message names the last.
    slopes = iter([1.0, -1.0, 1.0, -1.0])

    def run(points):
        calls.append(len(points))
        return SimpleNamespace(
            theta=_rotating(a=next(slopes), c=0.5, w=1.5).theta, interrupted=False
        )

    with pytest.raises(RuntimeError, match=r"after 3 rounds .*\(at p = 1\)"):
        run_stable(m, None, run)
    assert len(calls) == MAX_ROUNDS


def test_run_stable_refuses_an_unstable_start():
    """The start is checked over the range asked for, with the place and margin named."""
    m = _rotating(a=0.8, c=0.2, w=1.5)
    with pytest.raises(
        ValueError,
        match=r"stable=True needs a stable start.* p = 1 is unstable .*start from a stable model "
        r"\(e\.g\. lpvid\.stable\.enforce\.stabilised\(model\)\) or narrow p_range$",
    ):
        run_stable(m, None, lambda points: SimpleNamespace())
