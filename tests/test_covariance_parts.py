"""The parts of lpvid.covariance on small problems: against finite differences and numpy.

Each test names the wrong code it rejects. The covariance is checked against
``(J^T J)^+ / 2`` with ``J`` the finite-difference Jacobian of the weighted
residual and the pseudo-inverse taken by numpy on the complement of the
similarity directions; the rank rule against block matrices whose
eigenvalues are known in closed form.
"""

from __future__ import annotations

import re

import numpy as np
import pytest
from scipy.linalg import block_diag

import lpvid
from lpvid.model.similarity import free_similarity_directions
from lpvid.trust.uncertainty import pseudo_inverse

FREQS = np.linspace(0.02, 0.4, 12)


def _one_state(rng, lines=FREQS, rel=0.01):
    """A one-state DT LTI model and its data off the model by a small known error."""
    m = lpvid.LpvModel([[[0.6]]], [[[0.8]]], [[[1.2]]], [[[0.1]]], Ts=1.0)
    G = m.frf(lines, [0.0])
    sigma = rel * (np.abs(G) + 0.1)
    err = sigma * (rng.standard_normal(G.shape) + 1j * rng.standard_normal(G.shape)) / 2
    return m, lpvid.FrfData([0.0], lines, G + err, sigma=sigma, Ts=1.0)


def _residual_jacobian(model, data, h=1e-6):
    """d [Re; Im]((G(theta) - Gm) / sigma) / d theta by central differences: (2 N F l r, P)."""
    cols = []
    for k in range(model.theta.size):
        d = np.zeros(model.theta.size)
        d[k] = h
        up = model.with_theta(model.theta + d).frf(data.freqs_hz, data.p)
        dn = model.with_theta(model.theta - d).frf(data.freqs_hz, data.p)
        dg = ((up - dn) / (2 * h) / data.sigma).ravel()
        cols.append(np.concatenate([dg.real, dg.imag]))
    return np.stack(cols, axis=1)


def _expected(model, data, free):
    """(J^T J)^+ / 2 on the complement of the free similarity directions, by numpy."""
    J = _residual_jacobian(model, data)[:, free]
    T = free_similarity_directions(model, free)
    Pc = np.eye(free.sum()) - T @ np.linalg.pinv(T) if T.shape[1] else np.eye(free.sum())
    inv = np.linalg.pinv(Pc @ J.T @ J @ Pc, rcond=1e-9, hermitian=True)
    full = np.zeros((free.size, free.size))
    full[np.ix_(free, free)] = inv / 2
    return full


def test_the_attributes_say_what_it_was_computed_from(rng):
    """Rejects n_free, vnls or noise_floor left out (None) of the Covariance."""
    m, data = _one_state(rng)
    fixed = {"D": True}
    cov = lpvid.covariance(m, data, fixed)
    free = ~lpvid.fixed_mask(m, fixed)
    assert cov.n_free == 3 == free.sum()
    np.testing.assert_array_equal(cov.free, free)
    # V_NLS = sum |G(theta) - Gm|^2 / sigma^2, the noise floor N F l r complex residuals.
    v = np.sum(np.abs((m.frf(FREQS, [0.0]) - data.G) / data.sigma) ** 2)
    assert cov.vnls == pytest.approx(v, rel=1e-10)
    assert cov.noise_floor == FREQS.size
    assert cov.factor == 1.0


def test_one_state_against_the_finite_difference_jacobian(rng):
    """Rejects the span of the similarity directions judged on a second singular value."""
    # One state: one similarity direction (the state scale), so T has one column.
    m, data = _one_state(rng)
    cov = lpvid.covariance(m, data)
    assert (cov.rank, cov.n_similarity, cov.n_unidentified) == (3, 1, 0)
    expect = _expected(m, data, np.ones(4, bool))
    np.testing.assert_allclose(cov.theta, expect, rtol=1e-5, atol=1e-6 * np.abs(expect).max())


def test_no_free_similarity_direction(rng):
    """Rejects a similarity direction counted when no transformation is free (B fixed)."""
    m, data = _one_state(rng)
    cov = lpvid.covariance(m, data, {"B": True})
    free = ~lpvid.fixed_mask(m, {"B": True})
    assert (cov.rank, cov.n_similarity, cov.n_unidentified) == (3, 0, 0)
    # Identifiable: the plain inverse of J^T J over A, C and D.
    J = _residual_jacobian(m, data)[:, free]
    expect = np.linalg.inv(J.T @ J) / 2
    np.testing.assert_allclose(cov.theta[np.ix_(free, free)], expect, rtol=1e-5)
    assert np.all(cov.theta[~free] == 0) and np.all(cov.theta[:, ~free] == 0)


