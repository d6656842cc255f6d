"""Shared helpers for the lpvid test suite: random models and exact data."""

from __future__ import annotations

import signal

import numpy as np
import pytest

import lpvid


def random_lpv(
    rng: np.random.Generator,
    n: int = 3,
    r: int = 2,
    l: int = 2,
    nb: int = 2,
    Ts: float | None = 0.01,
    domain: tuple[float, float] = (0.0, 1.0),
) -> lpvid.LpvModel:
    """A random LPV model whose frozen models are stable on the domain."""
    basis = lpvid.Polynomial(nb, domain=domain)
    A = 0.1 * rng.normal(size=(nb + 1, n, n)) / np.sqrt(n)
    if Ts is None:
        A[0] -= 1.5 * np.eye(n)
    else:
        A[0] += 0.3 * np.eye(n)
    B = rng.normal(size=(nb + 1, n, r))
    C = rng.normal(size=(nb + 1, l, n))
    D = rng.normal(size=(nb + 1, l, r))
    return lpvid.LpvModel(A, B, C, D, basis, Ts=Ts)


def direct_frf(model: lpvid.LpvModel, freqs_hz: np.ndarray, p: np.ndarray) -> np.ndarray:
    """FRF by a dense numpy solve at every point and frequency (independent of the core)."""
    out = np.zeros((len(p), len(freqs_hz), model.n_outputs, model.n_inputs), complex)
    n = model.n_states
    for q, pq in enumerate(p):
        a, b, c, d = model.at(pq)
        for k, f in enumerate(freqs_hz):
            w = 2 * np.pi * f
            z = 1j * w if model.Ts is None else np.exp(1j * w * model.Ts)
            out[q, k] = c @ np.linalg.solve(z * np.eye(n) - a, b) + d
    return out


def noisy_data(
    model: lpvid.LpvModel,
    p: np.ndarray,
    freqs_hz: np.ndarray,
    rng: np.random.Generator,
    rel_noise: float = 0.05,
) -> lpvid.FrfData:
    """FRF data of a model with complex Gaussian noise and random known sigma."""
    G = direct_frf(model, freqs_hz, p)
    sigma = rel_noise * (0.5 + rng.random(G.shape)) * (np.abs(G) + 0.1)
    noise = sigma * (rng.normal(size=G.shape) + 1j * rng.normal(size=G.shape)) / np.sqrt(2)
    return lpvid.FrfData(p, freqs_hz, G + noise, sigma, Ts=model.Ts)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)


@pytest.fixture
def python_sigint():
    """Python's SIGINT handler (KeyboardInterrupt) for one test; the old handler restored.

    Python keeps SIGINT ignored when the process starts with it ignored (a
    background job, nohup, some CI runners); tests of Ctrl-C install it.
    """
    old = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old)
