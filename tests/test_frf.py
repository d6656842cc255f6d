"""Frequency responses of the core against independent implementations."""

import numpy as np
import pytest

import lpvid
from lpvid.testing import direct_frf, random_lpv


@pytest.mark.parametrize("Ts", [0.01, None])
@pytest.mark.parametrize("n,r,l,nb", [(1, 1, 1, 0), (3, 2, 2, 2), (6, 1, 2, 4), (5, 3, 1, 1)])
def test_frf_matches_python_control(rng, Ts, n, r, l, nb):
    control = pytest.importorskip("control")
    model = random_lpv(rng, n, r, l, nb, Ts=Ts)
    p = np.array([0.0, 0.35, 1.0])
    f = np.linspace(0.5, 45.0, 23)
    G = model.frf(f, p)
    assert G.shape == (3, 23, l, r)
    for q, pq in enumerate(p):
        a, b, c, d = model.at(pq)
        sys = control.ss(a, b, c, d, Ts if Ts is not None else 0)
        ref = sys(np.exp(2j * np.pi * f * Ts) if Ts is not None else 2j * np.pi * f, squeeze=False)
        # python-control returns (l, r, F)
        np.testing.assert_allclose(G[q], np.moveaxis(ref, -1, 0), rtol=1e-10, atol=1e-12)


def test_frf_matches_direct_solve(rng):
    model = random_lpv(rng, 4, 2, 3, 3, Ts=0.002)
    p = np.linspace(0, 1, 6)
    f = np.linspace(1, 240, 41)
    np.testing.assert_allclose(model.frf(f, p), direct_frf(model, f, p), rtol=1e-11, atol=1e-13)


def test_direct_frf_is_the_same_on_any_number_of_blas_threads(blas_threads):
    """Test data are a property of the model, not of the caller's cores: on two OpenBLAS
    threads the 101-state heat rod's solves took other last bits than on one."""
    rod = lpvid.testing.diffusion_rod(101)
    f, p = np.geomspace(0.01, 10.0, 6), np.array([0.1, 1.0, 10.0])
    runs = []
    for limit in (1, 2, 4):
        blas_threads(limit)
        runs.append(direct_frf(rod, f, p))
    assert all(np.array_equal(runs[0], other) for other in runs[1:])


def test_frf_of_a_scalar_point_and_frequency(rng):
    model = random_lpv(rng, 2, 1, 1, 1, Ts=None)
    G = model.frf(3.0, 0.5)
    assert G.shape == (1, 1, 1, 1)
    np.testing.assert_allclose(G, direct_frf(model, np.array([3.0]), np.array([0.5])))


def test_pole_on_the_imaginary_axis_raises(rng):
    # A pure integrator evaluated at 0 Hz in continuous time.
    model = lpvid.LpvModel(np.zeros((1, 1)), np.ones((1, 1)), np.ones((1, 1)))
    with pytest.raises(
        lpvid.SingularModelError,
        match=r"^zI - A\(p\) is singular at scheduling point 0, frequency line 0",
    ):
        model.frf([0.0, 1.0], [0.0])


def test_overflowing_response_raises_with_point_and_line():
    # |G| ~ 1e320 at the second point (p = 1) only: B(p) = 1e160 p.
    model = lpvid.LpvModel(
        [[[0.5]], [[0.0]]],
        [[[0.0]], [[1e160]]],
        [[[1e160]], [[0.0]]],
        [[[0.0]], [[0.0]]],
        lpvid.Polynomial(1),
        Ts=1.0,
    )
    assert np.all(np.isfinite(model.frf([0.1, 0.2], [0.0])))
    with pytest.raises(
        lpvid.SingularModelError,
        match=r"^the frequency response overflowed .* at scheduling point 1, frequency line 0",
    ):
        model.frf([0.1, 0.2], [0.0, 1.0])


def test_at_interpolates_the_coefficients(rng):
    model = random_lpv(rng, 3, 2, 2, 2)
    s = 2 * 0.3 - 1  # domain (0, 1) mapped to [-1, 1]
    for got, coef in zip(model.at(0.3), model.matrices().values(), strict=True):
        np.testing.assert_allclose(got, coef[0] + s * coef[1] + s**2 * coef[2])
