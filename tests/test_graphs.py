"""lpvid's assignment and spanning tree against scipy's."""

import numpy as np
import pytest
from scipy.optimize import linear_sum_assignment
from scipy.sparse.csgraph import breadth_first_order, minimum_spanning_tree

from lpvid._graphs import assignment, spanning_tree_walk


@pytest.mark.parametrize("n", [1, 2, 3, 7, 24])
@pytest.mark.parametrize("scale", [1e-6, 1.0, 1e6])
def test_assignment_has_scipys_optimal_cost(n, scale):
    rng = np.random.default_rng(n)
    for _ in range(10):
        c = scale * rng.random((n, n))
        rows, cols = assignment(c)
        r, s = linear_sum_assignment(c)
        assert np.array_equal(rows, np.arange(n))
        assert sorted(cols) == list(range(n))  # a permutation
        assert c[rows, cols].sum() == pytest.approx(c[r, s].sum(), rel=1e-12)


def test_assignment_refuses_bad_costs():
    with pytest.raises(ValueError, match=r"^cost: expected a square matrix"):
        assignment(np.ones((2, 3)))
    with pytest.raises(ValueError, match=r"^cost: contains NaN"):
        assignment([[np.nan]])


@pytest.mark.parametrize("dim", [1, 2])
@pytest.mark.parametrize("grid", [False, True])
def test_spanning_tree_has_scipys_parents(dim, grid):
    rng = np.random.default_rng(dim)
    for N in range(2, 30):
        if grid:  # equal distances everywhere: ties
            p = np.stack(np.meshgrid(np.arange(8.0), np.arange(4.0)), -1).reshape(-1, 2)
            p = p[:N, :dim]
            if len(np.unique(p, axis=0)) < N:
                continue
        else:
            p = rng.random((N, dim))
        d = np.linalg.norm(p[:, None] - p[None], axis=2)
        root = int(np.argmin(d.max(axis=1)))
        order, parent = spanning_tree_walk(d, root)
        ref_order, ref_parent = breadth_first_order(minimum_spanning_tree(d + 1e-300), root, False)
        assert np.array_equal(parent, np.where(ref_parent < 0, -1, ref_parent))
        assert sorted(order) == sorted(ref_order) and order[0] == root
        # every point comes after its parent
        position = {k: i for i, k in enumerate(order)}
        assert all(position[parent[k]] < position[k] for k in order[1:])
