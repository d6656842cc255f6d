"""Bad input gets a ValueError or TypeError that names the argument."""

import math
import warnings

import numpy as np
import pytest

import lpvid
from lpvid.testing import random_lpv


def good():
    return dict(
        p=np.array([0.0, 0.5, 1.0]),
        freqs_hz=np.array([1.0, 2.0, 3.0, 4.0]),
        G=np.ones((3, 4, 2, 1), complex),
        sigma=np.ones((3, 4, 2, 1)),
        Ts=0.01,
    )


def test_good_data_is_accepted():
    d = lpvid.FrfData(**good())
    assert (d.n_points, d.n_lines, d.n_outputs, d.n_inputs, d.n_residuals) == (3, 4, 2, 1, 24)


def test_p_rows_holds_one_row_per_point_for_one_parameter_or_several():
    one = lpvid.FrfData(**good())
    assert one.p_rows.shape == (3, 1)
    np.testing.assert_array_equal(one.p_rows[:, 0], one.p)
    two = lpvid.FrfData(**{**good(), "p": np.array([[0.0, 1.0], [0.5, 2.0], [1.0, 0.0]])})
    assert two.p_rows.shape == (3, 2)
    np.testing.assert_array_equal(two.p_rows, two.p)


@pytest.mark.parametrize(
    "change, exc, match",
    [
        (
            dict(G=np.ones((3, 5, 2, 1))),
            ValueError,
            r"^G: expected shape \(N, F, l, r\) with N=3 points and F=4 lines, got \(3, 5",
        ),
        (
            dict(G=np.ones((2, 4, 2, 1))),
            ValueError,
            r"^G: expected shape \(N, F, l, r\) with N=3 points and F=4 lines, got \(2, 4",
        ),
        (dict(G=np.ones((3, 4, 2))), ValueError, r"^G: expected a 2 or 4-dimensional array"),
        (dict(sigma=np.ones((3, 4, 1, 1))), ValueError, r"^sigma: expected the shape of G"),
        (
            dict(sigma=np.zeros((3, 4, 2, 1))),
            ValueError,
            r"^sigma: standard deviations must be > 0",
        ),
        (
            dict(sigma=-np.ones((3, 4, 2, 1))),
            ValueError,
            r"^sigma: standard deviations must be > 0",
        ),
        (dict(sigma=np.ones((3, 4, 2, 1)) * 1j), TypeError, r"^sigma: must be real"),
        (dict(p=np.array([0.0, 0.5, 0.5])), ValueError, r"^p: scheduling values must be distinct"),
        (dict(p=np.array([0.0, np.nan, 1.0])), ValueError, r"^p: contains NaN or Inf"),
        (dict(p=np.array([0.0, 1j, 1.0])), TypeError, r"^p: must be real"),
        (
            dict(freqs_hz=np.array([1.0, 2.0, 2.0, 4.0])),
            ValueError,
            r"^freqs_hz: frequencies must be strictly increasing",
        ),
        (
            dict(freqs_hz=np.array([1.0, 2.0, np.inf, 4.0])),
            ValueError,
            r"^freqs_hz: contains NaN or Inf",
        ),
        (
            dict(freqs_hz=np.array([1.0, 2.0, 3.0, 60.0])),
            ValueError,
            r"^freqs_hz: 60 Hz is above the Nyquist frequency",
        ),
        (dict(Ts=0.0), ValueError, r"^Ts: expected a finite number > 0"),
        (dict(Ts=-1.0), ValueError, r"^Ts: expected a finite number > 0"),
        (dict(Ts="1"), TypeError, r"^Ts: expected a real number"),
        (dict(G=np.full((3, 4, 2, 1), np.nan)), ValueError, r"^G: contains NaN or Inf"),
        (dict(G=np.array([["a"] * 4] * 3)), TypeError, r"^G: must be numeric"),
    ],
)
def test_bad_data_is_refused(change, exc, match):
    kwargs = good()
    kwargs.update(change)
    with pytest.raises(exc, match=match):
        lpvid.FrfData(**kwargs)


