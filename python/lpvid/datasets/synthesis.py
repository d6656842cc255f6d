"""Synthetic FRF measurements of physical models: sampling, noise, seeds."""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from lpvid._checks import positive_int
from lpvid.data.frf import FrfData, z_points
from lpvid.data.noise import circular_noise
from lpvid.model.frozen import lti_frf

Matrices = tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]


def _scalar(p: Any) -> float:
    if isinstance(p, bool) or not isinstance(p, numbers.Real):
        arr = np.asarray(p)
        if arr.size != 1 or np.iscomplexobj(arr) or not np.issubdtype(arr.dtype, np.number):
            raise TypeError(f"p: expected one real scheduling value, got {p!r}")
        p = arr.item()
    v = float(p)
    if not math.isfinite(v):
        raise ValueError(f"p: expected a finite scheduling value, got {p}")
    return v


def _frf(sys: Matrices, z: NDArray[np.complex128]) -> NDArray[np.complex128]:
    """``C (zI - A)^-1 B + D`` at every point of ``z``, shape (F, l, r)."""
    return lti_frf(*sys, z)


def _zoh(A: NDArray[np.float64], B: NDArray[np.float64], Ts: float) -> tuple[Any, Any]:
    """Zero-order-hold sampling: ``Ad = e^{A Ts}``, ``Bd = int_0^Ts e^{A s} ds B``."""
    import scipy.linalg

    n, r = B.shape
    big = np.zeros((n + r, n + r))
    big[:n, :n] = A
    big[:n, n:] = B
    e = scipy.linalg.expm(big * Ts)
    return e[:n, :n], e[:n, n:]


def _sampled(sys: Matrices, Ts: float | None) -> Matrices:
    """The model in the data's time domain.

    Continuous time: unchanged. Discrete time: zero-order-hold sampling, then
    every state multiplied by one number so that ``||B|| = ||C||`` (sampling
    scales B by about Ts).
    """
    A, B, C, D = sys
    if Ts is None:
        return A, B, C, D
    Ad, Bd = _zoh(A, B, Ts)
    return _balance_blocks((Ad, Bd, C, D), [slice(None)])


def _balance_blocks(sys: Matrices, blocks: list[slice]) -> Matrices:
    """Scale each block of states by one number so that its rows of B and columns of C match.

    A scalar per block commutes with a block-diagonal A, so the scaling can
    be applied before or after sampling alike.
    """
    A, B, C, D = (x.copy() for x in sys)
    for blk in blocks:
        nb, nc = np.linalg.norm(B[blk]), np.linalg.norm(C[:, blk])
        if nb > 0 and nc > 0:
            s = math.sqrt(nc / nb)
            B[blk] *= s
            C[:, blk] /= s
    return A, B, C, D


def _snr(snr_db: Any) -> float | None:
    if snr_db is None:
        return None
    if isinstance(snr_db, bool) or not isinstance(snr_db, numbers.Real):
        raise TypeError(f"snr_db: expected a number or None, got {type(snr_db).__name__}")
    v = float(snr_db)
    if math.isnan(v) or v == -math.inf:
        raise ValueError(f"snr_db: expected a finite number, inf or None, got {snr_db}")
    return None if v == math.inf else v


def _measure(
    physics: Callable[[float], Matrices],
    p: NDArray[np.float64],
    freqs_hz: NDArray[np.float64],
    Ts: float | None,
    snr_db: float | None,
    rng: np.random.Generator,
) -> FrfData:
    """True FRFs at ``p`` plus circular complex Gaussian noise of known sigma.

    ``sigma[q, :, i, j] = 10^(-snr_db / 20) * rms_k |G[q, k, i, j]|``, the
    same at every line; the noise lpvid's circular complex Gaussian
    (:func:`lpvid.data.noise.circular_noise`), ``E|noise|^2 = sigma^2``. Without noise
    (``snr_db`` None) sigma is the rms magnitude itself.
    """
    z = z_points(freqs_hz, Ts)
    G = np.stack([_frf(_sampled(physics(float(pq)), Ts), z) for pq in p])
    rms = np.sqrt(np.mean(np.abs(G) ** 2, axis=1, keepdims=True))
    if snr_db is None:
        return FrfData(p, freqs_hz, G, np.broadcast_to(rms, G.shape), Ts)
    sigma = np.broadcast_to(rms * 10.0 ** (-snr_db / 20.0), G.shape)
    return FrfData(p, freqs_hz, G + circular_noise(sigma, rng), sigma, Ts)


def _generators(seed: Any) -> tuple[np.random.Generator, np.random.Generator]:
    """Independent noise streams for identification and validation data."""
    s = positive_int(seed, "seed", minimum=0)
    ident, valid = np.random.SeedSequence(s).spawn(2)
    return np.random.default_rng(ident), np.random.default_rng(valid)
