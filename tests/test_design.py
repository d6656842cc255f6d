"""The information algebra of lpvid.experiment.design, against finite differences and inverses.

``C' = inv(inv(C) + 2 P^T R R^T P)`` (the covariance once an FRF with
information ``R R^T`` on the frozen parameters ``P theta`` is added) is the
independent reference for the low-rank updates; the frozen information
against a finite-difference Jacobian of the frozen FRF. Each test names the
wrong code it rejects.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import lpvid
import lpvid.experiment.design as design
import lpvid.trust.relative as relative
from lpvid.experiment.design import factor, greedy_update, updated
from lpvid.testing import noisy_data, one_group_lpv, random_lpv
from lpvid.trust.uncertainty import frozen_grams


@pytest.fixture(scope="module")
def res():
    """A small identify result: one mode, affine in p, three points on [0, 1]."""
    true = one_group_lpv(0, n=2)
    lines = np.linspace(5.0, 60.0, 12)
    data = noisy_data(true, [0.0, 0.5, 1.0], lines, np.random.default_rng(0), 0.01)
    return lpvid.identify(data, 2, lpvid.Polynomial(1, domain=(0.0, 1.0)), fixed={"D": True})


def _frozen_frf(A, B, C, D, z):
    n = A.shape[0]
    return np.array([C @ np.linalg.solve(zz * np.eye(n) - A, B) + D for zz in z])


def test_frozen_information_of_a_discrete_time_model_against_finite_differences(rng):
    """Rejects the frozen Jacobian evaluated at j w instead of exp(j w Ts) in discrete time."""
    Ts = 0.01
    model = random_lpv(rng, n=2, r=2, l=1, nb=1, Ts=Ts)
    f = np.array([3.0, 11.0, 27.0])
    p = np.array([0.2, 0.7])
    z = np.exp(2j * np.pi * f * Ts)
    weights = rng.uniform(0.5, 2.0, size=(2, f.size, 1, 2))
    K = frozen_grams(model, f, p, weights)
    h = 1e-6
    for m, pm in enumerate(p):
        mats = [x.copy() for x in model.at(pm)]
        cols = []
        for x in mats:  # vec: column-major, entry a + b n of vec A is A[a, b]
            for idx in np.ndindex(*x.shape[::-1]):
                idx = idx[::-1]
                up = [y.copy() for y in mats]
                dn = [y.copy() for y in mats]
                k = [y is x for y in mats].index(True)
                up[k][idx] += h
                dn[k][idx] -= h
                cols.append(((_frozen_frf(*up, z) - _frozen_frf(*dn, z)) / (2 * h)).ravel())
        J = np.stack(cols, axis=1)
        expect = (J.conj().T @ (weights[m].ravel()[:, None] * J)).real
        np.testing.assert_allclose(K[m], expect, rtol=1e-6, atol=1e-6 * np.abs(expect).max())


def test_factor_reproduces_the_information_with_one_column_per_direction():
    """Rejects factors that change the small eigenvalues or keep more columns than the rank."""
    # Diagonal blocks (exact eigenvalues), the smallest kept one 1e-8 of the largest.
    K = np.array([np.diag([1e-4, 0.0, 1e-12, 1e-6, 0.0]), np.diag([0.0, 3e-5, 0.0, 0.0, 2e-9])])
    R = factor(K)
    assert R.shape == (2, 5, 3)  # the largest rank of the blocks
    np.testing.assert_allclose(R @ R.transpose(0, 2, 1), K, rtol=0, atol=1e-20)
    one = factor(np.diag([0.0, 2e-3, 0.0])[None])
    assert one.shape == (1, 3, 1)
    np.testing.assert_allclose(one[0] @ one[0].T, np.diag([0.0, 2e-3, 0.0]), atol=1e-18)


def _algebra(rng, m=4, r=2):
    """A covariance C (6 x 6), criterion W, 2 coefficients of 3 frozen parameters, m candidates."""
    X = rng.normal(size=(6, 6))
    C = X @ X.T / 6 + 0.1 * np.eye(6)
    Y = rng.normal(size=(6, 6))
    W = Y @ Y.T / 6
    index = np.arange(6).reshape(2, 3)
    w = np.column_stack([np.ones(m), rng.uniform(-1, 1, m)])
    R = rng.normal(size=(m, 3, r))
    return C, W, index, w, R


def _added(C, index, w, R):
    """inv(inv(C) + 2 P^T R R^T P), P taking theta to the frozen parameters at weights w."""
    P = np.zeros((index.shape[1], C.shape[0]))
    for i, wi in enumerate(w):
        P[np.arange(index.shape[1]), index[i]] += wi
    return np.linalg.inv(np.linalg.inv(C) + 2 * P.T @ R @ R.T @ P)


def test_the_update_and_the_reductions_against_plain_inverses(rng):
    """Rejects the Woodbury reduction with a wrong identity term (I/2 changed or its sign)."""
    C, W, index, w, R = _algebra(rng)
    exact = [_added(C, index, w[c], R[c]) for c in range(len(w))]
    for c in range(len(w)):
        np.testing.assert_allclose(updated(C, index, w[c], R[c]), exact[c], rtol=1e-10, atol=1e-12)
    red = design._reductions(C, C @ W @ C, index, w, R)
    expect = [np.sum(C * W) - np.sum(e * W) for e in exact]
    np.testing.assert_allclose(red, expect, rtol=1e-9)
    # The greedy choice: the lowest criterion first, each value the exact one.
    picks, values, after = greedy_update(C, W, index, w, R, 2, np.zeros((4, 1)), np.ones((1, 1)))
    assert picks[0] == int(np.argmax(expect))
    assert values[0] == pytest.approx(np.sum(C * W)) and values[1] == pytest.approx(
        np.sum(exact[picks[0]] * W)
    )
    second = _added(exact[picks[0]], index, w[picks[1]], R[picks[1]])
    np.testing.assert_allclose(after, second, rtol=1e-9, atol=1e-12)
    assert values[2] == pytest.approx(np.sum(second * W))


def test_a_candidate_is_never_chosen_twice(rng):
    """Rejects a chosen candidate left available (chosen again while it still lowers most)."""
    C, W, index, w, R = _algebra(rng)
    R[1:] = 0.0  # only candidate 0 tells anything; the others tie at no reduction
    where = np.array([[0.1], [0.5], [0.9], [0.3]])
    picks, values, _ = greedy_update(C, W, index, w, R, 3, where, np.zeros((1, 1)))
    # Then the ties go to the farthest from the measured 0 and the chosen 0.1, 0.9.
    assert picks == [0, 2, 1]
    assert values[1] < values[0] and values[3] == pytest.approx(values[1], rel=1e-12)


def test_chunks_and_parts_recomputed_change_nothing(res, monkeypatch):
    """Rejects chunks that overlap, miss rows or count a chunk's part once too often or never."""
    whole = lpvid.suggest_points(res, k=2)
    L = res.covariance.lti_covariance(0.5).shape[-1]
    # Chunks of 2-3 candidates or grid values (the last one shorter), nothing kept.
    monkeypatch.setattr(relative, "_CHUNK_ENTRIES", 3 * L * L - 1)
    monkeypatch.setattr(relative, "_KEPT_ENTRIES", 0)
    parts = relative.GridParts(res.covariance.model, res.data.freqs_hz, whole.grid[:, None])
    assert len(parts.slices) > 30 and parts._kept is None
    s = lpvid.suggest_points(res, k=2)
    np.testing.assert_array_equal(s.points, whole.points)
    np.testing.assert_allclose(s.band, whole.band, rtol=1e-9)
    np.testing.assert_allclose(s.band_after, whole.band_after, rtol=1e-9)
    np.testing.assert_allclose(s.variance, whole.variance, rtol=1e-9)


