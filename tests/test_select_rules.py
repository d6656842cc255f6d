"""What select decides and shows, on hand-built grids: the choice rules, the table, the summary."""

import numpy as np
import pytest

import lpvid
from lpvid.initial.orders import OrderHints
from lpvid.selection.grid import held_out_points
from lpvid.selection.result import GridRow, SelectResult, basis_label, choose_pair, free_in_use


def _row(order, degree, *, val=None, n_free=None, vnls=None, floor=None, ok=True):
    """A grid row as select fills it (``result`` only marks the pair as done)."""
    basis = lpvid.Polynomial(degree, domain=(0.0, 1.0))
    return GridRow(
        order,
        basis,
        vnls=vnls,
        noise_floor=floor,
        validation_vnls=val,
        validation_floor=None if val is None else 100,
        n_free=n_free,
        result=object() if ok else None,
    )


def test_the_choice_among_pairs_within_tolerance():
    # The best validation V_NLS is 100: within 10 % are 100, 104, 105 and 109.
    rows = [
        _row(2, 1, val=100.0, n_free=10),
        _row(3, 1, val=109.0, n_free=8),
        _row(2, 2, val=111.0, n_free=5),  # simplest, but 11 % off
        _row(4, 2, val=104.0, n_free=8),  # as simple as the next, one basis function more
        _row(5, 1, val=105.0, n_free=8),  # as simple as (3, poly:1) and lower: chosen
        _row(6, 1, val=50.0, n_free=2, ok=False),  # failed: never chosen
        _row(6, 2, n_free=2),  # no validation V_NLS (cancelled rotation)
    ]
    k, reason = choose_pair(rows, "validation", 0.1)
    assert k == 4 and "4 of 5 pairs are within" in reason
    assert choose_pair(rows, "held-out", 0.0)[0] == 0
    assert choose_pair(rows, "validation", 0.11)[0] == 2  # 111 <= 1.11 * 100
    with pytest.raises(ValueError, match="no pair of the grid has a held-out V_NLS"):
        choose_pair(rows[5:6], "held-out", 0.1)


def test_the_noise_floor_choice_and_its_fallback():
    # M = 100: the floor is reached at V_NLS <= M + 2 sqrt(M) = 120 (exactly).
    rows = [
        _row(2, 2, vnls=150.0, floor=100, n_free=4),
        _row(3, 2, vnls=100.0, floor=100, n_free=9),
        _row(3, 1, vnls=119.0, floor=100, n_free=6),
        _row(4, 1, vnls=90.0, floor=100, n_free=8),
    ]
    assert choose_pair(rows, "noise floor", 0.1)[0] == 2  # smallest order, fewest functions
    rows.append(_row(2, 1, vnls=120.0, floor=100, n_free=3))
    assert choose_pair(rows, "noise floor", 0.1)[0] == 4  # on the bound counts
    # None reaches its floor: the lowest V_NLS / M, not the lowest V_NLS.
    above = [
        _row(2, 1, vnls=300.0, floor=100),
        _row(3, 1, vnls=500.0, floor=200),
        _row(4, 1, vnls=280.0, floor=90),
        _row(5, 1, vnls=1.0, floor=1, ok=False),
    ]
    k, reason = choose_pair(above, "noise floor", 0.1)
    assert k == 1 and "no pair reaches the noise floor" in reason
    with pytest.raises(ValueError, match="no pair of the grid has a model"):
        choose_pair(above[3:], "noise floor", 0.1)
    with pytest.raises(ValueError, match="rule: expected one of"):
        choose_pair(rows, "aic", 0.1)


def _result(rows, chosen, rule="validation", interrupted=False):
    hints = OrderHints(
        orders=[2], gaps=np.array([0.1, 3.25]), singular_values=np.ones((1, 4)), n_rows=2
    )
    return SelectResult(rows, chosen, "the reason", rule, 0.1, hints, interrupted, {"total_s": 1.5})


