"""Non-finite numbers never come back in silence: a property-based fuzz of the public API.

Random, malformed and extreme arguments (entries near 1e150 or 1e-200, NaN,
Inf, wrong shapes, damaged files) go to the data and model constructors,
``frf``, ``vnls``, ``simulate``, the fits and the file readers. Every call
must either raise one of the documented errors (ValueError, TypeError,
SingularModelError) or return finite numbers, or, where a non-finite result
is documented (a simulation that diverges, V_NLS beyond float64), say so
with a warning. About 1.1 x 10^4 calls in all (1500 x 3 constructor calls,
1200 x 4 model evaluations, 1500 simulations, 700 x 2 fits, 600 damaged
files); kept fast with tiny models.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from typing import Any

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import lpvid

DOCUMENTED = (ValueError, TypeError, lpvid.SingularModelError)


def fast(examples: int) -> settings:
    """Deterministic, no example database, no deadline (the machines are shared)."""
    return settings(
        max_examples=examples,
        deadline=None,
        database=None,
        derandomize=True,
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
    )


SCALES = [1e-200, 1e-30, 1e-3, 1.0, 1e3, 1e30, 1e150, 1e300]


def finite(value: Any) -> bool:
    """Whether every number in a result is finite."""
    if isinstance(value, lpvid.FitResult):
        return finite(value.vnls) and finite(value.model)
    if isinstance(value, lpvid.LpvModel):
        return bool(np.all(np.isfinite(value.theta)))
    if isinstance(value, lpvid.FrfData):
        return finite(value.G) and finite(value.sigma) and finite(value.p)
    if isinstance(value, tuple | list):
        return all(finite(v) for v in value)
    if isinstance(value, np.ndarray | float | int | complex | np.floating):
        return bool(np.all(np.isfinite(value)))
    return True


def outcome(call: Callable[[], Any]) -> str:
    """Run ``call``: 'error' (documented), 'finite', or 'warned' (non-finite, with a warning)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            result = call()
        except DOCUMENTED:
            return "error"
    if finite(result):
        return "finite"
    assert caught, f"a non-finite result came back without an error or a warning: {result!r}"
    return "warned"


def arrays(shape: tuple[int, ...], draw: Any, complex_: bool = False) -> np.ndarray:
    """Random entries of one scale, sometimes with a NaN or an Inf."""
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    scale = draw(st.sampled_from(SCALES))
    a = rng.standard_normal(shape) * scale
    if complex_:
        a = a + 1j * rng.standard_normal(shape) * scale
    poison = draw(st.sampled_from([None, None, None, np.nan, np.inf, -np.inf]))
    if poison is not None and a.size:
        a.flat[draw(st.integers(0, a.size - 1))] = poison
    return a


@st.composite
def models(draw: Any, Ts: float | None = 0.01) -> lpvid.LpvModel | None:
    n, r, l, nb = (draw(st.integers(1, 3)) for _ in range(4))
    nb -= 1
    basis = lpvid.Polynomial(nb, domain=(0.0, 1.0))
    parts = [arrays((nb + 1, *s), draw) for s in ((n, n), (n, r), (l, n), (l, r))]
    try:
        return lpvid.LpvModel(*parts, basis=basis, Ts=draw(st.sampled_from([Ts, None])))
    except DOCUMENTED:
        return None


@st.composite
def data_for(draw: Any, model: lpvid.LpvModel) -> lpvid.FrfData | None:
    N = draw(st.integers(1, 4))
    F = draw(st.integers(1, 5))
    p = np.linspace(0.0, 1.0, N)
    f = np.array(sorted(draw(st.sets(st.floats(0.0, 49.0), min_size=F, max_size=F))))
    G = arrays((N, len(f), model.n_outputs, model.n_inputs), draw, complex_=True)
    sigma = np.abs(arrays(G.shape, draw)) + draw(st.sampled_from([0.0, 1e-300, 1.0]))
    try:
        return lpvid.FrfData(p, f, G, sigma, Ts=model.Ts)
    except DOCUMENTED:
        return None


@fast(1500)
@given(st.data())
def test_constructors(data):
    draw = data.draw
    shape = draw(st.sampled_from([(3, 4), (3, 4, 1, 1), (2, 4, 2, 3), (0, 4), (3,), (3, 4, 1)]))
    outcome(
        lambda: lpvid.FrfData(
            arrays((shape[0],) if shape else (1,), draw),
            np.arange(1.0, 1.0 + (shape[1] if len(shape) > 1 else 1)),
            arrays(shape, draw, complex_=True),
            sigma=np.abs(arrays(shape, draw)) if draw(st.booleans()) else None,
            Ts=draw(st.sampled_from([None, 0.01, 0.0, -1.0, np.nan])),
        )
    )
    outcome(lambda: lpvid.Polynomial(2, domain=tuple(arrays((2,), draw))))
    outcome(lambda: lpvid.Polynomial(2, domain=(0, 1))(arrays((4,), draw)))


@fast(1200)
@given(st.data())
def test_frf_and_vnls(data):
    model = data.draw(models())
    if model is None:
        return
    d = data.draw(data_for(model))
    outcome(lambda: model.frf(np.linspace(0.0, 40.0, 3), [0.0, 0.5, 1.0]))
    outcome(lambda: model.at(0.3))
    if d is not None:
        outcome(lambda: lpvid.vnls(model, d))
        outcome(lambda: lpvid.residual(model, d))


@fast(1500)
@given(st.data())
def test_simulate(data):
    model = data.draw(models())
    if model is None:
        return
    T = data.draw(st.integers(1, 40))
    u = arrays((T, model.n_inputs), data.draw)
    p = np.clip(np.abs(arrays((T,), data.draw)), 0.0, 1.0)
    outcome(lambda: model.simulate(u, p, dt=0.01 if model.Ts is None else None))


@fast(700)
@given(st.data())
def test_fits(data):
    model = data.draw(models())
    if model is None:
        return
    d = data.draw(data_for(model))
    if d is None:
        return
    outcome(lambda: lpvid.fit_nls(model, d, max_iter=3, warn=False))
    if model.n_basis:
        gamma = data.draw(st.sampled_from([0.0, 1e-3, 1.0, 1e300]))
        outcome(lambda: lpvid.fit_l21(model, d, gamma, max_outer=2, max_inner=2, warn=False))


@fast(600)
@given(st.binary(max_size=400), st.sampled_from([".json", ".mat", ".npz"]))
def test_damaged_files(tmp_path_factory, blob, suffix):
    path = tmp_path_factory.mktemp("fuzz") / f"file{suffix}"
    path.write_bytes(blob)
    loader = lpvid.FrfData.load if suffix == ".npz" else lpvid.LpvModel.load
    assert outcome(lambda: loader(path)) == "error"
