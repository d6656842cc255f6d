"""Basis functions: values, scaling, sup norms, names."""

import numpy as np
import pytest
from numpy.polynomial import legendre

import lpvid


def test_polynomial_maps_the_domain_to_unit_interval():
    b = lpvid.Polynomial(4, domain=(24, 48))
    p = np.array([24.0, 30.0, 36.0, 42.0, 48.0])
    s = (p - 36.0) / 12.0
    np.testing.assert_allclose(b(p), np.stack([s, s**2, s**3, s**4], axis=1))
    assert b.names == ["s", "s^2", "s^3", "s^4"]
    np.testing.assert_allclose(b.sup_norms((24, 48)), [1, 1, 1, 1])
    np.testing.assert_allclose(b.sup_norms((36, 42)), [0.5, 0.25, 0.125, 0.0625])


def test_polynomial_without_domain_uses_p():
    b = lpvid.Polynomial(2)
    np.testing.assert_allclose(b([2.0, -3.0]), [[2, 4], [-3, 9]])
    np.testing.assert_allclose(b.sup_norms((-3, 2)), [3, 9])


@pytest.mark.parametrize("seed", range(4))
def test_polynomial_sup_norms_from_the_corners_are_a_dense_grids_maximum(seed):
    # The polynomial bases take the sup over the box's corners only; a dense
    # grid of the box (the general bases' rule, written out here) finds the
    # same values bit for bit, with one, two and three parameters, with and
    # without a domain, and boxes across zero.
    rng = np.random.default_rng(seed)
    for _ in range(25):
        n_params = int(rng.integers(1, 4))
        domain = [tuple(sorted(rng.normal(0, 10, 2))) for _ in range(n_params)]
        b = lpvid.Polynomial(
            int(rng.integers(1, 6)),
            domain=domain if rng.random() < 0.7 else None,
            n_params=n_params,
        )
        box = [tuple(sorted(rng.normal(0, 10, 2))) for _ in range(n_params)]
        axes = [np.linspace(lo, hi, {1: 2001, 2: 101, 3: 21}[n_params]) for lo, hi in box]
        grid = np.stack([g.ravel() for g in np.meshgrid(*axes, indexing="ij")], axis=1)
        dense = np.max(np.abs(b(grid)), axis=0)
        assert np.array_equal(b.sup_norms(box if n_params > 1 else box[0]), dense)


def test_sup_norms_found_again_are_the_first_and_a_bad_range_is_refused_every_time():
    # A polynomial basis keeps the sup norms of a range it has seen (every
    # model built checks its range by them): the second answer is the
    # first without evaluating the basis again, the caller's copy is
    # theirs to change, a refused range is refused again, and a copy sent
    # to another process is the same bytes as a fresh basis.
    import pickle

    b = lpvid.Polynomial(3, domain=(1.0, 100.0), scale="log")
    fresh = pickle.dumps(b)
    calls = []
    evaluate = b._evaluate
    b._evaluate = lambda p: calls.append(len(p)) or evaluate(p)
    first = b.sup_norms((2.0, 50.0))
    assert len(calls) == 1
    first[:] = -1.0
    again = b.sup_norms((2.0, 50.0))
    assert len(calls) == 1
    other = lpvid.Polynomial(3, domain=(1.0, 100.0), scale="log")
    assert np.array_equal(again, other.sup_norms((2.0, 50.0))) and np.all(again > 0)
    assert not np.array_equal(b.sup_norms((10.0, 20.0)), again) and len(calls) == 2
    for _ in range(2):
        with pytest.raises(ValueError, match="p_range"):
            b.sup_norms((-1.0, 50.0))
    del b._evaluate
    assert pickle.dumps(b) == fresh


def test_legendre_sup_norms_inside_the_domain_are_not_at_the_corners():
    # P2(s) = (3 s^2 - 1) / 2 is largest in size at s = 0 on [-0.5, 0.5]
    # (|-0.5| against 0.125 at the ends): the grid finds it.
    b = lpvid.Legendre(2, domain=(-1, 1))
    np.testing.assert_allclose(b.sup_norms((-0.5, 0.5)), [0.5, 0.5])


def test_legendre_matches_numpy():
    b = lpvid.Legendre(3, domain=(0, 2))
    p = np.linspace(0, 2, 7)
    s = p - 1
    ref = np.stack([legendre.legval(s, np.eye(4)[d]) for d in (1, 2, 3)], axis=1)
    np.testing.assert_allclose(b(p), ref, atol=1e-15)
    np.testing.assert_allclose(b.sup_norms((0, 2)), [1, 1, 1])


def test_two_scheduling_parameters():
    b = lpvid.Polynomial(2, domain=[(0, 1), (0, 2)])
    assert b.n_params == 2
    assert b.names == ["s1", "s2", "s1^2", "s1*s2", "s2^2"]
    v = b(np.array([[1.0, 0.0], [0.5, 2.0]]))
    np.testing.assert_allclose(v, [[1, -1, 1, -1, 1], [0, 1, 0, 0, 1]])


def test_custom_basis():
    b = lpvid.CustomBasis([np.sin, lambda p: p**2], names=["sin", "sq"])
    np.testing.assert_allclose(b([0.0, 1.0]), [[0, 0], [np.sin(1), 1]])
    np.testing.assert_allclose(b.sup_norms((-2, 1)), [1.0, 4.0], rtol=1e-6)


def test_degree_zero_is_an_lti_model():
    assert len(lpvid.Polynomial(0)) == 0
    m = lpvid.LpvModel(np.eye(2) * 0.5, np.ones((2, 1)), np.ones((1, 2)), Ts=1.0)
    assert m.n_basis == 0 and m.A.shape == (1, 2, 2)


@pytest.mark.parametrize("basis", [lpvid.Polynomial(3, domain=(1, 2)), lpvid.Legendre(2, (0, 1))])
def test_to_dict_round_trip(basis):
    from lpvid.data.basis import basis_from_dict

    assert basis_from_dict(basis.to_dict()) == basis
