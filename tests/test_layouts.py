"""Arrays in other memory layouts give the same numbers as C-ordered ones.

Fortran order, strided views and non-native byte order, at every place where
arrays enter lpvid and cross into the core: FrfData, LpvModel, the core's
Problem (through build_problem and directly), simulate and frf. Same
numbers means equal to the last bit: the core must read the values, not the
memory.
"""

from __future__ import annotations

import numpy as np
import pytest

import lpvid
from lpvid import _core
from lpvid.fit.cost import build_problem, gauss_newton
from lpvid.testing import noisy_data, random_lpv


def fortran(a):
    return np.asfortranarray(a)


def strided(a):
    """The same values as a view with gaps: every other entry of a wider array."""
    wide = np.zeros((*a.shape[:-1], 2 * a.shape[-1]), dtype=a.dtype)
    wide[..., ::2] = a
    return wide[..., ::2]


def swapped(a):
    """The same values in the other byte order."""
    return a.astype(a.dtype.newbyteorder())


def reversed_view(a):
    """The same values through a view with negative strides."""
    return np.flip(np.flip(a.copy(), axis=0).copy(), axis=0)


LAYOUTS = {"fortran": fortran, "strided": strided, "swapped": swapped, "reversed": reversed_view}


@pytest.fixture
def case(rng):
    model = random_lpv(rng, n=3, r=2, l=2, nb=2, Ts=0.01)
    data = noisy_data(model, np.array([0.0, 0.3, 0.7, 1.0]), np.linspace(1, 40, 9), rng)
    start = model.with_theta(model.theta + 0.01 * rng.normal(size=model.theta.size))
    return start, data


def relaid_data(data, layout):
    return lpvid.FrfData(
        layout(data.p), layout(data.freqs_hz), layout(data.G), layout(data.sigma), Ts=data.Ts
    )


def relaid_model(model, layout):
    return lpvid.LpvModel(
        *(layout(np.array(x)) for x in model.matrices().values()),
        basis=model.basis,
        Ts=model.Ts,
        p_range=model.p_range,
    )


@pytest.mark.parametrize("layout", LAYOUTS.values(), ids=LAYOUTS.keys())
def test_frf_data_and_model_in_other_layouts_give_the_same_fit_quantities(case, layout):
    start, data = case
    data2, start2 = relaid_data(data, layout), relaid_model(start, layout)
    for name in ("p", "freqs_hz", "G", "sigma"):
        np.testing.assert_array_equal(getattr(data2, name), getattr(data, name))
    assert start2.theta.tobytes() == start.theta.tobytes()
    assert lpvid.vnls(start2, data2) == lpvid.vnls(start, data)
    assert lpvid.residual(start2, data2).tobytes() == lpvid.residual(start, data).tobytes()
    v1, g1, h1 = gauss_newton(start, data)
    v2, g2, h2 = gauss_newton(start2, data2)
    assert v1 == v2 and g1.tobytes() == g2.tobytes() and h1.tobytes() == h2.tobytes()
    # five steps of the same fit (stopped short: both say so)
    with pytest.warns(lpvid.ConvergenceWarning):
        fit1 = lpvid.fit_nls(start, data, max_iter=5)
    with pytest.warns(lpvid.ConvergenceWarning):
        fit2 = lpvid.fit_nls(start2, data2, max_iter=5)
    assert fit1.model.theta.tobytes() == fit2.model.theta.tobytes()


def test_model_view_reads_basis_values_in_any_layout_by_value(case):
    """A view holds the basis array it is given: Fortran order and gaps read as row-major."""
    start, data = case
    psi = np.ascontiguousarray(start.basis_values(data.p))
    ref = _core.frequency_response(_core.ModelView(start.shape, start.theta, psi), data.z)
    for other in (fortran(psi), strided(psi)):
        assert not other.flags.c_contiguous
        view = _core.ModelView(start.shape, strided(start.theta), other)
        assert view.shape == start.shape and view.n_points == psi.shape[0]
        assert _core.frequency_response(view, data.z).tobytes() == ref.tobytes()


def test_core_problem_reads_strided_arrays_by_value(case):
    """The binding itself, fed strided 1-D views of what build_problem passes."""
    start, data = case
    problem = build_problem(start, data)
    psi = start.basis_values(data.p)
    args = (data.z, data.G.ravel(), data.sigma.ravel(), psi)
    views = [strided(np.ascontiguousarray(a)) for a in args]
    assert not any(v.flags.c_contiguous for v in views if v.size > 1)
    other = _core.Problem(_core.ModelView(start.shape, start.theta, views[3]), *views[:3])
    theta = strided(start.theta)
    assert other.vnls(theta) == problem.vnls(start.theta)
    assert other.residual(theta).tobytes() == problem.residual(start.theta).tobytes()
    free = strided(np.ones(theta.size, dtype=bool))
    a, b = other.gauss_newton(theta, free), problem.gauss_newton(start.theta, None)
    assert all(x.tobytes() == y.tobytes() for x, y in zip(a[1:], b[1:], strict=True))


@pytest.mark.parametrize("layout", LAYOUTS.values(), ids=LAYOUTS.keys())
def test_frf_in_other_layouts(case, layout):
    start, data = case
    f, p = data.freqs_hz, data.p
    expected = start.frf(f, p)
    assert start.frf(layout(f), layout(p)).tobytes() == expected.tobytes()
    assert relaid_model(start, layout).frf(f, p).tobytes() == expected.tobytes()


