"""Bad input gets a ValueError or TypeError that names the argument."""

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


@pytest.mark.parametrize(
    "change, exc, name",
    [
        (dict(G=np.ones((3, 5, 2, 1))), ValueError, "G"),
        (dict(G=np.ones((2, 4, 2, 1))), ValueError, "G"),
        (dict(G=np.ones((3, 4, 2))), ValueError, "G"),
        (dict(sigma=np.ones((3, 4, 1, 1))), ValueError, "sigma"),
        (dict(sigma=np.zeros((3, 4, 2, 1))), ValueError, "sigma"),
        (dict(sigma=-np.ones((3, 4, 2, 1))), ValueError, "sigma"),
        (dict(sigma=np.ones((3, 4, 2, 1)) * 1j), TypeError, "sigma"),
        (dict(p=np.array([0.0, 0.5, 0.5])), ValueError, "p"),
        (dict(p=np.array([0.0, np.nan, 1.0])), ValueError, "p"),
        (dict(p=np.array([0.0, 1j, 1.0])), TypeError, "p"),
        (dict(freqs_hz=np.array([1.0, 2.0, 2.0, 4.0])), ValueError, "freqs_hz"),
        (dict(freqs_hz=np.array([1.0, 2.0, np.inf, 4.0])), ValueError, "freqs_hz"),
        (dict(freqs_hz=np.array([1.0, 2.0, 3.0, 60.0])), ValueError, "Nyquist"),
        (dict(Ts=0.0), ValueError, "Ts"),
        (dict(Ts=-1.0), ValueError, "Ts"),
        (dict(Ts="1"), TypeError, "Ts"),
        (dict(G=np.full((3, 4, 2, 1), np.nan)), ValueError, "G"),
        (dict(G=np.array([["a"] * 4] * 3)), TypeError, "G"),
    ],
)
def test_bad_data_is_refused(change, exc, name):
    kwargs = good()
    kwargs.update(change)
    with pytest.raises(exc, match=name):
        lpvid.FrfData(**kwargs)


def test_bad_model_shapes_are_refused():
    basis = lpvid.Polynomial(1, domain=(0, 1))
    A, B, C, D = np.zeros((2, 3, 3)), np.ones((2, 3, 1)), np.ones((2, 2, 3)), np.zeros((2, 2, 1))
    lpvid.LpvModel(A, B, C, D, basis)
    with pytest.raises(ValueError, match="A"):
        lpvid.LpvModel(np.zeros((2, 3, 2)), B, C, D, basis)
    with pytest.raises(ValueError, match="A"):
        lpvid.LpvModel(np.zeros((3, 3, 3)), B, C, D, basis)
    with pytest.raises(ValueError, match="B"):
        lpvid.LpvModel(A, np.ones((2, 2, 1)), C, D, basis)
    with pytest.raises(ValueError, match="C"):
        lpvid.LpvModel(A, B, np.ones((2, 2, 2)), D, basis)
    with pytest.raises(ValueError, match="D"):
        lpvid.LpvModel(A, B, C, np.zeros((2, 1, 1)), basis)
    with pytest.raises(ValueError, match="A"):
        lpvid.LpvModel(A * np.nan, B, C, D, basis)
    with pytest.raises(TypeError, match="A"):
        lpvid.LpvModel(A + 1j, B, C, D, basis)
    with pytest.raises(TypeError, match="basis"):
        lpvid.LpvModel(A, B, C, D, basis=lambda p: p)
    with pytest.raises(ValueError, match="Ts"):
        lpvid.LpvModel(A, B, C, D, basis, Ts=-0.1)


def test_model_and_data_must_agree(rng):
    model = random_lpv(rng, n=2, r=1, l=2, nb=1, Ts=0.01)
    data = lpvid.FrfData(**good())
    lpvid.vnls(model, data)
    with pytest.raises(ValueError, match="sample time"):
        lpvid.vnls(model, lpvid.FrfData(**{**good(), "Ts": 0.001}))
    with pytest.raises(ValueError, match="outputs"):
        lpvid.vnls(model, lpvid.FrfData(**{**good(), "G": np.ones((3, 4, 1, 1)), "sigma": None}))
    with pytest.raises(TypeError, match="data"):
        lpvid.vnls(model, "data.npz")


def test_basis_not_finite_at_the_data_is_refused(rng):
    basis = lpvid.CustomBasis([lambda p: 1.0 / p], names=["1/p"])
    m = lpvid.LpvModel(
        np.zeros((2, 1, 1)), np.ones((2, 1, 1)), np.ones((2, 1, 1)), basis=basis, Ts=0.01
    )
    data = lpvid.FrfData(**{**good(), "G": np.ones((3, 4, 1, 1)), "sigma": None})
    with np.errstate(divide="ignore"), pytest.raises(ValueError, match="basis"):
        lpvid.vnls(m, data)


def test_bad_fixed_masks_are_refused(rng):
    model = random_lpv(rng, n=2, r=1, l=1, nb=1)
    with pytest.raises(ValueError, match="fixed"):
        lpvid.fixed_mask(model, {"E": True})
    with pytest.raises(ValueError, match="fixed"):
        lpvid.fixed_mask(model, {"A": [3]})
    with pytest.raises(ValueError, match="fixed"):
        lpvid.fixed_mask(model, np.ones(3, bool))
    with pytest.raises(ValueError, match="fixed"):
        lpvid.fixed_mask(model, {"B": np.ones((3, 3), bool)})


def test_bad_basis_arguments_are_refused():
    with pytest.raises(TypeError, match="degree"):
        lpvid.Polynomial(1.5)
    with pytest.raises(ValueError, match="degree"):
        lpvid.Polynomial(-1)
    with pytest.raises(ValueError, match="domain"):
        lpvid.Polynomial(2, domain=(1.0, 0.0))
    with pytest.raises(ValueError, match="domain"):
        lpvid.Legendre(2, domain=None)
    with pytest.raises(TypeError, match="funcs"):
        lpvid.CustomBasis([1.0])
    with pytest.raises(ValueError, match="p"):
        lpvid.Polynomial(2, domain=[(0, 1), (0, 1)])(np.zeros((3, 3)))


def test_no_panic_reaches_python_from_the_core():
    from lpvid import _core

    with pytest.raises(ValueError, match="theta"):
        _core.frequency_response(2, 1, 1, 0, np.zeros(3), np.zeros(0), 1, np.ones(2, complex))
    with pytest.raises(ValueError, match="psi"):
        _core.frequency_response(1, 1, 1, 1, np.zeros(8), np.zeros(3), 1, np.ones(2, complex))
    with pytest.raises(ValueError, match="n"):
        _core.frequency_response(0, 1, 1, 0, np.zeros(0), np.zeros(0), 1, np.ones(2, complex))
    with pytest.raises(ValueError, match="sigma"):
        _core.Problem(
            1, 1, 1, 0, 1, np.ones(2, complex), np.ones(2, complex), np.zeros(2), np.zeros(0)
        )
    with pytest.raises(ValueError, match="G"):
        _core.Problem(
            1, 1, 1, 0, 1, np.ones(2, complex), np.ones(3, complex), np.ones(2), np.zeros(0)
        )
    prob = _core.Problem(
        1, 1, 1, 0, 1, np.ones(2, complex), np.ones(2, complex), np.ones(2), np.zeros(0)
    )
    with pytest.raises(ValueError, match="free"):
        prob.gauss_newton(np.zeros(4), np.ones(3, bool))
    with pytest.raises(ValueError, match="theta"):
        prob.vnls(np.full(4, np.nan))
