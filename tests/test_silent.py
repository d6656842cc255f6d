"""What the measured points leave open (lpvid.trust.silent), and the block form (issue 58).

The count is checked against what it claims: a silent direction is one
along which the model's FRF at the measured points hardly moves while its
FRF between them does (finite differences along the direction found), and
points added never open a direction.
"""

from __future__ import annotations

import numpy as np
import pytest
from systems import SYNTHETIC as TRUE
from systems import SYNTHETIC_FIXED as FIXED
from systems import SYNTHETIC_FREQS as FREQS
from systems import synthetic_data as _data

import lpvid
from lpvid.initial.blocks import block_form, block_structure
from lpvid.testing import direct_frf
from lpvid.trust import silent


def test_more_points_never_open_a_direction_and_enough_close_them():
    counts = [
        silent.silent_directions(TRUE, _data(np.linspace(0.02, 1, n)), FIXED) for n in range(2, 8)
    ]
    opened = [c.silent for c in counts]
    assert opened[0] > opened[1] > 0  # two and three points leave directions open
    assert all(a >= b for a, b in zip(opened, opened[1:], strict=False))
    assert counts[-1].determined and counts[-1].points_needed == 0
    assert not counts[0].determined and counts[0].points_needed >= 1
    # the same structure is counted whatever the points: the range sees as many directions
    assert len({c.over_range for c in counts}) == 1
    assert all(c.at_points + c.silent == c.over_range for c in counts)


def test_a_silent_direction_moves_the_frf_between_the_points_and_not_at_them():
    """Finite differences (numpy's FRF, not the core's) along the least-seen direction.

    The direction comes scaled so that its mean effect over the range is 1
    (in the data's sigma, the nearest measured point's on the grid); a step
    of 1e-8 of it stays in the linear regime.
    """
    data = _data([0.02, 0.5, 1.0])
    count = silent.silent_directions(TRUE, data, FIXED)
    assert count.silent > 0
    v, free = silent.least_seen(TRUE, data, FIXED)
    h = 1e-8
    theta = TRUE.theta.copy()
    theta[free] += h * v
    moved = TRUE.with_theta(theta)
    grid = silent.range_grid(TRUE, data)[:, 0]
    nearest = np.argmin(np.abs(grid[:, None] - data.p[None, :]), axis=1)

    def effect(p, sigma):
        d = (direct_frf(moved, FREQS, p) - direct_frf(TRUE, FREQS, p)) / sigma / h
        return np.mean(np.sum(np.abs(d.reshape(len(p), -1)) ** 2, axis=1))

    over_range = effect(grid, data.sigma[nearest])
    at_points = effect(data.p, data.sigma)
    assert 0.5 < over_range < 2.0  # seen over the range: about its unit scale
    assert at_points / over_range < silent.SEEN  # the points see less than SEEN of it
    # and with five points the least-seen direction is seen
    five = _data(np.linspace(0.02, 1, 5))
    assert silent.silent_directions(TRUE, five, FIXED).seen[0] >= silent.SEEN


def test_the_block_form_is_the_same_system_with_a_off_its_blocks_zero():
    A, B, C, D = (x[0] for x in TRUE.with_theta(TRUE.theta).matrices().values())
    rng = np.random.default_rng(3)
    T = np.eye(10) + 0.3 * rng.normal(size=(10, 10))
    Ti = np.linalg.inv(T)
    A2, B2, C2, sizes = block_form(T @ A @ Ti, T @ B, C @ Ti)
    assert sizes == [2] * 5
    off = np.ones((10, 10), bool)
    for k in range(0, 10, 2):
        off[k : k + 2, k : k + 2] = False
    assert np.all(A2[off] == 0)
    z = 2j * np.pi * FREQS
    G = [C @ np.linalg.solve(s * np.eye(10) - A, B) for s in z]
    G2 = [C2 @ np.linalg.solve(s * np.eye(10) - A2, B2) for s in z]
    assert np.allclose(G2, G, rtol=1e-8, atol=1e-12)


def test_real_poles_share_blocks_and_an_odd_one_stands_alone():
    A = np.diag([-1.0, -3.0, -2.0])
    A2, _, _, sizes = block_form(A, np.ones((3, 1)), np.ones((1, 3)))
    assert sizes == [2, 1]
    assert np.allclose(np.sort(np.diag(A2)), [-3.0, -2.0, -1.0])


def test_a_defective_model_is_refused():
    A = np.array([[-1.0, 1.0], [0.0, -1.0]])  # a Jordan block: no modal form
    with pytest.raises(ValueError, match="block form"):
        block_form(A, np.ones((2, 1)), np.ones((1, 2)))


def test_the_structure_holds_the_off_block_entries_of_every_coefficient():
    mask = block_structure(TRUE, [2] * 5, FIXED)
    held = lpvid.fixed_mask(
        TRUE, {"A": np.broadcast_to(~np.kron(np.eye(5), np.ones((2, 2))).astype(bool), (3, 10, 10))}
    )
    assert np.array_equal(mask, held | lpvid.fixed_mask(TRUE, FIXED))
