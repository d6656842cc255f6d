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


def _tenfold(basis: bool = True) -> lpvid.LpvModel:
    """x(t+1) = 10 x(t) + u(t), y = x: from x(0) = 1, y(t) = 10^t, finite up
    to t = 308; with a first-order basis whose coefficients are zero."""
    if not basis:
        return lpvid.LpvModel([[10.0]], [[1.0]], [[1.0]], Ts=1.0)
    zero = [[0.0]]
    return lpvid.LpvModel(
        [[[10.0]], zero],
        [[[1.0]], zero],
        [[[1.0]], zero],
        [zero, zero],
        lpvid.Polynomial(1),
        Ts=1.0,
    )


def test_divergence_warns_with_the_sample_and_the_scheduling_value():
    model = _tenfold()
    T = 400
    p = 0.01 * np.arange(T)
    with pytest.warns(RuntimeWarning, match=r"sample 309 \(p = 3\.09\)") as caught:
        y = model.simulate(np.zeros(T), p, x0=[1.0])
    assert len(caught) == 1
    assert caught[0].filename == __file__  # points at the caller's line
    # The outputs come back as computed: 10^t up to the divergence.
    assert np.all(np.isfinite(y[:309])) and not np.isfinite(y[309, 0])
    assert np.allclose(y[:309, 0], 10.0 ** np.arange(309), rtol=1e-12, atol=0)
    # With the states, the first infinite one is x(309), computed at sample 308.
    with pytest.warns(RuntimeWarning, match=r"sample 308 \(p = 3\.08\)"):
        y, x = model.simulate(np.zeros(T), p, x0=[1.0], return_states=True)
    assert np.isfinite(x[308, 0]) and not np.isfinite(x[309, 0])


def test_divergence_raises_when_asked():
    model = _tenfold()
    p = np.zeros(400)
    with pytest.raises(ValueError, match=r"sample 309 \(p = 0\.0\).*unstable"):
        model.simulate(np.zeros(400), p, x0=[1.0], on_divergence="raise")
    # Nothing to report on a stable stretch.
    y = model.simulate(np.zeros(300), p[:300], x0=[1.0], on_divergence="raise")
    assert np.all(np.isfinite(y))
    with pytest.raises(ValueError, match=r"^on_divergence: expected one of \('warn', 'raise'\)"):
        model.simulate(np.zeros(3), p[:3], on_divergence="ignore")


def test_divergence_in_continuous_time():
    # dx/dt = 1000 x: exp(1000 dt) overflows in the first step.
    model = lpvid.LpvModel([[1000.0]], [[1.0]], [[1.0]], Ts=None)
    with pytest.warns(RuntimeWarning, match="sample 1 "):
        y = model.simulate(np.zeros(5), 0.0, x0=[1.0], dt=1.0)
    assert y[0, 0] == 1.0 and not np.isfinite(y[1, 0])
    with pytest.raises(
        ValueError, match=r"^simulate: the simulation left the range of floating point at sample 1 "
    ):
        model.simulate(np.zeros(5), 0.0, x0=[1.0], dt=1.0, on_divergence="raise")


def _hold_matrices(a: np.ndarray, b: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Ad and Bd of the zero-order hold as LpvModel.simulate computes them,
    read off one-step simulations with identity outputs: x(1) = Ad x0 + Bd u0."""
    n, r = b.shape
    model = lpvid.LpvModel(a, b, np.eye(n), np.zeros((n, r)), Ts=None)
    ad = np.empty((n, n))
    bd = np.empty((n, r))
    for j in range(n):
        _, x = model.simulate(np.zeros((1, r)), 0.0, np.eye(n)[j], dt=dt, return_states=True)
        ad[:, j] = x[1]
    for k in range(r):
        _, x = model.simulate(np.eye(r)[k : k + 1], 0.0, dt=dt, return_states=True)
        bd[:, k] = x[1]
    return ad, bd


def _stiff(seed: int, symmetric: bool) -> tuple[np.ndarray, np.ndarray]:
    # Time constants 1 s, 1 ms and 1 us: triangular and far from normal, or
    # symmetric in random coordinates.
    rng = np.random.default_rng(seed)
    if symmetric:
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        a = q @ np.diag([-1.0, -1e3, -1e6]) @ q.T
    else:
        a = np.diag([-1.0, -1e3, -1e6]) + np.triu(rng.normal(size=(3, 3)) * 1e3, 1)
    return a, rng.normal(size=(3, 2))


def _modes(seed: int) -> tuple[np.ndarray, np.ndarray]:
    # Modes at 50 Hz and 313 Hz with damping ratios 1e-3 and 1e-4 in random
    # orthogonal coordinates.
    rng = np.random.default_rng(seed)
    a = np.zeros((4, 4))
    for k, (f, zeta) in enumerate([(50.0, 1e-3), (313.0, 1e-4)]):
        w = 2 * np.pi * f
        s, wd = zeta * w, w * np.sqrt(1 - zeta**2)
        a[2 * k : 2 * k + 2, 2 * k : 2 * k + 2] = [[-s, wd], [-wd, -s]]
    q, _ = np.linalg.qr(rng.normal(size=(4, 4)))
    return q @ a @ q.T, rng.normal(size=(4, 1))


def _two_masses(seed: int) -> tuple[np.ndarray, np.ndarray]:
    # Two masses on springs with light damping (modes near 4 Hz and 8 Hz),
    # positions and velocities as states, a force on the first mass.
    k1, k2, c = 1e3, 5e2, 0.05
    m_inv = np.diag([1.0, 2.0])
    k = np.array([[k1 + k2, -k2], [-k2, k2]])
    a = np.block([[np.zeros((2, 2)), np.eye(2)], [-m_inv @ k, -c * m_inv]])
    return a, np.array([[0.0], [0.0], [1.0], [0.0]])


# (system, dt): stiffness ratio 1e6 with the fastest mode over up to 1000
# time constants per sample; lightly damped modes over up to 3 periods per
# sample. As ||A dt|| grows the exponential becomes ill-conditioned and
# every algorithm drifts from the exact result (measured against mpmath at
# ||A dt|| = 1e5: 5e-13 to 2e-12 relative for scipy and nalgebra alike), so
# 1e-13 is asked where the comparison with scipy can show it.
@pytest.mark.parametrize(
    ("system", "dt"),
    [
        (lambda s: _stiff(s, symmetric=False), 1e-4),
        (lambda s: _stiff(s, symmetric=False), 1e-3),
        (lambda s: _stiff(s, symmetric=True), 1e-4),
        (_modes, 1e-3),
        (_modes, 1e-2),
        (_two_masses, 1e-3),
        (_two_masses, 0.1),
        (_two_masses, 0.37),
    ],
)
@pytest.mark.parametrize("seed", [0, 1])
def test_zero_order_hold_matches_scipy_expm(system, dt, seed):
    a, b = system(seed)
    n, r = b.shape
    m = np.zeros((n + r, n + r))
    m[:n, :n], m[:n, n:] = a * dt, b * dt
    e = expm(m)
    ad, bd = _hold_matrices(a, b, dt)
    for got, want in [(ad, e[:n, :n]), (bd, e[:n, n:])]:
        assert np.linalg.norm(got - want) <= 1e-13 * np.linalg.norm(want)


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