def test_every_parameter_fixed_gives_no_spread(rng):
    """Rejects a pseudo-inverse that fails on an empty problem (no free parameter)."""
    m, data = _one_state(rng)
    cov = lpvid.covariance(m, data, np.ones(4, bool))
    assert (cov.rank, cov.n_free, cov.n_similarity, cov.n_unidentified) == (0, 0, 0, 0)
    np.testing.assert_array_equal(cov.theta, np.zeros((4, 4)))
    np.testing.assert_array_equal(cov.std, np.zeros(4))


def test_the_scale_factor_at_one_degree_of_freedom(rng):
    """Rejects the denominator of the noise estimate floored at 2 instead of 1."""
    # A and C free (B and D fixed: no similarity direction), two lines: M = 2
    # complex residuals, rank 2, so V_NLS / (M - rank / 2) = V_NLS / 1.
    m, data = _one_state(rng, lines=FREQS[[2, 8]])
    fixed = {"B": True, "D": True}
    a = lpvid.covariance(m, data, fixed)
    b = lpvid.covariance(m, data, fixed, scale=True)
    assert (a.rank, a.noise_floor) == (2, 2)
    v = np.sum(np.abs((m.frf(data.freqs_hz, [0.0]) - data.G) / data.sigma) ** 2)
    assert b.factor == pytest.approx(v, rel=1e-10)
    np.testing.assert_allclose(b.theta, v * a.theta, rtol=1e-10)


def test_the_refusal_counts_the_data(rng, monkeypatch):
    """Rejects the memory check made without the data's sizes."""
    m, small = _one_state(rng)
    many = np.linspace(0.001, 0.49, 20_000)
    big = lpvid.FrfData([0.0], many, np.ones((1, many.size, 1, 1)), sigma=1.0, Ts=1.0)
    monkeypatch.setattr(lpvid.fit.memory, "available_memory", lambda: (1000, "a test"))
    needs = {}
    for name, data in (("small", small), ("big", big)):
        with pytest.raises(MemoryError) as info:
            lpvid.covariance(m, data)
        message = str(info.value)
        assert f"N = 1 points, F = {data.n_lines} lines" in message, message
        needs[name] = int(re.search(r"\((\d+) bytes\)", message).group(1))
    # 20000 lines need more than 12; with room between the two only the small data go.
    assert needs["big"] > needs["small"]
    room = (needs["big"] + needs["small"]) // 2
    monkeypatch.setattr(lpvid.fit.memory, "available_memory", lambda: (room, "a test"))
    assert lpvid.covariance(m, small).rank == 3
    with pytest.raises(MemoryError, match="covariance needs about"):
        lpvid.covariance(m, big)


def test_pole_std_returns_the_spread_alone_by_default(rng):
    """Rejects pole_std returning (poles, std) when return_poles is not asked for."""
    m, data = _one_state(rng)
    cov = lpvid.covariance(m, data)
    std = cov.pole_std(0.0)
    assert isinstance(std, np.ndarray) and std.shape == (1,)
    lam, same = cov.pole_std(0.0, return_poles=True)
    np.testing.assert_array_equal(std, same)
    np.testing.assert_allclose(lam, [0.6])
    # d lambda / d a = 1 for one state: the spread of the pole is that of A.
    assert std[0] == pytest.approx(cov.std[0], rel=1e-12)


def _null_pair(rng):
    """H = J^T J with span(T) in its null space (2 directions of 6), and T."""
    J = rng.normal(size=(40, 6))
    T = rng.normal(size=(6, 2))
    Q, _ = np.linalg.qr(T)
    return (J - J @ Q @ Q.T).T @ (J - J @ Q @ Q.T), T


@pytest.mark.parametrize("scale", [1e-6, 1.0, 1e6])
def test_the_span_of_the_directions_does_not_depend_on_their_size(rng, scale):
    """Rejects a span cut-off relative to 1 (or divided by the largest singular value)."""
    H, T = _null_pair(rng)
    # A third column in their span (the same space), and the directions scaled.
    T3 = scale * np.column_stack([T, T @ [0.3, -1.2]])
    inv, rank, k, dropped = pseudo_inverse(H, T3)
    assert (rank, k, dropped) == (4, 2, 0)
    np.testing.assert_allclose(
        inv, np.linalg.pinv(H, hermitian=True), atol=1e-9 * np.abs(inv).max()
    )


