"""The per-point similarity directions: flat at the data when N = Nb + 1."""

from __future__ import annotations

import numpy as np
import pytest

import lpvid
from lpvid.model.similarity import (
    flat_at_points,
    pointwise_similarity_directions,
    similarity_directions,
)
from lpvid.testing import random_lpv

FREQS = np.linspace(1.0, 40.0, 30)


def _moved(model: lpvid.LpvModel, d: np.ndarray, p: np.ndarray, h: float) -> float:
    """Largest change of the frozen FRFs at ``p`` after the step ``h d``, over ``h``."""
    moved = model.with_theta(model.theta + h * d)
    return float(np.max(np.abs(moved.frf(FREQS, p) - model.frf(FREQS, p)))) / h


def test_flat_at_the_points_and_not_between(rng):
    model = random_lpv(rng, n=3, r=2, l=2, nb=2)
    p = np.array([0.1, 0.5, 0.9])
    W = pointwise_similarity_directions(model, p)
    assert W.shape == (model.theta.size, 3 * 9) and flat_at_points(model, p)
    between = np.array([0.3, 0.7])
    for k in (0, 13, 26):
        d = W[:, k] / np.linalg.norm(W[:, k])
        # First order: the change at the points shrinks with the step, the
        # change between them does not.
        assert _moved(model, d, p, 1e-5) < 1e-3 * _moved(model, d, between, 1e-5)
        assert _moved(model, d, p, 1e-4) < 0.2 * _moved(model, d, p, 1e-3)
    # A random direction moves the response at the points at first order.
    r = rng.normal(size=model.theta.size)
    assert _moved(model, r / np.linalg.norm(r), p, 1e-6) > 1e-3


def test_the_sum_over_the_points_is_the_common_transformation(rng):
    model = random_lpv(rng, n=2, r=1, l=2, nb=1)
    p = np.array([0.2, 0.8])
    W = pointwise_similarity_directions(model, p)
    total = W.reshape(model.theta.size, 2, 4).sum(axis=1)
    np.testing.assert_allclose(total, similarity_directions(model), atol=1e-12)


@pytest.mark.parametrize("p", [[0.1, 0.5], [0.1, 0.4, 0.6, 0.9], [0.5, 0.5, 0.9]])
def test_none_without_exactly_one_point_per_coefficient(rng, p):
    model = random_lpv(rng, n=2, r=1, l=1, nb=2)
    assert pointwise_similarity_directions(model, np.array(p)).shape == (model.theta.size, 0)
    assert not flat_at_points(model, np.array(p))