def test_a_nan_is_named_by_its_point_and_line():
    """The error says where the first NaN or Inf is, by point and line, and how many."""
    G = np.ones((3, 4, 2, 1), complex)
    G[2, 1, 1, 0] = np.nan
    G[2, 3, 0, 0] = np.inf
    with pytest.raises(
        ValueError,
        match=r"^G: contains NaN or Inf \(2 entries, the first at "
        r"point 2, line 1, output 1, input 0\)$",
    ):
        lpvid.FrfData(**{**good(), "G": G})
    G2 = np.ones((3, 4), complex)
    G2[0, 3] = np.inf
    with pytest.raises(
        ValueError, match=r"^G: contains NaN or Inf \(1 entry at point 0, line 3\)$"
    ):
        lpvid.FrfData(**{**good(), "G": G2, "sigma": None})
    sigma = np.ones((3, 4, 2, 1))
    sigma[1, 0, 0, 0] = np.nan
    with pytest.raises(
        ValueError, match=r"^sigma: contains NaN or Inf \(1 entry at point 1, line 0"
    ):
        lpvid.FrfData(**{**good(), "sigma": sigma})
    with pytest.raises(ValueError, match=r"^freqs_hz: contains NaN or Inf \(1 entry at line 2\)$"):
        lpvid.FrfData(**{**good(), "freqs_hz": np.array([1.0, 2.0, np.inf, 4.0])})


def test_a_nan_without_named_axes_is_given_by_its_index():
    """Arrays whose axes have no names (or more axes than names) give the index; a scalar not."""
    from lpvid._checks import real_array

    x = np.zeros((2, 3))
    x[1, 2] = np.nan
    with pytest.raises(ValueError, match=r"^x: contains NaN or Inf \(1 entry at index \(1, 2\)\)$"):
        real_array(x, "x")
    with pytest.raises(ValueError, match=r"at index \(1, 2\)\)$"):
        real_array(x, "x", axes=("point",))
    for axes in ((), ("point",)):
        with pytest.raises(ValueError, match=r"^t: contains NaN or Inf \(1 entry at its value\)$"):
            real_array(np.inf, "t", axes=axes)


def test_bad_model_shapes_are_refused():
    basis = lpvid.Polynomial(1, domain=(0, 1))
    A, B, C, D = np.zeros((2, 3, 3)), np.ones((2, 3, 1)), np.ones((2, 2, 3)), np.zeros((2, 2, 1))
    lpvid.LpvModel(A, B, C, D, basis)
    with pytest.raises(ValueError, match=r"^A: expected square matrices"):
        lpvid.LpvModel(np.zeros((2, 3, 2)), B, C, D, basis)
    with pytest.raises(ValueError, match=r"^A: expected 2 coefficient matrices"):
        lpvid.LpvModel(np.zeros((3, 3, 3)), B, C, D, basis)
    with pytest.raises(ValueError, match=r"^B: expected shape \(Nb\+1, 3, r\)"):
        lpvid.LpvModel(A, np.ones((2, 2, 1)), C, D, basis)
    with pytest.raises(ValueError, match=r"^C: expected shape \(Nb\+1, l, 3\)"):
        lpvid.LpvModel(A, B, np.ones((2, 2, 2)), D, basis)
    with pytest.raises(ValueError, match=r"^D: expected shape \(Nb\+1, 2, 1\)"):
        lpvid.LpvModel(A, B, C, np.zeros((2, 1, 1)), basis)
    with pytest.raises(ValueError, match=r"^A: contains NaN or Inf"):
        lpvid.LpvModel(A * np.nan, B, C, D, basis)
    with pytest.raises(TypeError, match=r"^A: must be real"):
        lpvid.LpvModel(A + 1j, B, C, D, basis)
    with pytest.raises(TypeError, match=r"^basis: expected an lpvid basis"):
        lpvid.LpvModel(A, B, C, D, basis=lambda p: p)
    with pytest.raises(ValueError, match=r"^Ts: expected a finite number > 0"):
        lpvid.LpvModel(A, B, C, D, basis, Ts=-0.1)


