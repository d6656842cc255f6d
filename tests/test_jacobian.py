"""Gradient and Gauss-Newton matrix against finite differences and an explicit Jacobian."""

import numpy as np
import pytest

import lpvid
from lpvid.fit.cost import gauss_newton
from lpvid.testing import noisy_data, random_lpv


def real_residual(model, data, theta):
    e = lpvid.residual(model.with_theta(theta), data).ravel()
    return np.concatenate([e.real, e.imag])


def explicit_jacobian(model, data, h=1e-6):
    theta = model.theta
    cols = [
        (real_residual(model, data, theta + h * e) - real_residual(model, data, theta - h * e))
        / (2 * h)
        for e in np.eye(theta.size)
    ]
    return np.array(cols).T


@pytest.mark.parametrize("Ts", [0.01, None])
def test_gradient_and_jtj_match_explicit_jacobian(rng, Ts):
    model = random_lpv(rng, n=3, r=2, l=2, nb=2, Ts=Ts)
    p = np.array([0.0, 0.4, 0.7, 1.0])
    data = noisy_data(model.with_theta(model.theta * 1.01), p, np.linspace(1, 40, 9), rng)
    v, g, jtj = gauss_newton(model, data)
    J = explicit_jacobian(model, data)
    r = real_residual(model, data, model.theta)
    assert v == pytest.approx(r @ r, rel=1e-12)
    assert v == pytest.approx(lpvid.vnls(model, data), rel=1e-12)
    np.testing.assert_allclose(g, 2 * J.T @ r, rtol=1e-6, atol=1e-8 * np.abs(g).max())
    np.testing.assert_allclose(jtj, J.T @ J, rtol=1e-6, atol=1e-8 * np.abs(jtj).max())


def test_gradient_matches_central_differences_of_vnls(rng):
    model = random_lpv(rng, n=3, r=2, l=2, nb=2)
    data = noisy_data(model, np.array([0.0, 0.5, 1.0]), np.linspace(1, 40, 8), rng)
    model = model.with_theta(model.theta + 0.01 * rng.normal(size=model.theta.size))
    _, g, _ = gauss_newton(model, data)
    theta, h = model.theta, 1e-6
    fd = np.array(
        [
            (
                lpvid.vnls(model.with_theta(theta + h * e), data)
                - lpvid.vnls(model.with_theta(theta - h * e), data)
            )
            / (2 * h)
            for e in np.eye(theta.size)
        ]
    )
    np.testing.assert_allclose(g, fd, rtol=1e-5, atol=1e-6 * np.abs(g).max())


def test_fixed_parameters_are_left_out(rng):
    model = random_lpv(rng, n=3, r=2, l=2, nb=2)
    data = noisy_data(model, np.array([0.0, 0.5, 1.0]), np.linspace(1, 40, 8), rng)
    fixed = {"D": True, "A": [2], "C": np.array([[True, False, False], [False, False, True]])}
    mask = lpvid.fixed_mask(model, fixed)
    assert mask.sum() == 4 * 3 + 9 + 3 * 2
    v_all, g_all, h_all = gauss_newton(model, data)
    v, g, h = gauss_newton(model, data, fixed=fixed)
    free = ~mask
    assert v == v_all
    np.testing.assert_array_equal(g, g_all[free])
    np.testing.assert_array_equal(h, h_all[np.ix_(free, free)])
    # and against the explicit Jacobian restricted to the free columns
    J = explicit_jacobian(model, data)[:, free]
    np.testing.assert_allclose(h, J.T @ J, rtol=1e-6, atol=1e-8 * np.abs(h).max())


def test_jtj_is_symmetric_positive_semidefinite(rng):
    model = random_lpv(rng, n=4, r=1, l=2, nb=3)
    data = noisy_data(model, np.linspace(0, 1, 5), np.linspace(1, 40, 30), rng)
    _, _, h = gauss_newton(model, data)
    np.testing.assert_array_equal(h, h.T)
    assert np.linalg.eigvalsh(h).min() > -1e-9 * np.abs(h).max()


def test_noise_floor_at_the_true_system(rng):
    model = random_lpv(rng, n=3, r=1, l=2, nb=2)
    data = noisy_data(model, np.linspace(0, 1, 5), np.linspace(1, 40, 200), rng)
    v = lpvid.vnls(model, data)
    m = data.n_residuals
    # V_NLS at the true system is chi-square with 2M degrees of freedom, scaled by 1/2.
    assert abs(v - m) < 5 * np.sqrt(m)
