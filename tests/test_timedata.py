"""TimeData and TimeCost: shapes, sigma forms, and errors that name the argument."""

from __future__ import annotations

import numpy as np
import pytest

import lpvid


def test_one_record_shapes_and_sigma_forms():
    T = 50
    u, p, y = np.ones(T), np.linspace(0, 1, T), np.zeros((T, 2))
    td = lpvid.TimeData(u, p, y, dt=0.1)
    assert (td.n_records, td.n_inputs, td.n_outputs, td.n_params) == (1, 1, 2, 1)
    assert td.n_samples == [T] and td.n_residuals == 2 * T
    assert td.u[0].shape == (T, 1) and td.p[0].shape == (T,)
    np.testing.assert_array_equal(td.sigma[0], np.ones((T, 2)))
    per_output = lpvid.TimeData(u, p, y, dt=0.1, sigma=[0.1, 0.2]).sigma[0]
    np.testing.assert_array_equal(per_output, np.tile([0.1, 0.2], (T, 1)))
    per_sample = np.linspace(1, 2, 2 * T).reshape(T, 2)
    np.testing.assert_array_equal(lpvid.TimeData(u, p, y, 0.1, per_sample).sigma[0], per_sample)
    assert td.p_range == (0.0, 1.0)
    with pytest.raises(ValueError, match="read-only"):
        td.y[0][0, 0] = 1.0


def test_several_records_and_two_scheduling_parameters():
    rng = np.random.default_rng(0)
    us = [rng.normal(size=(30, 2)), rng.normal(size=(20, 2))]
    ps = [rng.uniform(size=(30, 2)), rng.uniform(size=(20, 2))]
    ys = [rng.normal(size=30), rng.normal(size=20)]
    td = lpvid.TimeData(us, ps, ys, dt=1.0, sigma=[np.full(30, 0.5), np.full(20, 0.2)])
    assert (td.n_records, td.n_inputs, td.n_outputs, td.n_params) == (2, 2, 1, 2)
    assert td.n_samples == [30, 20] and td.n_residuals == 50
    assert td.sigma[1].shape == (20, 1) and td.sigma[1][0, 0] == 0.2
    one = td.record(1)
    np.testing.assert_array_equal(one.y[0], td.y[1])
    assert len(td.p_range) == 2
    cost = lpvid.TimeCost(td, x0="zero", skip=5)
    assert cost.n_residuals == 50 - 2 * 5
    with pytest.raises(ValueError, match="k: expected a record index"):
        td.record(2)


@pytest.mark.parametrize(
    "kwargs, error, pattern",
    [
        (dict(u=np.ones(10), p=np.ones(9), y=np.ones(10)), ValueError, r"^p: expected one row"),
        (dict(u=np.ones(10), p=np.ones(10), y=np.ones(11)), ValueError, r"^y: expected one row"),
        (dict(u=np.ones(0), p=np.ones(0), y=np.ones(0)), ValueError, r"^u: needs at least"),
        (dict(u=[np.nan] * 10, p=np.ones(10), y=np.ones(10)), ValueError, r"^u: contains NaN"),
        (dict(u=np.ones(10), p=np.ones(10), y=np.ones(10) * 1j), TypeError, r"^y: must be real"),
        (dict(u=np.ones(10), p=np.ones(10), y=np.ones(10), dt=0), ValueError, r"^dt: expected"),
        (dict(u=np.ones(10), p=np.ones(10), y=np.ones(10), sigma=0), ValueError, r"^sigma: stand"),
        (
            dict(u=np.ones(10), p=np.ones(10), y=np.ones((10, 2)), sigma=np.ones(3)),
            ValueError,
            r"^sigma: expected one number, one per output \(2,\)",
        ),
        (dict(u=[np.ones(5)], p=np.ones(5), y=[np.ones(5)]), TypeError, r"^p: several records"),
        (
            dict(
                u=[np.ones(5), np.ones(4)], p=[np.ones(5), np.ones(3)], y=[np.ones(5), np.ones(4)]
            ),
            ValueError,
            r"^p\[1\]: expected one row per sample of u\[1\] \(T=4\)",
        ),
        (
            dict(
                u=[np.ones(5), np.ones((4, 2))],
                p=[np.ones(5), np.ones(4)],
                y=[np.ones(5), np.ones(4)],
            ),
            ValueError,
            r"^records: record 1 has 2 inputs",
        ),
        (
            dict(u=[np.ones(5)], p=[np.ones(5)], y=[np.ones(5)], sigma=[np.ones(5)] * 2),
            ValueError,
            r"^sigma: 2 arrays given for 1 records",
        ),
    ],
)
def test_bad_records_are_named(kwargs, error, pattern):
    args = dict(dt=0.1) | kwargs
    with pytest.raises(error, match=pattern):
        lpvid.TimeData(**args)


def test_time_cost_checks_its_options():
    td = lpvid.TimeData(np.ones(20), np.zeros(20), np.zeros(20), dt=1.0)
    with pytest.raises(ValueError, match=r"^x0: expected 'estimate', 'zero'"):
        lpvid.TimeCost(td, x0="guess")
    with pytest.raises(ValueError, match=r"^skip: 20 samples skipped leave nothing"):
        lpvid.TimeCost(td, skip=20)
    with pytest.raises(TypeError, match=r"^skip: expected an integer, got float$"):
        lpvid.TimeCost(td, skip=1.5)
    with pytest.raises(TypeError, match=r"^skip: expected an integer, got bool$"):
        lpvid.TimeCost(td, skip=True)
    with pytest.raises(ValueError, match=r"^skip: expected an integer >= 0, got -1$"):
        lpvid.TimeCost(td, skip=-1)
    with pytest.raises(TypeError, match=r"^time_data: expected a TimeData, got ndarray$"):
        lpvid.TimeCost(np.ones(3))
    with pytest.raises(TypeError, match=r"^time_data: expected a TimeData or TimeCost, got list$"):
        lpvid.time_vnls(None, [td])
    with pytest.raises(ValueError, match=r"^x0: expected a 1 or 2-dimensional array"):
        lpvid.TimeCost(td, x0=np.zeros((1, 1, 2)))
    # The options are stored checked: x0 as an array, skip as a Python int.
    cost = lpvid.TimeCost(td, x0=[1.0, 2.0], skip=np.int64(3))
    assert isinstance(cost.x0, np.ndarray) and type(cost.skip) is int and cost.skip == 3
    with pytest.raises(ValueError, match=r"^x0: expected shape \(2,\) or \(1, 2\)"):
        lpvid.TimeCost(td, x0=np.zeros(3)).x0_values(2)
    np.testing.assert_array_equal(lpvid.TimeCost(td, x0=[1.0, 2.0]).x0_values(2), [[1.0, 2.0]])
