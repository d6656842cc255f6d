"""Time-domain simulation of LPV models along a scheduling trajectory."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal
from scipy.linalg import expm

import lpvid
from lpvid.testing import random_lpv


def loop_simulation(model: lpvid.LpvModel, u: np.ndarray, p: np.ndarray, x0: np.ndarray):
    """The recursion written out in numpy, one frozen model per sample."""
    x = x0.copy()
    ys, xs = [], [x.copy()]
    for t in range(len(u)):
        a, b, c, d = model.at(p[t])
        ys.append(c @ x + d @ u[t])
        x = a @ x + b @ u[t]
        xs.append(x.copy())
    return np.array(ys), np.array(xs)


@pytest.mark.parametrize(
    ("n", "r", "l", "nb"),
    [(3, 2, 2, 2), (6, 1, 2, 4), (2, 1, 1, 0), (3, 1, 1, 6), (30, 2, 4, 1)],
)
def test_constant_p_equals_dlsim(rng, n, r, l, nb):
    # (6, 1, 2, 4) is the gantry size; (3, 1, 1, 6) has more basis functions
    # than the kernels specialise; (30, 2, 4, 1) runs the general path.
    model = random_lpv(rng, n=n, r=r, l=l, nb=nb, Ts=0.01)
    T = 5000
    u = rng.normal(size=(T, r))
    x0 = rng.normal(size=n)
    a, b, c, d = model.at(0.3)
    _, y_ref, x_ref = signal.dlsim((a, b, c, d, 0.01), u, x0=x0)
    y, x = model.simulate(u, 0.3, x0, return_states=True)
    assert y.shape == (T, l) and x.shape == (T + 1, n)
    scale = np.max(np.abs(y_ref))
    assert np.max(np.abs(y - y_ref)) <= 1e-12 * scale
    assert np.max(np.abs(x[:-1] - x_ref)) <= 1e-12 * np.max(np.abs(x_ref))
    # the last state is one step beyond dlsim's
    assert np.allclose(x[-1], a @ x_ref[-1] + b @ u[-1], rtol=1e-12, atol=1e-12 * scale)


def test_varying_p_matches_the_recursion_written_out(rng):
    model = random_lpv(rng, n=4, r=2, l=3, nb=3, Ts=0.01)
    T = 300
    u = rng.normal(size=(T, 2))
    p = rng.uniform(0.0, 1.0, size=T)
    x0 = rng.normal(size=4)
    y_ref, x_ref = loop_simulation(model, u, p, x0)
    y, x = model.simulate(u, p, x0, return_states=True)
    assert np.max(np.abs(y - y_ref)) <= 1e-12 * np.max(np.abs(y_ref))
    assert np.max(np.abs(x - x_ref)) <= 1e-12 * np.max(np.abs(x_ref))


def test_two_scheduling_parameters(rng):
    basis = lpvid.Polynomial(2, domain=[(0.0, 1.0), (-1.0, 1.0)])
    nb = len(basis)
    A = 0.1 * rng.normal(size=(nb + 1, 3, 3))
    A[0] += 0.4 * np.eye(3)
    model = lpvid.LpvModel(
        A, rng.normal(size=(nb + 1, 3, 1)), rng.normal(size=(nb + 1, 2, 3)), basis=basis, Ts=1.0
    )
    T = 100
    p = np.column_stack([rng.uniform(0, 1, T), rng.uniform(-1, 1, T)])
    u = rng.normal(size=T)
    y_ref, _ = loop_simulation(model, u[:, None], p, np.zeros(3))
    assert np.allclose(model.simulate(u, p), y_ref, rtol=0, atol=1e-12 * np.abs(y_ref).max())
    with pytest.raises(
        ValueError,
        match=r"^p: the basis takes 2 scheduling parameters: expected shape \(T, 2\), got a single",
    ):
        model.simulate(u, 0.5)
    with pytest.raises(
        ValueError,
        match=r"^p: the basis takes 2 scheduling parameters: expected shape \(T, 2\), got \(100,\)",
    ):
        model.simulate(u, p[:, 0])


def test_continuation_from_the_last_state(rng):
    model = random_lpv(rng, n=3, r=1, l=2, nb=2, Ts=0.01)
    u = rng.normal(size=(400, 1))
    p = np.linspace(0, 1, 400)
    y, x = model.simulate(u, p, return_states=True)
    y1, x1 = model.simulate(u[:150], p[:150], return_states=True)
    y2 = model.simulate(u[150:], p[150:], x0=x1[-1])
    assert np.allclose(np.vstack([y1, y2]), y, rtol=0, atol=1e-13 * np.abs(y).max())


def test_continuous_time_constant_p_equals_zoh_dlsim(rng):
    model = random_lpv(rng, n=4, r=2, l=2, nb=2, Ts=None)
    dt = 0.02
    T = 5000
    u = rng.normal(size=(T, 2))
    x0 = rng.normal(size=4)
    a, b, c, d = model.at(0.7)
    ad, bd, cd, dd, _ = signal.cont2discrete((a, b, c, d), dt, method="zoh")
    _, y_ref, _ = signal.dlsim((ad, bd, cd, dd, dt), u, x0=x0)
    y = model.simulate(u, 0.7, x0, dt=dt)
    assert np.max(np.abs(y - y_ref)) <= 1e-12 * np.max(np.abs(y_ref))


def test_continuous_time_varying_p_holds_u_and_p_over_each_sample(rng):
    model = random_lpv(rng, n=3, r=1, l=2, nb=2, Ts=None)
    dt = 0.05
    T = 300
    u = rng.normal(size=(T, 1))
    p = rng.uniform(0, 1, size=T)
    x = np.zeros(3)
    y_ref = []
    for t in range(T):
        a, b, c, d = model.at(p[t])
        y_ref.append(c @ x + d @ u[t])
        m = np.zeros((4, 4))
        m[:3, :3], m[:3, 3:] = a * dt, b * dt
        e = expm(m)
        x = e[:3, :3] @ x + e[:3, 3:] @ u[t]
    y_ref = np.array(y_ref)
    y = model.simulate(u, p, dt=dt)
    assert np.max(np.abs(y - y_ref)) <= 1e-12 * np.max(np.abs(y_ref))


def test_slowly_varying_p_stays_close_to_frozen_behaviour(rng):
    # A sine through a model whose p ramps slowly: after the transient, the
    # output follows the frozen steady-state response G(f0, p(t)).
    model = random_lpv(rng, n=3, r=1, l=2, nb=2, Ts=1e-3)
    f0, T = 37.0, 40000
    t = np.arange(T)
    u = np.cos(2 * np.pi * f0 * t * 1e-3)
    p = np.linspace(0.0, 1.0, T)
    y = model.simulate(u, p)
    check = t[2000::97]
    G = model.frf([f0], p[check])[:, 0, :, 0]  # (len(check), l)
    frozen = np.real(G * np.exp(2j * np.pi * f0 * check * 1e-3)[:, None])
    amplitude = np.abs(G)
    # the frozen response changes a lot along the ramp ...
    assert np.max(np.abs(amplitude - amplitude[0])) > 0.1 * np.max(amplitude)
    # ... and the simulation tracks it closely
    assert np.max(np.abs(y[check] - frozen)) < 5e-3 * np.max(amplitude)
    # while holding p at its start value does not
    y_fixed = model.simulate(u, 0.0)
    assert np.max(np.abs(y_fixed[check] - frozen)) > 0.05 * np.max(amplitude)


def test_unstable_model_gives_non_finite_output_not_an_error():
    model = lpvid.LpvModel([[1.5]], [[1.0]], [[1.0]], Ts=1.0)
    y = model.simulate(np.ones(3000), 0.0)
    assert not np.all(np.isfinite(y))


def test_bad_input_is_named(rng):
    model = random_lpv(rng, n=3, r=2, l=2, nb=2, Ts=0.01)
    u = rng.normal(size=(50, 2))
    p = np.linspace(0, 1, 50)
    for kwargs, name in [
        ({"u": u[:, :1], "p": p}, r"u: expected shape \(T, 2\) for a model with 2 inputs"),
        ({"u": u[:, 0], "p": p}, r"u: the model has 2 inputs"),
        ({"u": u[:0], "p": p[:0]}, r"u: needs at least one sample"),
        ({"u": np.where(u > 1, np.nan, u), "p": p}, r"u: contains NaN or Inf"),
        ({"u": u, "p": p[:-1]}, r"p: expected one scheduling value per sample of u \(T=50\)"),
        ({"u": u, "p": np.where(p > 0.5, np.inf, p)}, r"p: contains NaN or Inf"),
        ({"u": u, "p": p, "x0": np.zeros(2)}, r"x0: expected 3 initial states"),
        ({"u": u, "p": p, "x0": [0.0, np.nan, 0.0]}, r"x0: contains NaN or Inf"),
        (
            {"u": u, "p": p, "dt": 0.02},
            r"dt: a discrete-time model runs at its sample time Ts=0.01 s",
        ),
    ]:
        with pytest.raises(ValueError, match=f"^{name}"):
            model.simulate(**kwargs)
    with pytest.raises(TypeError, match=r"^u: must be real, got a complex array"):
        model.simulate(u + 0j, p)
    # a discrete-time model accepts its own sample time
    assert np.array_equal(model.simulate(u, p, dt=0.01), model.simulate(u, p))
    ct = random_lpv(rng, n=3, r=2, l=2, nb=2, Ts=None)
    with pytest.raises(
        ValueError, match=r"^dt: a continuous-time model needs the sample time of u"
    ):
        ct.simulate(u, p)
    with pytest.raises(ValueError, match=r"^dt: expected a finite number > 0"):
        ct.simulate(u, p, dt=-1.0)