def _plane_model(scale=1.0, c0=(2.0, 1.5)):
    """n = 1, two outputs C(p) = c0 + [s1; s2] (s the scaled p, zero at p = (0.5, 0.5))."""
    basis = lpvid.Polynomial(1, domain=[(0.0, 1.0), (0.0, 1.0)])
    A = np.array([[[0.5]], [[0.1]], [[0.05]]])
    B = np.array([[[1.0]], [[0.0]], [[0.0]]])
    C = scale * np.array([[[c0[0]], [c0[1]]], [[1.0], [0.0]], [[0.0], [1.0]]])
    return lpvid.LpvModel(A, B, C, np.zeros((3, 2, 1)), basis, Ts=1.0)


def _result_of(res, model, p, rel=0.01):
    f = np.linspace(0.02, 0.45, 10)
    G = model.frf(f, p)
    data = lpvid.FrfData(p, f, G, sigma=rel * np.abs(G).max(), Ts=1.0)
    cov = lpvid.covariance(model, data, {"D": True}, warn=False)
    return dataclasses.replace(res, covariance=cov, data=data)


def test_the_relative_band_is_refused_where_the_frf_is_zero(res):
    """Rejects a zero FRF let through (its relative band divides by zero) or misplaced."""
    # The FRF vanishes at (0.5, 0.5) when C0 = 0 there: C(p) = s.
    model = _plane_model(c0=(0.0, 0.0))
    corners = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0], [0.2, 0.9]])
    bad = _result_of(res, model, corners)
    with pytest.raises(ValueError) as info:
        lpvid.suggest_points(bad)
    assert str(info.value) == (
        "result: the model's FRF is zero at p = 0.5, 0.5; its relative band is not defined there"
    )


def test_the_relative_band_does_not_depend_on_the_scale_of_the_frf(res):
    """Rejects FRFs of small norm refused as if zero."""
    corners = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0], [0.2, 0.9]])
    one = lpvid.suggest_points(_result_of(res, _plane_model(), corners))
    tiny = lpvid.suggest_points(_result_of(res, _plane_model(1e-4), corners))
    np.testing.assert_allclose(tiny.band, one.band, rtol=1e-6)
    np.testing.assert_array_equal(tiny.points, one.points)
