"""Distinct rows without numpy's structured comparisons (lpvid._rows)."""

import numpy as np
import pytest

from lpvid._rows import unique_rows


@pytest.mark.parametrize("cols", [1, 2, 3])
def test_unique_rows_is_numpys_unique_along_the_rows(cols):
    rng = np.random.default_rng(cols)
    for _ in range(50):
        n = int(rng.integers(1, 40))
        # Few distinct values, so that rows repeat; -0.0 beside 0.0.
        a = rng.integers(-2, 3, size=(n, cols)).astype(float) * rng.choice(
            [1.0, 0.5], size=(n, cols)
        )
        a[rng.random((n, cols)) < 0.1] = -0.0
        rows, first, counts = unique_rows(a)
        want_rows, want_first, want_counts = np.unique(
            a, axis=0, return_index=True, return_counts=True
        )
        assert np.array_equal(rows, want_rows)
        assert np.array_equal(first, want_first)
        assert np.array_equal(counts, want_counts)


def test_unique_rows_edge_cases():
    rows, first, counts = unique_rows(np.zeros((0, 2)))
    assert rows.shape == (0, 2) and first.size == 0 and counts.size == 0
    rows, first, counts = unique_rows([[0.0], [-0.0], [1.0]])
    assert (
        rows.tolist() == [[0.0], [1.0]] and first.tolist() == [0, 2] and counts.tolist() == [2, 1]
    )
    with pytest.raises(ValueError, match="2-dimensional"):
        unique_rows([1.0, 2.0])
