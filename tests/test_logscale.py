"""Bases on the log scale: values, names, the model's own use of p, files, bad input, stability.

A model on ``Polynomial(d, domain=(0.1, 10), scale="log")`` is, coefficient
for coefficient, the model on ``Polynomial(d, domain=(-1, 1))`` fed
``log10(p)``: most tests compare the two. What select does with the scale
is in ``tests/test_select_logscale.py``.
"""

import json
import pickle
import warnings

import numpy as np
import pytest

import lpvid
import lpvid.testing
from lpvid._files import mat_variables
from lpvid.data.basis import basis_from_dict
from lpvid.stable.ranges import box_grid
from lpvid.trust.silent import range_grid

DOMAIN = (0.1, 10.0)
FREQS = np.array([0.5, 2.0, 8.0])


def twins(rng, Ts=None, n_params=1):
    """A model on the log scale and the same coefficients on a basis of log10(p)."""
    lin = lpvid.testing.random_lpv(rng, n=3, r=1, l=2, nb=2, Ts=Ts, domain=(-1.0, 1.0))
    log = lpvid.LpvModel(
        lin.A, lin.B, lin.C, lin.D, lpvid.Polynomial(2, domain=DOMAIN, scale="log"), Ts=Ts
    )
    return log, lin


@pytest.mark.parametrize("kind", [lpvid.Polynomial, lpvid.Legendre])
def test_the_log_scale_is_the_linear_basis_of_log10_p(kind, rng):
    p = 10 ** rng.uniform(-1, 1, 50)
    for degree in (1, 3):
        log = kind(degree, domain=DOMAIN, scale="log")
        lin = kind(degree, domain=(-1.0, 1.0))
        assert np.array_equal(log(p), lin(np.log10(p)))
        # one parameter on each scale: the log one mapped, the other as it is
        two = kind(degree, domain=[(0.0, 1.0), (2.0, 200.0)], scale=["linear", "log"])
        ref = kind(degree, domain=[(0.0, 1.0), (np.log10(2.0), np.log10(200.0))])
        q = np.stack([rng.uniform(0, 1, 50), 10 ** rng.uniform(np.log10(2), 2 + np.log10(2), 50)])
        np.testing.assert_allclose(two(q.T), ref(np.stack([q[0], np.log10(q[1])]).T), atol=1e-14)
    # the sup norms over a sub-range: s from -1 to 0 on [0.1, 1]
    np.testing.assert_allclose(kind(2, domain=DOMAIN, scale="log").sup_norms((0.1, 1.0)), [1, 1])


def test_names_repr_and_descriptions_say_the_scale():
    b = lpvid.Polynomial(2, domain=DOMAIN, scale="log")
    assert b.names == ["s(log p)", "s(log p)^2"] and b.scales == ("log",)
    assert repr(b) == str(b) == "Polynomial(2, domain=(0.1, 10.0), scale='log')"
    assert lpvid.Legendre(2, domain=DOMAIN, scale="log").names == ["P1(s(log p))", "P2(s(log p))"]
    assert lpvid.Polynomial(2, scale="log").names == ["log10(p)", "log10(p)^2"]
    two = lpvid.Polynomial(1, domain=[(0, 1), (1, 100)], scale=("linear", "log"))
    assert two.names == ["s1", "s2(log p2)"]
    assert repr(two).endswith("scale=('linear', 'log'))")
    # linear bases as before: no scale in the repr or the description
    lin = lpvid.Polynomial(2, domain=DOMAIN)
    assert repr(lin) == "Polynomial(2, domain=(0.1, 10.0))" and "scale" not in lin.to_dict()
    assert lin.scales == ("linear",) and lpvid.CustomBasis([np.sin]).scales == ("linear",)
    assert b != lin and b == lpvid.Polynomial(2, domain=DOMAIN, scale=["log"])
    assert b.to_dict()["scale"] == ["log"] and basis_from_dict(b.to_dict()) == b
    assert basis_from_dict(lin.to_dict()) == lin  # a description without "scale": linear
    assert pickle.loads(pickle.dumps(b)) == b