def test_a_zero_direction_spans_nothing(rng):
    """Rejects a zero column of T counted as one similarity direction."""
    J = rng.normal(size=(30, 4))
    H = J.T @ J
    inv, rank, k, dropped = pseudo_inverse(H, np.zeros((4, 1)))
    assert (rank, k, dropped) == (4, 0, 0)
    np.testing.assert_allclose(inv, np.linalg.inv(H), rtol=1e-9)
    inv0, rank0, k0, _ = pseudo_inverse(H, np.zeros((4, 0)))
    assert (rank0, k0) == (4, 0)
    np.testing.assert_allclose(inv0, np.linalg.inv(H), rtol=1e-9)


def test_poorly_scaled_parameters_are_kept(rng):
    """Rejects the Jacobi scaling dropped for parameters whose diagonal is below 1."""
    # H = D S D: S well conditioned, D over 20 decades. Scaled, every direction
    # is well determined; unscaled, the eigenvalues span 40 decades.
    X = rng.normal(size=(6, 6))
    S = np.eye(6) + 0.1 * (X + X.T)
    D = np.diag(np.logspace(-10, 10, 6))
    inv, rank, k, dropped = pseudo_inverse(D @ S @ D, np.zeros((6, 0)))
    assert (rank, k, dropped) == (6, 0, 0)
    np.testing.assert_allclose(D @ inv @ D, np.linalg.inv(S), rtol=1e-8, atol=1e-10)


def test_the_rank_rule_drops_eigenvalues_below_k_eps_times_the_largest():
    """Rejects the cut-off at zero, at k eps / largest, or relative to the second largest."""
    # Blocks of unit diagonal (the scaling leaves them) with closed-form eigenvalues:
    # (1 - c) I + c 1 1^T of size b has 1 + (b - 1) c once and 1 - c (b - 1) times.
    # One 4 x 4 block with c = 0.9 (the largest eigenvalue, 3.7), 49 blocks 2 x 2 with
    # c = 0.5 (kept), 50 blocks 2 x 2 with 1 - c = k eps sqrt(2 * 3.7): below the
    # cut-off k eps 3.7, above k eps 2 (the second largest eigenvalue, 2 - (1 - c))
    # and k eps / 3.7 (k = 202).
    k = 202
    small = k * np.finfo(float).eps * np.sqrt(2 * 3.7)
    cs = [0.9] + [0.5] * 49 + [1.0 - small] * 50
    sizes = [4] + [2] * 99
    H = block_diag(*[(1 - c) * np.eye(b) + c for c, b in zip(cs, sizes, strict=True)])
    inv, rank, n_span, dropped = pseudo_inverse(H, np.zeros((k, 0)))
    assert (rank, n_span, dropped) == (152, 0, 50)
    expect = []
    for c, b in zip(cs, sizes, strict=True):
        if c < 0.99:  # every direction kept: the inverse
            expect.append((np.eye(b) - c / (1 + (b - 1) * c)) / (1 - c))
        else:  # only the direction (1, 1) / sqrt(2), eigenvalue 1 + c
            expect.append(np.full((2, 2), 0.5) / (1 + c))
    np.testing.assert_allclose(inv, block_diag(*expect), atol=1e-10)


@pytest.mark.parametrize("held", ["B", "A1"])
def test_the_free_similarity_directions_leave_the_held_parameters_alone(rng, held):
    """Rejects a null space cut from the thin SVD where it is short (fewer held rows than n^2).

    Holding B (8 rows at n = 4 with a one-function basis: fewer than the 16
    transformations) needs the full ``vt``; holding A(1) and D (18 rows) the
    thin one serves. Either way the directions span the null space of the
    held rows (scipy's ``null_space``, an independent computation).
    """
    from scipy.linalg import null_space

    basis = lpvid.Polynomial(1, domain=(0.0, 1.0))
    A = 0.3 * rng.normal(size=(2, 4, 4))
    B, C, D = rng.normal(size=(2, 4, 1)), rng.normal(size=(2, 1, 4)), rng.normal(size=(2, 1, 1))
    m = lpvid.LpvModel(A, B, C, D, basis=basis, Ts=1.0)
    fixed = {"B": True} if held == "B" else {"A": [1], "D": True}
    free = ~lpvid.fixed_mask(m, fixed)
    full = lpvid.model.similarity.similarity_directions(m)
    T = free_similarity_directions(m, free)
    want = null_space(full[~free])
    assert T.shape[1] == want.shape[1] == 16 - np.linalg.matrix_rank(full[~free])
    # The same span: the directions, in the full theta, are full @ (some basis of want).
    moved = np.zeros((free.size, T.shape[1]))
    moved[free] = T
    np.testing.assert_allclose(moved[~free], 0.0, atol=1e-12)
    coef = np.linalg.lstsq(full @ want, moved, rcond=None)[0]
    np.testing.assert_allclose(full @ want @ coef, moved, atol=1e-10 * np.abs(moved).max())