def test_model_and_data_must_agree(rng):
    model = random_lpv(rng, n=2, r=1, l=2, nb=1, Ts=0.01)
    data = lpvid.FrfData(**good())
    lpvid.vnls(model, data)
    with pytest.raises(ValueError, match=r"^data: sample time Ts=0.001 differs from the model's"):
        lpvid.vnls(model, lpvid.FrfData(**{**good(), "Ts": 0.001}))
    with pytest.raises(ValueError, match=r"^data: has 1 outputs x 1 inputs, the model 2 x 1"):
        lpvid.vnls(model, lpvid.FrfData(**{**good(), "G": np.ones((3, 4, 1, 1)), "sigma": None}))
    with pytest.raises(TypeError, match=r"^data: expected an FrfData"):
        lpvid.vnls(model, "data.npz")


def test_basis_not_finite_at_the_data_is_refused(rng):
    basis = lpvid.CustomBasis([lambda p: 1.0 / p], names=["1/p"])
    m = lpvid.LpvModel(
        np.zeros((2, 1, 1)), np.ones((2, 1, 1)), np.ones((2, 1, 1)), basis=basis, Ts=0.01
    )
    data = lpvid.FrfData(**{**good(), "G": np.ones((3, 4, 1, 1)), "sigma": None})
    with (
        np.errstate(divide="ignore"),
        pytest.raises(ValueError, match=r"^basis: a basis function is not finite"),
    ):
        lpvid.vnls(m, data)


def test_bad_fixed_masks_are_refused(rng):
    model = random_lpv(rng, n=2, r=1, l=1, nb=1)
    with pytest.raises(ValueError, match=r"^fixed: unknown matrix name"):
        lpvid.fixed_mask(model, {"E": True})
    with pytest.raises(ValueError, match=r"^fixed\['A'\]: coefficient indices must be in 0\.\.1"):
        lpvid.fixed_mask(model, {"A": [3]})
    with pytest.raises(
        ValueError, match=r"^fixed: expected a dict .* or a boolean array of length 18"
    ):
        lpvid.fixed_mask(model, np.ones(3, bool))
    with pytest.raises(ValueError, match=r"^fixed\['B'\]: expected a boolean array of shape"):
        lpvid.fixed_mask(model, {"B": np.ones((3, 3), bool)})


def test_bad_basis_arguments_are_refused():
    with pytest.raises(TypeError, match=r"^degree: expected an integer, got float"):
        lpvid.Polynomial(1.5)
    with pytest.raises(ValueError, match=r"^degree: expected an integer >= 0"):
        lpvid.Polynomial(-1)
    with pytest.raises(ValueError, match=r"^domain: every pair needs lo < hi"):
        lpvid.Polynomial(2, domain=(1.0, 0.0))
    with pytest.raises(ValueError, match=r"^domain: required"):
        lpvid.Legendre(2, domain=None)
    with pytest.raises(TypeError, match=r"^funcs: every entry must be callable"):
        lpvid.CustomBasis([1.0])
    with pytest.raises(ValueError, match=r"^p: the basis takes 2 scheduling parameter"):
        lpvid.Polynomial(2, domain=[(0, 1), (0, 1)])(np.zeros((3, 3)))


def test_no_panic_reaches_python_from_the_core():
    from lpvid import _core

    with pytest.raises(ValueError, match=r"^theta: expected 9 parameters"):
        _core.frequency_response(
            _core.ModelView((2, 1, 1, 0), np.zeros(3), np.zeros((1, 0))), np.ones(2, complex)
        )
    with pytest.raises(ValueError, match=r"^psi: expected 1 basis values"):
        _core.frequency_response(
            _core.ModelView((1, 1, 1, 1), np.zeros(8), np.zeros((1, 3))), np.ones(2, complex)
        )
    with pytest.raises(ValueError, match=r"^n: the model needs at least one state"):
        _core.frequency_response(
            _core.ModelView((0, 1, 1, 0), np.zeros(0), np.zeros((1, 0))), np.ones(2, complex)
        )
    view = _core.ModelView((1, 1, 1, 0), np.zeros(4), np.zeros((1, 0)))
    with pytest.raises(ValueError, match=r"^sigma: must be finite and > 0"):
        _core.Problem(view, np.ones(2, complex), np.ones(2, complex), np.zeros(2))
    with pytest.raises(ValueError, match=r"^G: expected 2 values"):
        _core.Problem(view, np.ones(2, complex), np.ones(3, complex), np.ones(2))
    prob = _core.Problem(view, np.ones(2, complex), np.ones(2, complex), np.ones(2))
    with pytest.raises(ValueError, match=r"^free: mask has 3 entries, theta has 4"):
        prob.gauss_newton(np.zeros(4), np.ones(3, bool))
    with pytest.raises(ValueError, match=r"^theta: contains NaN or Inf"):
        prob.vnls(np.full(4, np.nan))