@pytest.mark.parametrize("layout", LAYOUTS.values(), ids=LAYOUTS.keys())
def test_frf_with_two_scheduling_parameters_in_other_layouts(rng, layout):
    basis = lpvid.Polynomial(2, domain=[(0, 1), (-1, 1)])
    k = len(basis) + 1
    model = lpvid.LpvModel(
        0.1 * rng.normal(size=(k, 2, 2)),
        rng.normal(size=(k, 2, 1)),
        rng.normal(size=(k, 1, 2)),
        basis=basis,
        Ts=None,
    )
    p = rng.uniform(0, 1, size=(5, 2))
    f = np.linspace(0.1, 5.0, 7)
    assert model.frf(f, layout(p)).tobytes() == model.frf(f, p).tobytes()


@pytest.mark.parametrize("layout", LAYOUTS.values(), ids=LAYOUTS.keys())
@pytest.mark.parametrize("Ts", [0.01, None])
def test_simulate_in_other_layouts(rng, layout, Ts):
    model = random_lpv(rng, n=3, r=2, l=2, nb=2, Ts=Ts)
    T = 200
    u = rng.normal(size=(T, 2))
    p = 0.5 + 0.4 * np.sin(np.linspace(0, 6, T))
    x0 = rng.normal(size=3)
    dt = None if Ts else 1e-2
    y, x = model.simulate(u, p, x0, dt=dt, return_states=True)
    y2, x2 = model.simulate(layout(u), layout(p), layout(x0), dt=dt, return_states=True)
    assert y2.tobytes() == y.tobytes() and x2.tobytes() == x.tobytes()
    y3 = relaid_model(model, layout).simulate(u, p, x0, dt=dt)
    assert y3.tobytes() == y.tobytes()


def test_core_fits_return_typed_read_only_outcomes(case):
    """fit_nls and l21_path give FitOutcome / PathOutcome objects, not dicts."""
    start, data = case
    problem = build_problem(start, data)
    out = _core.fit_nls(problem, start.theta, None, {"max_iter": 3})
    assert isinstance(out, _core.FitOutcome)
    assert out.theta.shape == start.theta.shape and out.vnls <= problem.vnls(start.theta)
    assert len(out.history) == 3 and set(out.history[0]) >= {"kind", "vnls", "accepted"}
    with pytest.raises(AttributeError):
        out.vnls = 0.0
    gammas = np.array([1e-2, 1e-3])
    sup = start.basis.sup_norms((0.0, 1.0))
    path = _core.l21_path(problem, start.theta, sup, gammas, None, {"max_outer": 2})
    assert isinstance(path, _core.PathOutcome) and len(path) == 2
    assert path.gammas == gammas.tolist()
    assert all(isinstance(f, _core.FitOutcome) for f in path.fits)


def test_core_fit_settings_name_a_bad_key(case):
    """The settings dicts: an unknown key, a value of the wrong type or out of range is named."""
    start, data = case
    problem = build_problem(start, data)
    sup = start.basis.sup_norms((0.0, 1.0))
    with pytest.raises(ValueError, match="unknown setting 'gamma'"):
        _core.fit_nls(problem, start.theta, None, {"gamma": 1.0})
    with pytest.raises(ValueError, match="xtol: has the wrong type"):
        _core.fit_nls(problem, start.theta, None, {"xtol": "small"})
    with pytest.raises(ValueError, match="lambda0"):
        _core.fit_nls(problem, start.theta, None, {"lambda0": -1.0})
    with pytest.raises(ValueError, match="weights: expected 'relative', 'scaled' or 'plain'"):
        _core.fit_l21(problem, start.theta, sup, None, {"weights": "other"})
    with pytest.raises(ValueError, match="max_outer: has the wrong type"):
        _core.l21_path(problem, start.theta, sup, np.array([1e-2]), None, {"max_outer": 1.5})
    with pytest.raises(TypeError, match="settings"):
        _core.cone_step(problem, start.theta, sup, None, [("gamma", 1.0)], 1.0)


@pytest.mark.parametrize("layout", LAYOUTS.values(), ids=LAYOUTS.keys())
def test_with_theta_gives_the_constructors_model_with_its_own_arrays(case, layout, rng):
    """``with_theta`` skips the constructor's checks; what it builds is the constructor's."""
    start, _ = case
    theta = start.theta + rng.normal(size=start.theta.size)
    given = layout(theta.copy())
    model = start.with_theta(given)
    # The constructor's model from the same values, the parts cut by hand.
    parts, at = [], 0
    for x in start.matrices().values():
        k, rows, cols = x.shape
        parts.append(theta[at : at + x.size].reshape(k, cols, rows).transpose(0, 2, 1))
        at += x.size
    ref = lpvid.LpvModel(*parts, basis=start.basis, Ts=start.Ts, p_range=start.p_range)
    assert model.theta.tobytes() == ref.theta.tobytes() == theta.tobytes()
    for mine, theirs in zip(model.matrices().values(), ref.matrices().values(), strict=True):
        assert mine.dtype == np.float64 and mine.flags.c_contiguous and not mine.flags.writeable
        assert mine.tobytes() == theirs.tobytes()
        assert not np.shares_memory(mine, given)
    assert model.p_range == ref.p_range and model.Ts == ref.Ts and model.basis is start.basis
    assert model.info == {} and model == ref
    given[:] = 0.0  # the caller's array is theirs to change
    assert model.theta.tobytes() == theta.tobytes()
    with pytest.raises(ValueError, match=r"^theta: contains NaN"):
        start.with_theta(np.where(np.arange(theta.size) == 3, np.nan, theta))
