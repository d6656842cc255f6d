"""The model handed on: a python-control system scheduled by p, a gridded MATLAB file."""

import sys

import numpy as np
import pytest

import lpvid
from lpvid.testing import random_lpv

control = pytest.importorskip("control")
loadmat = pytest.importorskip("scipy.io").loadmat


def trajectory(rng, T, r, dt):
    """Inputs and a scheduling value sweeping the domain [0, 1] back and forth."""
    t = np.arange(T) * dt
    p = 0.5 + 0.45 * np.sin(2 * np.pi * t / (T * dt) * 1.5) + 0.04 * rng.uniform(-1, 1, T)
    return rng.normal(size=(T, r)), p


def test_discrete_time_matches_simulate_along_p(rng):
    model = random_lpv(rng, n=4, r=2, l=3, nb=3, Ts=0.01)
    u, p = trajectory(rng, 300, 2, model.Ts)
    x0 = rng.normal(size=4)
    sys_ = model.to_control_lpv()
    assert isinstance(sys_, control.NonlinearIOSystem) and sys_.dt == model.Ts
    assert sys_.input_labels == ["u[0]", "u[1]", "p[0]"]
    assert sys_.output_labels == ["y[0]", "y[1]", "y[2]"]
    T = np.arange(300) * model.Ts
    resp = control.input_output_response(sys_, T, np.vstack([u.T, p]), x0)
    y, x = model.simulate(u, p, x0, return_states=True)
    scale = np.max(np.abs(y))
    assert np.max(np.abs(resp.outputs.T - y)) <= 1e-10 * scale
    np.testing.assert_allclose(resp.states.T, x[:-1], rtol=0, atol=1e-10 * np.max(np.abs(x)))
    # p matters: the same inputs at a constant p give other outputs.
    frozen = control.input_output_response(
        sys_, T, np.vstack([u.T, np.full(300, 0.5)]), x0
    ).outputs.T
    assert np.max(np.abs(frozen - y)) > 1e-2 * scale


def test_full_state_outputs_the_states(rng):
    model = random_lpv(rng, n=3, r=1, l=2, nb=2, Ts=0.01)
    u, p = trajectory(rng, 50, 1, model.Ts)
    sys_ = model.to_control_lpv(full_state=True)
    assert sys_.output_labels == ["x[0]", "x[1]", "x[2]"]
    resp = control.input_output_response(sys_, np.arange(50) * model.Ts, np.vstack([u.T, p]))
    _, x = model.simulate(u, p, return_states=True)
    np.testing.assert_allclose(resp.outputs.T, x[:-1], rtol=0, atol=1e-12 * np.max(np.abs(x)))


def test_continuous_time_matches_the_zero_order_hold_sample_by_sample(rng):
    """python-control integrates the ODE (solve_ivp, inputs interpolated linearly
    between the given times); lpvid.simulate holds u and p over each sample and
    solves exactly. Given u and p constant over one sample per call, both solve
    the same ODE: they agree to the solver's tolerance (DOP853, rtol 1e-12);
    4e-16 of the output scale was measured, 1e-11 is asked over 40 samples."""
    model = random_lpv(rng, n=3, r=2, l=2, nb=2, Ts=None)
    dt = 0.05
    u, p = trajectory(rng, 40, 2, dt)
    x = x0 = rng.normal(size=3)
    sys_ = model.to_control_lpv(name="plant")
    assert sys_.dt == 0 and sys_.name == "plant"
    y_ctrl = []
    for k in range(40):
        held = np.repeat(np.concatenate([u[k], [p[k]]])[:, None], 2, axis=1)
        resp = control.input_output_response(
            sys_,
            [k * dt, (k + 1) * dt],
            held,
            x,
            solve_ivp_method="DOP853",
            solve_ivp_kwargs={"rtol": 1e-12, "atol": 1e-14},
        )
        y_ctrl.append(resp.outputs[:, 0])
        x = resp.states[:, -1]
    y = model.simulate(u, p, x0, dt=dt)
    assert np.max(np.abs(np.array(y_ctrl) - y)) <= 1e-11 * np.max(np.abs(y))