def test_model_view_checks_its_parts_once():
    from lpvid import _core

    with pytest.raises(TypeError, match=r"^argument 'shape': expected a tuple \(n, r, l, nb\)"):
        _core.ModelView((1, 1, 1), np.zeros(4), np.zeros((1, 0)))
    with pytest.raises(TypeError, match=r"^argument 'shape': expected a tuple"):
        _core.ModelView((1, 1, -1, 0), np.zeros(4), np.zeros((1, 0)))
    with pytest.raises(ValueError, match=r"^theta: expected 8 parameters"):
        _core.ModelView((1, 1, 1, 1), np.zeros(4), np.zeros((2, 1)))
    with pytest.raises(
        ValueError, match=r"^psi: expected 4 basis values \(2 points x 2 functions\)"
    ):
        _core.ModelView((1, 1, 1, 2), np.zeros(12), np.zeros((2, 1)))
    with pytest.raises(TypeError):
        _core.ModelView((1, 1, 1, 1), np.zeros(8), np.zeros(2))  # basis values are (N, Nb)
    with pytest.raises(TypeError, match=r"^argument 'shape': expected a tuple"):
        _core.fit_memory((1, 1, 1), "lm")
    view = _core.ModelView((1, 1, 1, 1), np.full(8, np.nan), np.zeros((2, 1)))
    with pytest.raises(ValueError, match=r"^theta: contains NaN or Inf"):
        _core.frequency_response(view, np.ones(2, complex))


def test_errors_beyond_float64_come_back_as_inf_with_a_warning(rng):
    """vnls and residual say so when the weighted error overflows float64."""
    model = random_lpv(rng, n=2, r=1, l=1, nb=1)
    p, f = np.array([0.2, 0.8]), np.array([1.0, 5.0])
    G = model.frf(f, p)
    fine = lpvid.FrfData(p, f, G + 1.0, sigma=1.0, Ts=model.Ts)
    # errors of 1e10 / 1e-300 = 1e310 sigma: beyond float64
    huge = lpvid.FrfData(p, f, G + 1e10, sigma=1e-300, Ts=model.Ts)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert lpvid.vnls(model, fine) == pytest.approx(2 * 2)  # |1|^2 at 4 entries, sigma 1
        assert np.all(np.isfinite(lpvid.residual(model, fine)))
    with pytest.warns(RuntimeWarning, match=r"^vnls: V_NLS is not finite"):
        assert lpvid.vnls(model, huge) == np.inf
    with pytest.warns(RuntimeWarning, match=r"^residual: some entries are not finite"):
        assert not np.all(np.isfinite(lpvid.residual(model, huge)))


def test_same_sample_time_is_numpys_isclose_at_1e_12_and_none_for_continuous_time():
    from lpvid._checks import same_sample_time

    rng = np.random.default_rng(7)
    for _ in range(2000):
        a = float(10.0 ** rng.uniform(-6, 1))
        b = a * (1.0 + float(rng.choice([0.0, 1.0, -1.0])) * 10.0 ** rng.uniform(-14, -10))
        assert same_sample_time(a, b) == bool(np.isclose(a, b, rtol=1e-12, atol=0.0)), (a, b)
    assert same_sample_time(5e-4, 5e-4 * (1 + 5e-13))
    assert not same_sample_time(5e-4, 5e-4 * (1 + 2e-12))
    assert same_sample_time(None, None)
    assert not same_sample_time(None, 5e-4) and not same_sample_time(5e-4, None)
    assert same_sample_time(math.inf, math.inf) and not same_sample_time(math.nan, math.nan)
