"""How near-ties are decided (lpvid.fit.judge): each margin at its boundary, then the order."""

import math

import pytest

from lpvid.fit.judge import COST_TIE, DEPENDENCE_TIE, by_simplicity, noise_slack, simplest, tied

# A margin of 1e-6 either side of each boundary: far above any last-bit difference.
IN, OUT = 1 - 1e-6, 1 + 1e-6


def test_costs_within_the_cost_tie_are_decided_by_the_order_given():
    lowest = 2402.0
    near = lowest * (1 + COST_TIE * IN)
    assert simplest([8.0, 8.0], [near, lowest]) == 0
    assert simplest([8.0, 8.0], [lowest, near]) == 0
    far = lowest * (1 + COST_TIE * OUT)
    assert simplest([8.0, 8.0], [far, lowest]) == 1
    assert simplest([8.0, 8.0], [lowest, far]) == 0


def test_dependences_within_the_dependence_tie_then_the_cost():
    least = 0.5
    assert simplest([least * (1 + DEPENDENCE_TIE * IN), least], [10.0, 20.0]) == 0
    assert simplest([least * (1 + DEPENDENCE_TIE * OUT), least], [10.0, 20.0]) == 1
    # Simplicity first: a far lower cost does not buy a dependence beyond the tie.
    assert simplest([0.5, 0.6], [100.0, 1.0]) == 0


def test_by_simplicity_takes_the_simplest_of_the_rest_each_time():
    deps = [0.50, 0.51, 2.0, 0.2, 0.5]
    costs = [10.0, 9.0, 1.0, 50.0, 10.0 * (1 + COST_TIE * IN)]
    assert by_simplicity(deps, costs) == [3, 1, 0, 4, 2]
    # Its first is simplest's pick for every rotation of the same models.
    for shift in range(len(deps)):
        d, c = deps[shift:] + deps[:shift], costs[shift:] + costs[:shift]
        assert by_simplicity(d, c)[0] == simplest(d, c)
        assert sorted(by_simplicity(d, c)) == list(range(len(deps)))


def test_not_finite_values_count_as_infinite_and_bad_lengths_are_refused():
    nan, inf = math.nan, math.inf
    assert by_simplicity([nan, 1.0, inf], [1.0, 5.0, 1.0]) == [1, 0, 2]
    assert by_simplicity([1.0, 1.0, 1.0], [nan, 3.0, inf]) == [1, 0, 2]
    assert by_simplicity([nan, nan], [nan, nan]) == [0, 1]
    with pytest.raises(ValueError, match=r"^dependences, costs: need the same length"):
        by_simplicity([1.0, 2.0], [1.0])
    with pytest.raises(ValueError, match=r"^dependences, costs: need the same length"):
        by_simplicity([], [])


def test_noise_slack_is_two_standard_deviations_of_v_nls():
    assert noise_slack(0.25) == pytest.approx(1.0)  # 2 sqrt(M), below one residual too
    assert noise_slack(10_000.0) == pytest.approx(200.0)
    assert noise_slack(-1.0) == 0.0


def test_tied_at_its_margins():
    floor = 10_000.0  # noise slack 2 sqrt(floor) = 200
    assert tied([1000.0, 1000.0 + 200.0 * IN, 1000.0 + 200.0 * OUT], floor) == [True, True, False]
    assert tied([1000.0, 1020.0 * IN, 1020.0 * OUT], floor, tolerance=0.02) == [True, True, False]
    # Not finite costs never tie, and with none finite none ties.
    assert tied([math.nan, 1000.0, math.inf], floor) == [False, True, False]
    assert tied([math.nan, math.inf], floor) == [False, False]
