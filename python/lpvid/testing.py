"""Helpers to build random LPV models and noisy FRF data for tests and examples.

Import it as ``import lpvid.testing``. Numpy only: the frequency responses
here are computed by dense numpy solves, independently of lpvid's Rust core,
so that a test can compare the two.

Examples
--------
>>> import numpy as np
>>> import lpvid.testing
>>> rng = np.random.default_rng(0)
>>> model = lpvid.testing.random_lpv(rng, n=2, r=1, l=1, nb=1)
>>> data = lpvid.testing.noisy_data(model, [0.0, 0.5, 1.0], np.linspace(1, 40, 8), rng)
>>> data.G.shape
(3, 8, 1, 1)

"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lpvid._checks import positive_float, positive_int, real_array
from lpvid.basis import Polynomial
from lpvid.data import FrfData
from lpvid.model import LpvModel

__all__ = ["random_lpv", "direct_frf", "noisy_data"]


def _generator(rng: object) -> np.random.Generator:
    if not isinstance(rng, np.random.Generator):
        raise TypeError(
            f"rng: expected a numpy Generator (np.random.default_rng(seed)), "
            f"got {type(rng).__name__}"
        )
    return rng


def random_lpv(
    rng: np.random.Generator,
    n: int = 3,
    r: int = 2,
    l: int = 2,
    nb: int = 2,
    Ts: float | None = 0.01,
    domain: tuple[float, float] = (0.0, 1.0),
) -> LpvModel:
    """A random LPV model whose frozen models are stable on the domain.

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of the random numbers.
    n, r, l : int, optional
        Numbers of states, inputs and outputs.
    nb : int, optional
        Degree of the :class:`lpvid.Polynomial` basis on ``domain`` (the
        number of basis functions; 0 gives an LTI model).
    Ts : float or None, optional
        Sample time; None for continuous time.
    domain : (lo, hi), optional
        Scheduling range of the basis.

    Returns
    -------
    LpvModel
        ``A(0)`` is ``0.3 I`` (discrete time) or ``-1.5 I`` (continuous time)
        plus small random entries, so that every frozen model on the domain
        is stable; B, C, D are standard normal.

    """
    gen = _generator(rng)
    n = positive_int(n, "n")
    r = positive_int(r, "r")
    l = positive_int(l, "l")
    nb = positive_int(nb, "nb", minimum=0)
    basis = Polynomial(nb, domain=domain)
    A = 0.1 * gen.normal(size=(nb + 1, n, n)) / np.sqrt(n)
    if Ts is None:
        A[0] -= 1.5 * np.eye(n)
    else:
        A[0] += 0.3 * np.eye(n)
    B = gen.normal(size=(nb + 1, n, r))
    C = gen.normal(size=(nb + 1, l, n))
    D = gen.normal(size=(nb + 1, l, r))
    return LpvModel(A, B, C, D, basis, Ts=Ts)


def direct_frf(model: LpvModel, freqs_hz: ArrayLike, p: ArrayLike) -> NDArray[np.complex128]:
    """Frequency response by a dense numpy solve at every point and frequency.

    Independent of lpvid's core (:meth:`lpvid.LpvModel.frf`), which it can
    check.

    Parameters
    ----------
    model : LpvModel
    freqs_hz : array_like, shape (F,)
        Frequencies in Hz.
    p : array_like, shape (N,) or (N, Np)
        Scheduling values.

    Returns
    -------
    ndarray, shape (N, F, l, r), complex
        ``C(p) (zI - A(p))^-1 B(p) + D(p)`` with ``z = exp(j w Ts)`` or ``j w``.

    """
    if not isinstance(model, LpvModel):
        raise TypeError(f"model: expected an LpvModel, got {type(model).__name__}")
    freqs = real_array(freqs_hz, "freqs_hz", ndim=1)
    points = real_array(p, "p", ndim=(1, 2))
    out = np.zeros((len(points), freqs.size, model.n_outputs, model.n_inputs), complex)
    n = model.n_states
    for q, pq in enumerate(points):
        a, b, c, d = model.at(pq)
        for k, f in enumerate(freqs):
            w = 2 * np.pi * f
            z = 1j * w if model.Ts is None else np.exp(1j * w * model.Ts)
            out[q, k] = c @ np.linalg.solve(z * np.eye(n) - a, b) + d
    return out


def noisy_data(
    model: LpvModel,
    p: ArrayLike,
    freqs_hz: ArrayLike,
    rng: np.random.Generator,
    rel_noise: float = 0.05,
) -> FrfData:
    """FRF data of a model with complex Gaussian noise of random, known sigma.

    Parameters
    ----------
    model : LpvModel
    p : array_like, shape (N,) or (N, Np)
        Scheduling values of the measurements.
    freqs_hz : array_like, shape (F,)
        Frequencies in Hz.
    rng : numpy.random.Generator
        Source of the noise.
    rel_noise : float, optional
        Noise level: ``sigma = rel_noise (0.5 + U(0, 1)) (|G| + 0.1)`` per
        entry, and the noise is circular complex Gaussian with that standard
        deviation, so that V_NLS at the true model has mean ``M`` (the number
        of real residuals).

    Returns
    -------
    FrfData
        With ``sigma`` set and ``Ts`` that of the model.

    """
    gen = _generator(rng)
    level = positive_float(rel_noise, "rel_noise")
    G = direct_frf(model, freqs_hz, p)
    sigma = level * (0.5 + gen.random(G.shape)) * (np.abs(G) + 0.1)
    noise = sigma * (gen.normal(size=G.shape) + 1j * gen.normal(size=G.shape)) / np.sqrt(2)
    return FrfData(p, freqs_hz, G + noise, sigma, Ts=model.Ts)
