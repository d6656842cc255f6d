"""Measured data: random-phase multisines and FRFs from periodic records.

The experiment of method.md section 5c (Pintelon and Schoukens): excite
the system at a frozen scheduling value with M random-phase multisine
realisations, record P periods of each in steady state, and estimate the
FRF at the excited lines together with its sample total variance (noise
plus stochastic nonlinear distortions) over the realisations.

lpvid's FRF convention is discrete time: at the excited DFT bin ``k`` of a
period of ``N`` samples, ``z = exp(j 2 pi k / N) = exp(j 2 pi f Ts)`` with
``f = k fs / N`` and ``Ts = 1 / fs``. For a discrete-time LTI system in
periodic steady state, the DFT of the output is exactly ``G(z) U`` at
every line.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lpvid._checks import generator, positive_float, positive_int, real_array
from lpvid._threads import single_blas
from lpvid.data.frf import FrfData

__all__ = ["Multisine", "multisine", "estimate_frf"]

_GRIDS = ("full", "odd")


@dataclass(frozen=True, eq=False)
class Multisine:
    """One period of a random-phase multisine (or of r orthogonal ones).

    Attributes
    ----------
    signal : ndarray
        Shape ``(period,)`` for one input. For ``r > 1`` inputs, shape
        ``(r, period, r)``: ``signal[e, :, i]`` drives input ``i`` during
        experiment ``e`` (see :func:`multisine`).
    freqs_hz : ndarray, shape (F,)
        The excited frequencies, ``lines * fs / period``.
    lines : ndarray of int, shape (F,)
        The excited DFT bins of one period.
    fs : float
        Sample rate in Hz.
    rms : float
        RMS value of every channel of every experiment.
    grid : str
        ``"full"`` or ``"odd"``.

    """

    signal: NDArray[np.float64]
    freqs_hz: NDArray[np.float64]
    lines: NDArray[np.int64]
    fs: float
    rms: float
    grid: str

    @property
    def period(self) -> int:
        """Samples per period."""
        return int(self.signal.shape[-2] if self.signal.ndim == 3 else self.signal.shape[0])

    @property
    def n_inputs(self) -> int:
        """Number of inputs r (and of experiments)."""
        return 1 if self.signal.ndim == 1 else int(self.signal.shape[2])

    @property
    def Ts(self) -> float:
        """Sample time ``1 / fs`` in seconds."""
        return 1.0 / self.fs

    def __repr__(self) -> str:
        return (
            f"Multisine(period={self.period}, fs={self.fs:g} Hz, {self.lines.size} lines "
            f"{self.freqs_hz[0]:g}-{self.freqs_hz[-1]:g} Hz, {self.grid} grid, "
            f"rms={self.rms:g}, {self.n_inputs} input(s))"
        )

    def periodic(self, n_periods: int) -> NDArray[np.float64]:
        """The signal repeated over ``n_periods`` periods along the time axis.

        Parameters
        ----------
        n_periods : int
            Number of periods (>= 1).

        Returns
        -------
        ndarray
            Shape ``(n_periods * period,)`` or ``(r, n_periods * period, r)``.

        """
        k = positive_int(n_periods, "n_periods")
        if self.signal.ndim == 1:
            return np.tile(self.signal, k)
        return np.tile(self.signal, (1, k, 1))


def _band(band_hz: Any, fs: float) -> tuple[float, float]:
    band = real_array(band_hz, "band_hz", ndim=1)
    if band.size != 2:
        raise ValueError(f"band_hz: expected (f_lo, f_hi) in Hz, got {band_hz!r}")
    lo, hi = float(band[0]), float(band[1])
    if lo > hi:
        raise ValueError(f"band_hz: expected f_lo <= f_hi, got ({lo:g}, {hi:g})")
    if lo < 0 or hi > fs / 2:
        raise ValueError(
            f"band_hz: ({lo:g}, {hi:g}) Hz lies outside the Nyquist range "
            f"[0, {fs / 2:g}] Hz of fs={fs:g} Hz"
        )
    return lo, hi


def multisine(
    period: int,
    fs: float,
    band_hz: ArrayLike,
    rms: float = 1.0,
    grid: str = "full",
    seed: int | Sequence[int] | np.random.Generator | None = None,
    n_inputs: int = 1,
) -> Multisine:
    """One period of a random-phase multisine with a flat amplitude spectrum.

    Every DFT line ``k`` of the period with ``f_lo <= k fs / period <=
    f_hi`` (``0 < k < period / 2``; only odd ``k`` on the odd grid) gets the
    same amplitude and an independent phase uniform in ``[0, 2 pi)``; the
    signal is scaled to the exact RMS asked for.

    Several inputs (``n_inputs = r > 1``) get orthogonal multisines
    (Pintelon and Schoukens): ``r`` experiments, where input ``i`` of
    experiment ``e`` carries its own random-phase multisine times
    ``T[i, e] = exp(-2 pi j i e / r)`` at every line (the phase pattern of a
    DFT matrix; for ``r = 2`` a Hadamard matrix of signs). At every line
    the ``r x r`` input spectra of the ``r`` experiments are then a diagonal
    times a unitary matrix, as well conditioned as possible, which
    :func:`estimate_frf` inverts.

    Parameters
    ----------
    period : int
        Samples per period (>= 3).
    fs : float
        Sample rate in Hz.
    band_hz : (f_lo, f_hi)
        Excited band in Hz, inside ``[0, fs / 2]``. DC and the Nyquist line
        are never excited.
    rms : float, optional
        RMS value of each channel (default 1).
    grid : {"full", "odd"}, optional
        Excite every line of the band, or only the odd ones (leaving the
        even lines to reveal even nonlinear distortions).
    seed : int, sequence of int or numpy.random.Generator, optional
        Source of the random phases (anything ``numpy.random.default_rng``
        takes); the same seed gives the same signal, e.g. ``seed=(point,
        realisation)``.
    n_inputs : int, optional
        Number of inputs r (default 1).

    Returns
    -------
    Multisine
        ``.signal`` of shape ``(period,)``, or ``(r, period, r)`` for
        ``r > 1`` (``signal[e, :, i]``: input ``i`` in experiment ``e``),
        ``.freqs_hz``, ``.lines``.

    Raises
    ------
    ValueError
        When the band lies outside the Nyquist range or holds no line of
        the DFT grid (resolution ``fs / period``), or ``grid`` is unknown.

    Examples
    --------
    >>> import numpy as np, lpvid
    >>> ms = lpvid.multisine(1024, 1000.0, (10.0, 100.0), rms=0.5, seed=1)
    >>> ms.signal.shape, round(float(np.sqrt(np.mean(ms.signal**2))), 12)
    ((1024,), 0.5)

    """
    n_per = positive_int(period, "period", minimum=3)
    f_s = positive_float(fs, "fs")
    lo, hi = _band(band_hz, f_s)
    level = positive_float(rms, "rms")
    if grid not in _GRIDS:
        raise ValueError(f"grid: expected one of {_GRIDS}, got {grid!r}")
    r = positive_int(n_inputs, "n_inputs")
    res = f_s / n_per
    tol = 1e-9
    first = max(1, int(np.ceil(lo / res - tol)))
    last = min((n_per - 1) // 2, int(np.floor(hi / res + tol)))
    lines = np.arange(first, last + 1, dtype=np.int64)
    if grid == "odd":
        lines = lines[lines % 2 == 1]
    if lines.size == 0:
        raise ValueError(
            f"band_hz: ({lo:g}, {hi:g}) Hz holds no excitable line of the {grid} grid "
            f"(resolution fs/period = {res:g} Hz, DC and Nyquist excluded)"
        )
    rng = generator(seed)
    phases = rng.uniform(0.0, 2.0 * np.pi, size=(r, lines.size))
    idx = np.arange(r)
    pattern = np.exp(-2j * np.pi * np.outer(idx, idx) / r)  # T[i, e]
    spectrum = np.zeros((r, r, n_per // 2 + 1), complex)  # [e, i, k]
    spectrum[:, :, lines] = np.exp(1j * phases)[None, :, :] * pattern.T[:, :, None]
    signal = np.fft.irfft(spectrum, n=n_per, axis=-1)  # (e, i, t)
    signal *= level / np.sqrt(np.mean(signal**2, axis=-1, keepdims=True))
    signal = signal.transpose(0, 2, 1)  # (e, t, i)
    out = signal[0, :, 0].copy() if r == 1 else np.ascontiguousarray(signal)
    freqs = lines * res
    for arr in (out, freqs, lines):
        arr.setflags(write=False)
    return Multisine(out, freqs, lines, f_s, level, grid)


def _records(value: Any, name: str) -> NDArray[np.float64]:
    arr = real_array(value, name)
    if arr.ndim == 2:
        arr = arr[:, :, None]
    if arr.ndim != 3:
        hint = f"; for a single record use {name}[None]" if arr.ndim == 1 else ""
        raise ValueError(
            f"{name}: expected shape (R, T) or (R, T, channels): R records of T samples, "
            f"got {arr.shape}{hint}"
        )
    if 0 in arr.shape:
        raise ValueError(f"{name}: needs at least one record, sample and channel, got {arr.shape}")
    return arr


def _lines(freqs_hz: Any, period: int, fs: float) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    freqs = real_array(freqs_hz, "freqs_hz", ndim=(0, 1)).ravel()
    if freqs.size == 0:
        raise ValueError("freqs_hz: needs at least one frequency line")
    k = freqs * period / fs
    lines = np.rint(k).astype(np.int64)
    off = np.abs(k - lines) > 1e-6 * np.maximum(1.0, np.abs(k))
    if np.any(off):
        f = freqs[np.argmax(off)]
        raise ValueError(
            f"freqs_hz: {f:g} Hz is not on the DFT grid of the period "
            f"(multiples of fs/period = {fs / period:g} Hz)"
        )
    bad = (lines <= 0) | (2 * lines >= period)
    if np.any(bad):
        f = freqs[np.argmax(bad)]
        raise ValueError(
            f"freqs_hz: {f:g} Hz is outside the open Nyquist range (0, {fs / 2:g}) Hz "
            "(DC and the Nyquist line carry no FRF)"
        )
    if np.any(np.diff(lines) <= 0):
        raise ValueError("freqs_hz: frequencies must be strictly increasing")
    return freqs, lines


@single_blas
def estimate_frf(
    u: ArrayLike,
    y: ArrayLike,
    period: int,
    fs: float,
    freqs_hz: ArrayLike,
    *,
    p: ArrayLike,
    drop_periods: int = 0,
) -> FrfData:
    r"""FRF and its standard deviation from periodic multisine records.

    The records come from one frozen scheduling value ``p``. Each record is
    cut into periods; the first ``drop_periods`` periods of every record
    (transients) are dropped, the DFT of the others taken at the excited
    lines and averaged over periods. Per realisation ``m`` this gives
    ``G^m = Y^m (U^m)^{-1}``, and over the ``M`` realisations::

        G     = mean_m G^m
        sigma = sqrt( sum_m |G^m - G|^2 / (M (M - 1)) )

    the standard deviation of the mean ``G``, holding noise and stochastic
    nonlinear distortions (method.md section 5c). With a single
    realisation (``M = 1``) ``sigma`` comes from the period-to-period
    scatter instead and holds the noise only.

    Several inputs (``r > 1``): the ``R`` records form ``M = R / r``
    realisations of ``r`` experiments each, in the order
    ``record = m * r + e`` (experiment ``e`` of realisation ``m``); the
    inputs of the ``r`` experiments must be linearly independent at every
    line, as with :func:`multisine` and ``n_inputs=r``.

    Parameters
    ----------
    u : array_like, shape (R, T) or (R, T, r)
        Input records: R records of T samples, T a whole number of periods.
    y : array_like, shape (R, T) or (R, T, l)
        Output records, sampled with ``u``.
    period : int
        Samples per period.
    fs : float
        Sample rate in Hz.
    freqs_hz : array_like, shape (F,)
        The excited lines (e.g. ``Multisine.freqs_hz``); each on the grid
        ``k fs / period`` with ``0 < k < period / 2``.
    p : float or array_like, shape (Np,)
        The scheduling value of the experiment.
    drop_periods : int, optional
        Periods at the start of every record to discard (default 0).

    Returns
    -------
    FrfData
        One point: ``p``, ``freqs_hz``, ``G`` of shape ``(1, F, l, r)``,
        ``sigma`` (floored at the round-off level ``eps * max|G|`` so that
        noise-free records still give valid data) and ``Ts = 1 / fs``.
        Combine points with :meth:`FrfData.stack`.

    Raises
    ------
    ValueError
        On records that are not whole periods, mismatched records, lines off
        the grid or outside the Nyquist range, inputs without energy or not
        independent at a line, too little data for a variance, NaN or Inf.

    """
    n_per = positive_int(period, "period")
    f_s = positive_float(fs, "fs")
    drop = positive_int(drop_periods, "drop_periods", minimum=0)
    uu = _records(u, "u")
    yy = _records(y, "y")
    n_rec, t_len, r = uu.shape
    if yy.shape[:2] != (n_rec, t_len):
        raise ValueError(
            f"y: expected R={n_rec} records of T={t_len} samples like u, "
            f"got {yy.shape[0]} of {yy.shape[1]}"
        )
    l = yy.shape[2]
    if t_len % n_per:
        raise ValueError(
            f"u: T={t_len} samples is not a whole number of periods of {n_per} samples"
        )
    n_periods = t_len // n_per
    if drop >= n_periods:
        raise ValueError(f"drop_periods: {drop} leaves no period of the {n_periods} in each record")
    if n_rec % r:
        raise ValueError(
            f"u: R={n_rec} records do not make whole realisations of r={r} experiments "
            "(one experiment per input)"
        )
    n_real = n_rec // r
    kept = n_periods - drop
    if n_real < 2 and kept < 2:
        raise ValueError(
            "u: one realisation of one period gives no variance: record more "
            "realisations, or more periods (drop_periods)"
        )
    freqs, lines = _lines(freqs_hz, n_per, f_s)
    p_arr = real_array(p, "p", ndim=(0, 1))
    # DFT of every kept period at the excited lines: (R, P, F, channels).
    U = np.fft.rfft(uu.reshape(n_rec, n_periods, n_per, r)[:, drop:], axis=2)[:, :, lines]
    Y = np.fft.rfft(yy.reshape(n_rec, n_periods, n_per, l)[:, drop:], axis=2)[:, :, lines]
    # Mean over periods, grouped as (M, e, F, channels), then per line the
    # e x r matrix of input spectra (rows: experiments).
    Um = U.mean(axis=1).reshape(n_real, r, lines.size, r).transpose(0, 2, 1, 3)
    Ym = Y.mean(axis=1).reshape(n_real, r, lines.size, l).transpose(0, 2, 1, 3)
    kept_u = uu.reshape(n_real, r, n_periods, n_per * r)[:, :, drop:]
    energy = np.sqrt(n_per * np.sum(kept_u**2, axis=(1, 2, 3)) / kept)
    _check_inputs(Um, energy, freqs)
    # G^m (l x r) from G^m U = Y, i.e. Um G^T = Ym.
    Gm = np.linalg.solve(Um, Ym).swapaxes(-1, -2)  # (M, F, l, r)
    G = Gm.mean(axis=0)
    if n_real >= 2:
        var = np.sum(np.abs(Gm - G) ** 2, axis=0) / (n_real * (n_real - 1))
    else:
        # Period-to-period scatter of Y - G U per experiment e and output j,
        # propagated through U^-1: var G_jc = sum_e var(Ybar_je) |U^-1_ec|^2.
        # With M = 1 the records are the r experiments: U (e, P, F, i), Y (e, P, F, j).
        resid = Y - np.einsum("fji,epfi->epfj", G, U)
        var_y = np.sum(np.abs(resid) ** 2, axis=1) / ((kept - 1) * kept)  # (e, F, j)
        inv = np.linalg.inv(Um[0])  # (F, i, e): (U^-1)_{e c} = inv[c, e]
        var = np.einsum("efj,fce->fjc", var_y, np.abs(inv) ** 2)
    scale = float(np.max(np.abs(G)))
    floor = np.finfo(float).eps * scale if scale > 0 else np.finfo(float).tiny
    sigma = np.maximum(np.sqrt(var), floor)
    p_point = p_arr.reshape(1) if p_arr.ndim == 0 else p_arr.reshape(1, -1)
    return FrfData(p_point, freqs, G[None], sigma[None], Ts=1.0 / f_s)


def _check_inputs(
    Um: NDArray[np.complex128], energy: NDArray[np.float64], freqs: NDArray[np.float64]
) -> None:
    """Every realisation must excite every line, with independent inputs.

    ``Um`` holds the (M, F, e, i) period-mean input spectra and ``energy``
    the scale ``sqrt(period * sum u^2)`` of one period of each realisation
    (all experiments and inputs): a line carrying a fair share of the power
    has a spectrum far above ``1e-8`` times it, an unexcited line only
    round-off.
    """
    r = Um.shape[-1]
    sv = np.linalg.svd(Um, compute_uv=False)  # (M, F, r), descending
    floor = 1e-8 * energy[:, None]
    empty = ~(sv[..., 0] > floor)
    if np.any(empty):
        m, k = np.argwhere(empty)[0]
        raise ValueError(
            f"u: realisation {m} has no energy at {freqs[k]:g} Hz; freqs_hz must "
            "list lines the input excites"
        )
    if r == 1:
        return
    bad = ~(sv[..., -1] > 1e-10 * sv[..., 0]) | ~(sv[..., -1] > floor)
    if np.any(bad):
        m, k = np.argwhere(bad)[0]
        raise ValueError(
            f"u: the inputs of the {r} experiments of realisation {m} are (nearly) "
            f"linearly dependent at {freqs[k]:g} Hz; use orthogonal multisines "
            f"(lpvid.multisine(..., n_inputs={r}))"
        )