def test_a_gain_scheduled_state_feedback_is_the_frozen_closed_loop(rng):
    """create_statefbk_iosystem on the hand-off: p passes the controller as ud[r]
    (a zero row of the gain) and schedules it; at a grid value the closed loop is
    x+ = (A - B K) x there."""
    model = random_lpv(rng, n=3, r=1, l=2, nb=2, Ts=0.01)
    plant = model.to_control_lpv(full_state=True, inputs=["torque"], parameters=["load"])
    points = np.linspace(0.0, 1.0, 3)
    gains = []
    for value in points:
        A, B, _, _ = model.at(value)
        K, _, _ = control.dlqr(A, B, np.eye(3), np.eye(1))
        gains.append(np.vstack([K, np.zeros((1, 3))]))  # the row of p: passed through
    # python-control 0.10 builds a scheduled controller with the default timebase
    # (0: continuous time); None lets it join a discrete-time plant.
    control.set_defaults("control", default_dt=None)
    try:
        _, closed = control.create_statefbk_iosystem(
            plant, (gains, points), gainsched_indices=["ud[1]"]
        )
    finally:
        control.set_defaults("control", default_dt=0)
    assert closed.dt == model.Ts
    x0 = rng.normal(size=3)
    T = np.arange(30) * model.Ts
    for j in (0, 2):
        inputs = np.zeros((closed.ninputs, 30))
        inputs[closed.input_labels.index("ud[1]")] = points[j]
        resp = control.input_output_response(closed, T, inputs, x0)
        A, B, _, _ = model.at(points[j])
        x, expected = x0, []
        for _ in range(30):
            expected.append(x)
            x = (A - B @ gains[j][:1]) @ x
        states = resp.outputs[: model.n_states].T
        np.testing.assert_allclose(states, expected, rtol=0, atol=1e-12 * np.max(np.abs(x0)))


def test_names_come_from_the_data_set(rng):
    ds = lpvid.datasets.gantry()
    model = random_lpv(rng, n=2, r=1, l=2, nb=1, Ts=ds.Ts, domain=(24.0, 48.0))
    sys_ = model.to_control_lpv(ds)
    assert sys_.input_labels == ["motor torque [N m]", "tube side p [mm]"]
    assert sys_.output_labels == list(ds.outputs)
    data = ds.identification.subset([0, 1])
    data.provenance = {"inputs": ["torque"], "outputs": ["head", "carriage"], "parameters": None}
    sys_ = model.to_control_lpv(data, parameters=["side"])
    assert sys_.input_labels == ["torque", "side"]
    assert sys_.output_labels == ["head", "carriage"]


@pytest.mark.parametrize(
    "kwargs, error, message",
    [
        ({"inputs": ["a", "b"]}, ValueError, r"^inputs: 2 names for a model with 1 inputs"),
        ({"outputs": ["a"]}, ValueError, r"^outputs: 1 names for a model with 2 outputs"),
        ({"inputs": ["p[0]"]}, ValueError, r"^names: \['p\[0\]'\] name more than one signal"),
        ({"outputs": ["a.b", "c"]}, ValueError, r"^outputs: 'a.b' cannot name a python-control"),
        ({"inputs": "torque"}, TypeError, r"^inputs: expected a list of names"),
        ({"names": 3}, TypeError, r"^names: expected an FrfData or a built-in data set, got int"),
        ({"full_state": 1}, TypeError, r"^full_state: expected True or False"),
    ],
)
def test_bad_names(rng, kwargs, error, message):
    model = random_lpv(rng, n=2, r=1, l=2, nb=1, Ts=0.01)
    with pytest.raises(error, match=message):
        model.to_control_lpv(**kwargs)


def test_names_of_a_data_set_that_does_not_fit(rng):
    model = random_lpv(rng, n=2, r=2, l=2, nb=1, Ts=0.01)
    with pytest.raises(ValueError, match=r"^names: the data set's inputs: 1 names for a model"):
        model.to_control_lpv(lpvid.datasets.gantry())


def test_a_scheduling_input_that_is_not_finite_names_the_time(rng):
    model = random_lpv(rng, n=2, r=1, l=1, nb=1, Ts=0.01)
    p = np.full(5, 0.5)
    p[3] = np.nan
    with pytest.raises(ValueError, match=r"^p: the scheduling input is \[nan\] at t = 0.03"):
        control.input_output_response(
            model.to_control_lpv(), np.arange(5) * 0.01, np.vstack([np.ones(5), p])
        )


def test_without_python_control_the_error_names_the_extra(rng, monkeypatch):
    model = random_lpv(rng, n=2, r=1, l=1, nb=1, Ts=0.01)
    monkeypatch.setitem(sys.modules, "control", None)
    with pytest.raises(ImportError, match=r'needs python-control: pip install "lpvid\[control\]"'):
        model.to_control_lpv()


# ------------------------------------------------------------------ the gridded MATLAB file
def by_hand(model, p):
    """X(0) + sum_i s^i X(i), s = p mapped from the basis domain to [-1, 1]."""
    (lo, hi) = model.basis.domain[0]
    s = 2 * (p - lo) / (hi - lo) - 1
    w = s ** np.arange(len(model.basis) + 1)
    return [np.tensordot(w, x, axes=1) for x in (model.A, model.B, model.C, model.D)]


