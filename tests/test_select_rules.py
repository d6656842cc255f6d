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
    # parameters on ranges that start apart: a point at the second's lowest is an edge
    p = np.array([[0.0, 2.0], [1.0, 2.0], [0.5, 1.0], [0.5, 3.0], [0.5, 2.0], [0.3, 2.5]])
    data = lpvid.FrfData(p, f, np.ones((6, 3, 1, 1)))
    assert held_out_points(data, [lpvid.Polynomial(1, n_params=2)]) == [4, 5]
    one = lpvid.FrfData(np.linspace(0, 1, 5), f, np.ones((5, 3, 1, 1)))
    assert held_out_points(one, [lpvid.Polynomial(2)]) == [1, 2, 3]  # N = Nb + 3: enough
    assert held_out_points(one, [lpvid.Polynomial(3)]) == []  # N = Nb + 2: not
    assert held_out_points(one, [lpvid.Polynomial(1), lpvid.Polynomial(3)]) == []  # for every basis


def test_the_reason_names_what_judged_and_the_numbers():
    """Rejects a reason that names the wrong data (validation / held-out) or drops the rule."""
    rows = [_row(2, 1, val=100.0, n_free=10), _row(3, 1, val=105.0, n_free=8)]
    _, reason = choose_pair(rows, "validation", 0.1)
    assert "whose validation V_NLS (105) is within 10% of the best (100)" in reason
    assert "held-out" not in reason
    _, reason = choose_pair(rows, "held-out", 0.0)
    assert "whose held-out V_NLS (100) is within 0% of the best (100)" in reason
    assert "validation" not in reason
    assert "1 of 2 pairs are within" in reason
    at = [_row(2, 1, vnls=100.0, floor=100)]
    _, reason = choose_pair(at, "noise floor", 0.1)
    assert reason.startswith("no validation data and too few scheduling points to hold one out")
    assert reason.endswith(
        "the smallest order and basis whose V_NLS reaches the noise floor (V_NLS <= M + 2 sqrt(M))"
    )
    _, reason = choose_pair([_row(2, 1, vnls=300.0, floor=100)], "noise floor", 0.1)
    assert reason.startswith("no validation data and too few scheduling points to hold one out")
    assert "(V_NLS <= M + 2 sqrt(M)), so the lowest V_NLS / M is kept" in reason
    assert reason.endswith("try higher orders or degrees")
    with pytest.raises(ValueError, match=r"^no pair of the grid has a model$"):
        choose_pair([_row(2, 1, ok=False)], "noise floor", 0.1)


def test_the_noise_floor_bound_is_two_square_roots():
    """Rejects another multiple of sqrt(M) in the bound: M = 100 gives 120, not 110 or 130."""
    rows = [
        _row(1, 1, vnls=125.0, floor=100),  # above 120: a bound of 3 sqrt(M) would take it
        _row(2, 1, vnls=115.0, floor=100),  # below 120: a bound of sqrt(M) would miss it
        _row(3, 1, vnls=100.0, floor=100),
    ]
    assert choose_pair(rows, "noise floor", 0.1)[0] == 1
    # M = 400: 400 + 2 * 20 = 440
    assert choose_pair([_row(1, 1, vnls=439.0, floor=400), *rows], "noise floor", 0.1)[0] == 0


def _columns(header, line, names):
    """The text of each right-aligned column of ``line``, cut where its heading ends."""
    out = []
    for name in names:
        end = header.index(name) + len(name)
        start = line.rfind(" ", 0, end) + 1
        assert line[end : end + 1] in ("", " "), (name, line)
        out.append(line[start:end])
    return out


def test_table_numbers_are_aligned_under_their_headings_with_their_digits():
    """Rejects another width or number format in the table (.5g V_NLS, .4g ratios, lower-case e)."""
    rows = [
        _row(2, 1, vnls=458090.0, floor=10, val=123456.0, n_free=6),
        _row(3, 1, vnls=50.0, floor=100, val=3141600.0, n_free=9),
    ]
    rows[0].n_groups, rows[1].n_groups, rows[1].seconds = 1, 12, 3.5
    names = ["order", "V_NLS", "V/floor", "val V/floor", "groups", "free", "seconds"]
    lines = _result(rows, 1).table().splitlines()
    # 458090 to 5 digits; 45809 and 1234.56 to 4 digits
    assert _columns(lines[0], lines[1], names) == [
        "2",
        "4.5809e+05",
        "4.581e+04",
        "1235",
        "1",
        "6",
        "0.00",
    ]
    assert _columns(lines[0], lines[2], names) == ["3", "50", "0.5", "3.142e+04", "12", "9", "3.50"]
    assert lines[2][: lines[0].index("basis")].split() == ["->", "3"]
    held = _result(rows, 1, rule="held-out").table().splitlines()
    assert held[0].split()[4:6] == ["held-out", "V/fl"]
    assert _columns(held[0], held[1], ["held-out V/fl"]) == ["1235"]
    plain = _result(rows, 1, rule="noise floor").table().splitlines()
    assert plain[0].split() == "order basis V_NLS V/floor groups free seconds".split()
    assert _columns(plain[0], plain[1], ["V/floor", "groups"]) == ["4.581e+04", "1"]


def test_table_and_summary_never_divide_by_a_missing_floor():
    """Rejects a table or summary that divides when a V_NLS or its floor is missing."""
    rows = [
        GridRow(2, lpvid.Polynomial(1), vnls=5.0, validation_vnls=7.0, n_free=3, result=object()),
        GridRow(3, lpvid.Polynomial(1), noise_floor=100, validation_floor=100),
    ]
    lines = _result(rows, 0).table().splitlines()
    assert lines[1].split()[:6] == ["->", "2", "poly:1", "5", "-", "-"]
    assert lines[2].split()[:5] == ["3", "poly:1", "-", "-", "-"]
    rows[0].noise_floor = 10
    text = _result(rows, 0).summary()
    assert "validation data" not in text  # no floor: no ratio to show
    rows[0].validation_vnls, rows[0].validation_floor = None, 100
    assert "validation data" not in _result(rows, 0).summary()


def test_summary_without_a_recorded_time():
    """Rejects a summary that fails when the run's time was not recorded."""
    rows = [_row(2, 1, vnls=100.0, floor=100, n_free=3)]
    hints = OrderHints(orders=[], gaps=np.array([]), singular_values=np.ones((1, 4)), n_rows=2)
    sel = SelectResult(rows, 0, "why", "noise floor", 0.1, hints)
    assert sel.summary().splitlines()[-1] == "time: nan s for 1 pairs"


class _Waves(lpvid.Basis):
    """A basis of the user's own, without a ``kind``."""

    names = ["sin", "cos"]

    def _evaluate(self, p):
        return np.hstack([np.sin(p), np.cos(p)])

    def to_dict(self):
        return {"names": self.names}


def test_a_basis_without_a_kind_is_named_after_its_class():
    """Rejects a label that fails or uses another name for a basis class without ``kind``."""
    assert basis_label(_Waves()) == "_Waves(sin, cos)"
    assert _row(2, 1).label == "order 2, poly:1"
