"""Group magnitudes (the paper's Tables 1-4)."""

import re

import numpy as np
import pytest

import lpvid


def test_group_norms_of_a_known_model():
    basis = lpvid.Polynomial(2, domain=(0, 2))
    A = np.zeros((3, 2, 2))
    A[0] = [[3.0, 0.0], [0.0, 4.0]]  # norm 5
    A[1] = [[1.0, 0.0], [0.0, 0.0]]
    B = np.zeros((3, 2, 1))
    B[0] = [[1.0], [0.0]]
    C = np.zeros((3, 1, 2))
    C[0] = [[2.0, 0.0]]
    C[2] = [[0.0, 1.0]]
    D = np.zeros((3, 1, 1))
    D[1] = [[0.5]]  # D(0) = 0: relative magnitude drops the division
    m = lpvid.LpvModel(A, B, C, D, basis, p_range=(1.0, 2.0))
    g = m.group_norms()
    # on p in [1, 2], s in [0, 1]: sup |s| = sup |s^2| = 1
    np.testing.assert_allclose(g.absolute, [[1, 0], [0, 0], [0, 1], [0.5, 0]])
    np.testing.assert_allclose(g.relative, [[0.2, 0], [0, 0], [0, 0.5], [0.5, 0]])
    np.testing.assert_allclose(g.constant, [5, 1, 2, 0])
    assert g.nonzero() == {"A": [1], "B": [], "C": [2], "D": [1]}
    assert g.count() == 3
    assert "s^2" in str(g)
    # a narrower range shrinks the relative magnitudes by sup |psi_i|
    g2 = m.group_norms(p_range=(1.0, 1.5))
    np.testing.assert_allclose(g2.relative[0, 0], 0.2 * 0.5)


def _column_ends(line: str) -> list[int]:
    """Where each cell of ``line`` ends (cells are apart by two spaces or more)."""
    return [m.end() for m in re.finditer(r"\S(?=\s{2,}|$)", line)]


@pytest.mark.parametrize("degree", [0, 1, 4])
def test_group_norm_table_rows_line_up(degree):
    """Every row of the table, the constant's too, ends its cells where the header does."""
    rng = np.random.default_rng(degree)
    basis = lpvid.Polynomial(degree, domain=(0, 1)) if degree else None
    k = degree + 1
    m = lpvid.LpvModel(
        rng.normal(size=(k, 3, 3)) * 100,
        rng.normal(size=(k, 3, 1)),
        rng.normal(size=(k, 2, 3)),
        rng.normal(size=(k, 2, 1)),
        basis,
    )
    lines = m.group_norms().table().splitlines()
    header = _column_ends(lines[0])
    assert len(header) == 9
    assert lines[1].startswith("0 (const)") and len(lines) == 2 + degree
    assert _column_ends(lines[1]) == header[:5]
    for line in lines[2:]:
        assert _column_ends(line) == header


def test_group_norms_need_a_range():
    m = lpvid.LpvModel(
        np.zeros((2, 1, 1)), np.ones((2, 1, 1)), np.ones((2, 1, 1)), basis=lpvid.Polynomial(1)
    )
    with pytest.raises(ValueError, match=r"^p_range: the model has no scheduling range"):
        m.group_norms()
    assert m.group_norms(p_range=(0, 1)).absolute.shape == (4, 1)