@pytest.mark.parametrize("Ts", [None, 5e-4])
def test_the_grid_file_holds_the_frozen_models(tmp_path, rng, Ts):
    ds = lpvid.datasets.gantry()
    model = random_lpv(rng, n=3, r=1, l=2, nb=3, Ts=Ts, domain=(24.0, 48.0))
    grid = np.array([24.0, 30.0, 33.5, 48.0])
    path = model.save_grid(tmp_path / "g.mat", grid, ds)
    f = loadmat(path)  # scipy only: no lpvid
    assert f["A"].shape == (3, 3, 4) and f["B"].shape == (3, 1, 4) and f["D"].shape == (2, 1, 4)
    np.testing.assert_array_equal(f["grid"][0, 0].ravel(), grid)
    np.testing.assert_array_equal(f["SamplingGrid"]["tube_side_p_mm"][0, 0], grid[:, None])
    assert float(f["Ts"][0, 0]) == (0.0 if Ts is None else Ts)
    assert [x[0] for x in f["OutputName"].ravel()] == list(ds.outputs)
    assert [x[0] for x in f["InputName"].ravel()] == list(ds.inputs)
    assert "ss(s.A, s.B, s.C, s.D, s.Ts" in str(f["description"][0])
    freqs = np.linspace(1.0, 300.0, 7)
    for k, value in enumerate(grid):
        frozen = [f[x][:, :, k] for x in "ABCD"]
        for got, want in zip(frozen, by_hand(model, value), strict=True):
            np.testing.assert_allclose(got, want, rtol=0, atol=1e-14 * np.max(np.abs(want)))
        sys_ = control.ss(*frozen, 0 if Ts is None else Ts)
        s = 2j * np.pi * freqs
        G = np.moveaxis(sys_(s if Ts is None else np.exp(s * Ts), squeeze=False), -1, 0)
        np.testing.assert_allclose(G, model.frf(freqs, [value])[0], rtol=1e-10)


def test_a_grid_over_two_parameters(tmp_path, rng):
    basis = lpvid.Polynomial(2, domain=[(0.0, 1.0), (-1.0, 1.0)])
    nb = len(basis)
    model = lpvid.LpvModel(
        rng.normal(size=(nb + 1, 2, 2)), rng.normal(size=(nb + 1, 2, 1)),
        rng.normal(size=(nb + 1, 1, 2)), basis=basis,
    )  # fmt: skip
    a, b = np.array([0.0, 0.5, 1.0]), np.array([-1.0, 0.0, 0.25, 1.0])
    f = loadmat(model.save_grid(tmp_path / "g.mat", [a, b], parameters=["x", "temp"]))
    assert f["A"].shape == (2, 2, 3, 4)
    grid = f["SamplingGrid"]
    np.testing.assert_array_equal(grid["x"][0, 0], np.repeat(a[:, None], 4, axis=1))
    np.testing.assert_array_equal(grid["temp"][0, 0], np.repeat(b[None, :], 3, axis=0))
    for i, j in [(0, 0), (1, 2), (2, 3)]:
        for x, want in zip("ABCD", model.at([a[i], b[j]]), strict=True):
            np.testing.assert_allclose(f[x][:, :, i, j], want, rtol=1e-14, atol=1e-14)
    # 5 values per parameter over the basis domain
    f = loadmat(model.save_grid(tmp_path / "h.mat", count=5))
    assert f["A"].shape == (2, 2, 5, 5)
    np.testing.assert_array_equal(f["grid"][0, 1].ravel(), np.linspace(-1.0, 1.0, 5))
    assert sorted(f["SamplingGrid"].dtype.names) == ["p1", "p2"]


@pytest.mark.parametrize(
    "name, kwargs, message",
    [
        ("g.npz", {}, r"^path: expected a .mat file, got 'g.npz'"),
        ("g.mat", {"grid": [0.0, 0.5, 0.5]}, r"^grid: expected strictly increasing values"),
        ("g.mat", {"grid": [0.0, np.nan]}, r"^grid: contains NaN or Inf"),
        ("g.mat", {"count": 0}, r"^count: expected an integer >= 1, got 0"),
    ],
)
def test_bad_grid(tmp_path, rng, name, kwargs, message):
    model = random_lpv(rng, n=2, r=1, l=1, nb=1, Ts=0.01)
    with pytest.raises(ValueError, match=message):
        model.save_grid(tmp_path / name, **kwargs)
    assert not list(tmp_path.iterdir())  # nothing written


def test_a_grid_needs_values_when_the_model_has_no_range(tmp_path, rng):
    model = lpvid.LpvModel(
        rng.normal(size=(2, 2, 2)), rng.normal(size=(2, 2, 1)), rng.normal(size=(2, 1, 2)),
        basis=lpvid.Polynomial(1),
    )  # fmt: skip
    with pytest.raises(ValueError, match=r"^grid: the model has no p_range"):
        model.save_grid(tmp_path / "g.mat")
    f = loadmat(model.save_grid(tmp_path / "g.mat", [-2.0, 3.0]))
    np.testing.assert_allclose(f["A"][:, :, 1], model.A[0] + 3.0 * model.A[1], rtol=1e-15)