@pytest.mark.parametrize("Ts", [None, 0.01], ids=["continuous", "discrete"])
def test_the_model_takes_p_in_the_users_units(rng, Ts):
    log, lin = twins(rng, Ts)
    p = np.array([0.1, 0.37, 1.0, 4.2, 10.0])
    assert np.array_equal(log.frf(FREQS, p), lin.frf(FREQS, np.log10(p)))
    for a, b in zip(log.at(3.0), lin.at(np.log10(3.0)), strict=True):
        assert np.array_equal(a, b)
    assert log.p_range == [0.1, 10.0]
    T = 200
    u = rng.normal(size=(T, 1))
    traj = 10 ** np.sin(np.linspace(0, 6, T))
    dt = None if Ts is not None else 0.01
    assert np.array_equal(log.simulate(u, traj, dt=dt), lin.simulate(u, np.log10(traj), dt=dt))


def test_the_python_control_system_takes_p_in_the_users_units(rng):
    control = pytest.importorskip("control")
    log, lin = twins(rng, 0.01)
    T, u = 100, rng.normal(size=(1, 100))
    traj = 10 ** np.sin(np.linspace(0, 6, T))
    t = np.arange(T) * 0.01
    y_log = control.input_output_response(log.to_control_lpv(), t, np.vstack([u, traj])).outputs
    y_lin = control.input_output_response(
        lin.to_control_lpv(), t, np.vstack([u, np.log10(traj)])
    ).outputs
    np.testing.assert_allclose(y_log, y_lin, rtol=0, atol=1e-12 * np.max(np.abs(y_lin)))
    np.testing.assert_allclose(y_log.T, log.simulate(u.T, traj), atol=1e-10 * np.abs(y_lin).max())


@pytest.mark.parametrize("suffix", [".json", ".mat"])
def test_model_files_keep_the_scale(tmp_path, rng, suffix):
    log, lin = twins(rng, 0.01)
    back = lpvid.LpvModel.load(log.save(tmp_path / f"log{suffix}"))
    assert back.basis == log.basis and back.basis.scales == ("log",)
    assert np.array_equal(back.theta, log.theta) and back.p_range == log.p_range
    assert np.array_equal(back.frf(FREQS, [0.2, 5.0]), log.frf(FREQS, [0.2, 5.0]))
    # the file's version: 2 with a scale (an lpvid before it refuses the file), else 1
    log.save(tmp_path / "log.json")
    lpvid.LpvModel(lin.A, lin.B, lin.C, lin.D, lin.basis, Ts=0.01).save(tmp_path / "lin.json")
    doc, old = (json.loads((tmp_path / f"{x}.json").read_text()) for x in ("log", "lin"))
    assert doc["version"] == 2 and doc["content"]["basis"]["scale"] == ["log"]
    assert old["version"] == 1 and "scale" not in old["content"]["basis"]