def test_the_table_and_the_summary():
    rows = [
        _row(2, 1, vnls=250.0, floor=100, val=210.0, n_free=6),
        _row(3, 2, vnls=101.0, floor=100, val=105.0, n_free=9),
        _row(4, 1, ok=False),
    ]
    rows[1].n_groups, rows[0].n_groups, rows[1].seconds = 3, 1, 2.25
    rows[2].error = "ValueError: order: 4\n  is too large"
    rows[0].warnings = [(UserWarning, "a"), (UserWarning, "b")]
    sel = _result(rows, 1)
    lines = sel.table().splitlines()
    assert lines[0].split() == "order basis V_NLS V/floor val V/floor groups free seconds".split()
    assert lines[1].split() == [
        "2",
        "poly:1",
        "250",
        "2.5",
        "2.1",
        "1",
        "6",
        "0.00",
        "(2",
        "warning(s))",
    ]
    assert lines[2].split() == ["->", "3", "poly:2", "101", "1.01", "1.05", "3", "9", "2.25"]
    assert lines[3].split() == [
        "4",
        "poly:1",
        "-",
        "-",
        "-",
        "-",
        "-",
        "0.00",
        "ValueError:",
        "order:",
        "4",
        "is",
        "too",
        "large",
    ]
    held = _result(rows, 1, rule="held-out").table().splitlines()[0]
    assert "held-out V/fl" in held and "val V/floor" not in held
    assert "V/floor" in _result(rows, 1, rule="noise floor").table().splitlines()[0]
    assert "held-out V/fl" not in _result(rows, 1, rule="noise floor").table()
    text = sel.summary().splitlines()
    assert text == [
        "chosen: order 3, poly:2 (validation rule); the reason",
        "order hints (drop of the subspace singular values): 2 (3.25 decades)",
        "V_NLS = 101 on identification data (noise floor 100, ratio 1.010); 3 groups kept, 9 "
        "free parameters in use",
        "V_NLS = 105 on validation data (noise floor 100, ratio 1.050)",
        "1 pair(s) failed: see the table",
        "time: 1.50 s for 3 pairs",
    ]
    rows[2].error = "cancelled"
    stopped = _result(rows, 1, rule="held-out", interrupted=True).summary().splitlines()
    assert stopped[0] == (
        "interrupted (Ctrl-C): 2 of 3 pairs done, the others cancelled; the choice is among "
        "those done"
    )
    assert "V_NLS = 105 on held-out points (noise floor 100, ratio 1.050)" in stopped
    assert not any("failed" in line for line in stopped)
    assert repr(sel) == "SelectResult(order 3, poly:2, rule='validation', pairs=3)"
    assert (sel.order, sel.basis) == (3, rows[1].basis) and sel.row is rows[1]


def test_basis_labels_and_free_parameters_in_use():
    assert basis_label(lpvid.Polynomial(3)) == "poly:3"
    assert basis_label(lpvid.Legendre(2, domain=(0, 1))) == "legendre:2"
    assert basis_label(lpvid.CustomBasis([np.sin, np.cos])) == "custom(sin, cos)"
    # n = 2, r = 1, l = 1, Nb = 2: A, B, C, D blocks of 4, 2, 2, 1 per coefficient.
    model = lpvid.LpvModel(
        np.zeros((3, 2, 2)),
        np.zeros((3, 2, 1)),
        np.zeros((3, 1, 2)),
        np.zeros((3, 1, 1)),
        basis=lpvid.Polynomial(2),
    )
    kept = {"A": [1, 2], "C": [2]}
    assert free_in_use(model, kept) == (4 + 2 + 2 + 1) + 4 * 2 + 2
    assert free_in_use(model, kept, {"D": True}) == (4 + 2 + 2) + 4 * 2 + 2
    assert free_in_use(model, {}) == 9


def test_held_out_points_are_the_interior_ones():
    f = np.linspace(1.0, 2.0, 3)
    # Two parameters on different ranges: interior = at no parameter's lowest or highest value.
    p = np.array([[0.0, 0.0], [1.0, 2.0], [0.5, 1.0], [0.2, 2.0], [0.7, 0.5], [1.0, 0.3]])
    data = lpvid.FrfData(p, f, np.ones((6, 3, 1, 1)))
    assert held_out_points(data, [lpvid.Polynomial(1, n_params=2)]) == [2, 4]
    one = lpvid.FrfData(np.linspace(0, 1, 5), f, np.ones((5, 3, 1, 1)))
    assert held_out_points(one, [lpvid.Polynomial(2)]) == [1, 2, 3]  # N = Nb + 3: enough
    assert held_out_points(one, [lpvid.Polynomial(3)]) == []  # N = Nb + 2: not