def test_mat_files_hold_the_scale_as_a_variable(tmp_path, rng):
    from scipy.io import savemat

    log, _ = twins(rng, 0.01)
    raw = mat_variables(log.save(tmp_path / "log.mat"))
    assert [str(x.item()) for x in raw["basis_scale"].ravel()] == ["log"]
    assert "log10(p)" in str(raw["description"].item())
    # without lpvid's copy the variables alone give the model, its scale too
    del raw["lpvid_model"]
    savemat(tmp_path / "arrays.mat", raw)
    assert lpvid.LpvModel.load(tmp_path / "arrays.mat").basis == log.basis
    # without basis_scale (files from before the scale) the basis is linear: the
    # names of the log scale then do not match it, and without them it loads
    del raw["basis_scale"]
    savemat(tmp_path / "old.mat", raw)
    with pytest.raises(ValueError, match=r"^path: old\.mat: basis_names: .* and basis_scale"):
        lpvid.LpvModel.load(tmp_path / "old.mat")
    del raw["basis_names"]
    savemat(tmp_path / "old.mat", raw)
    assert lpvid.LpvModel.load(tmp_path / "old.mat").basis.scales == ("linear",)
    # an edited scale beside lpvid's copy is refused by name
    raw = mat_variables(log.save(tmp_path / "log.mat"))
    raw["basis_scale"] = np.array(["linear"], dtype=object)
    raw["basis_names"] = np.array(["s", "s^2"], dtype=object)  # as the linear basis names them
    savemat(tmp_path / "edited.mat", raw)
    with pytest.raises(ValueError, match=r"^path: edited\.mat: the MATLAB variable basis_scale "):
        lpvid.LpvModel.load(tmp_path / "edited.mat")
    raw["basis_scale"] = np.array(["ln"], dtype=object)
    savemat(tmp_path / "bad.mat", raw)
    with pytest.raises(ValueError, match=r"^path: bad\.mat: basis_scale: expected 'linear' or"):
        lpvid.LpvModel.load(tmp_path / "bad.mat")


def _log_model():
    return lpvid.LpvModel(
        np.array([[[-1.0]], [[0.5]], [[0.0]]]),
        np.ones((3, 1, 1)),
        np.ones((3, 1, 1)),
        basis=lpvid.Polynomial(2, domain=DOMAIN, scale="log"),
    )


def _data(p):
    return lpvid.FrfData(p, [1.0, 2.0], np.ones((len(p), 2, 1, 1), complex))


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: lpvid.Polynomial(2, domain=(0.0, 10.0), scale="log"), r"^domain: a log scale"),
        (lambda: lpvid.Legendre(2, domain=(-1.0, 10.0), scale="log"), r"^domain: a log scale"),
        (
            lambda: lpvid.Polynomial(1, domain=[(0, 1), (-1, 1)], scale=["linear", "log"]),
            r"^domain: .* of parameter 2 \(-1, 1\)",
        ),
        (lambda: lpvid.Polynomial(2, domain=DOMAIN, scale="ln"), r"^scale: expected 'linear'"),
        (lambda: lpvid.Polynomial(2, domain=DOMAIN, scale=["log"] * 2), r"^scale: 2 scales"),
        (lambda: lpvid.Polynomial(2, scale="log")([1.0, 0.0]), r"^p: .*above zero; got 0"),
        (lambda: _log_model().frf(FREQS, [0.5, -2.0]), r"^p: .*above zero; got -2"),
        (lambda: _log_model().simulate(np.ones(5), -np.ones(5), dt=0.1), r"^p: .*above zero"),
        (lambda: _log_model().basis.sup_norms((0.0, 1.0)), r"^p_range: .*above zero; got 0"),
        (
            lambda: lpvid.LpvModel(
                *_log_model().matrices().values(), _log_model().basis, p_range=(-1.0, 1.0)
            ),
            r"^p_range: .*above zero; got -1",
        ),
        (
            lambda: lpvid.Problem(_data([0.0, 1.0, 2.0, 3.0]), 1, _log_model().basis),
            r"^basis: takes the scheduling on the log scale.*the data reach 0 ",
        ),
        (
            lambda: lpvid.Problem(
                _data([1.0, 2.0, 3.0, 4.0]), 1, _log_model().basis, validation=_data([-1.0])
            ),
            r"^basis: .*the validation data reach -1 ",
        ),
        (
            lambda: lpvid.select(_data([0.0, 1.0, 2.0, 3.0]), [1], [_log_model().basis]),
            r"^bases: Polynomial\(2, .*scale='log'\) takes .*the data reach 0",
        ),
        (
            lambda: lpvid.select(_data([1.0, 2.0, 3.0, 4.0]), [1], [1], log_scale="yes"),
            r"^log_scale: expected 'auto', True or False",
        ),
    ],
)
def test_bad_input_names_the_argument(call, message):
    with pytest.raises(ValueError, match=message):
        call()


def test_a_linear_parameter_beside_a_log_one_may_reach_zero():
    b = lpvid.Polynomial(1, domain=[(-1, 1), (1, 100)], scale=["linear", "log"])
    np.testing.assert_allclose(b([[-1.0, 10.0]]), [[-1.0, 0.0]])
    with pytest.raises(ValueError, match=r"^p: .*got 0 \(parameter 2\)"):
        b([[0.5, 0.0]])


def test_stability_is_exact_on_the_log_scale():
    # A(p) = -1 + 1.5 s, s = log10(p) on [0.1, 10]: unstable for p > 10^(2/3).
    m = lpvid.LpvModel(
        np.array([[[-1.0]], [[1.5]]]),
        np.ones((2, 1, 1)),
        np.ones((2, 1, 1)),
        basis=lpvid.Polynomial(1, domain=DOMAIN, scale="log"),
    )
    rep = lpvid.stability(m)
    assert rep.method == "crossings" and not rep.stable
    np.testing.assert_allclose(rep.crossings, [10 ** (2 / 3)], rtol=1e-9)
    # stable below it, with the certificate of the polynomial in log10(p)
    ok = lpvid.stability(m, (0.1, 4.0))
    assert ok.stable and ok.method == "crossings" and ok.quadratic is True
    np.testing.assert_allclose(ok.margin, 1.0)
    # the same report as the model of log10(p), at the mapped values
    lin = lpvid.LpvModel(m.A, m.B, m.C, basis=lpvid.Polynomial(1, domain=(-1.0, 1.0)))
    twin = lpvid.stability(lin, (-1.0, np.log10(4.0)))
    assert twin.quadratic is True and twin.margin == pytest.approx(ok.margin)


def test_grids_over_the_range_are_even_on_the_scale():
    grid = box_grid([(0.1, 10.0), (0.0, 1.0)], 9, ("log", "linear"))
    np.testing.assert_allclose(np.unique(grid[:, 0]), [0.1, 1.0, 10.0])
    np.testing.assert_allclose(np.unique(grid[:, 1]), [0.0, 0.5, 1.0])
    assert box_grid([(0.1, 10.0)], 3).ravel().tolist() == [0.1, 5.05, 10.0]


def test_figures_draw_the_scheduling_on_the_basiss_scale(rng, plt):
    from lpvid import plots

    log, lin = twins(rng)
    p = np.geomspace(0.1, 10.0, 12)
    assert plots.magnitude_surface(log, FREQS, p).axes[0].get_yscale() == "log"
    assert plots.magnitude_surface(lin, FREQS, np.log10(p)).axes[0].get_yscale() == "linear"


def test_the_spread_and_the_plan_look_between_the_points_on_the_scale(rng):
    # few points on the log scale: the grids of the spread and of where to measure next
    # are even in log10(p), as a basis of log10(p) sees the range (a grid even in p would
    # put one value of 41 in [0.1, 0.35], where a third of the range's decades lie)
    true, _ = twins(rng)
    p = np.geomspace(0.1, 10.0, 4)
    data = lpvid.testing.noisy_data(true, p, np.geomspace(0.05, 20.0, 40), rng, 0.01)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lpvid.ConvergenceWarning)
        result = lpvid.identify(data, 3, true.basis)
    for grid in (range_grid(result.model, data)[:, 0], lpvid.suggest_points(result).grid):
        steps = np.diff(np.log10(grid))
        np.testing.assert_allclose(steps, steps[0], rtol=1e-9)
        assert grid[0] == 0.1 and grid[-1] == 10.0
    # the suggestion is one of the grid's values, none of them measured
    s = lpvid.suggest_points(result)
    assert np.isin(s.points, s.grid).all() and not np.isin(s.points, p).any()
