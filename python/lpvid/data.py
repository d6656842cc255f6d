"""Frequency-response data measured at frozen scheduling values."""

from __future__ import annotations

import io
import os
import zipfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lpvid._checks import complex_array, real_array, sample_time
from lpvid._files import write_atomic

__all__ = ["FrfData", "z_points"]


def z_points(freqs_hz: ArrayLike, Ts: float | None) -> NDArray[np.complex128]:
    """Evaluation points of a transfer function at the given frequencies.

    Parameters
    ----------
    freqs_hz : array_like
        Frequencies in Hz.
    Ts : float or None
        Sample time in seconds; None for continuous time.

    Returns
    -------
    ndarray of complex
        ``exp(j w Ts)`` in discrete time, ``j w`` in continuous time, with
        ``w = 2 pi f``.

    """
    w = 2.0 * np.pi * np.asarray(freqs_hz, dtype=np.float64)
    if Ts is None:
        return 1j * w
    return np.exp(1j * w * Ts)


class FrfData:
    """FRF measurements of a system at N frozen scheduling values.

    At scheduling point ``p[q]`` and frequency line ``f_k`` the measured
    frequency response ``G[q, k]`` is an ``l x r`` complex matrix (outputs by
    inputs) with standard deviation ``sigma[q, k]`` (same shape, real > 0).
    All points share the frequency lines.

    Parameters
    ----------
    p : array_like, shape (N,) or (N, Np)
        Scheduling values, one row per point; all distinct.
    freqs_hz : array_like, shape (F,)
        Frequency lines in Hz, strictly increasing, >= 0 (and at most the
        Nyquist frequency ``1 / (2 Ts)`` in discrete time).
    G : array_like, shape (N, F, l, r) or (N, F)
        Measured FRFs; a 2-D array is single-input single-output.
    sigma : array_like or float, optional
        Standard deviations with the shape of ``G`` (or one positive number
        for all). Default 1, which makes V_NLS a plain sum of squares.
    Ts : float, optional
        Sample time in seconds for discrete-time models; None (default) for
        continuous time.

    Raises
    ------
    ValueError, TypeError
        When shapes disagree, values are NaN or Inf, sigma is not positive,
        scheduling values repeat, or a real argument is complex.

    Examples
    --------
    >>> import numpy as np, lpvid
    >>> G = np.ones((3, 4, 1, 1), complex)
    >>> data = lpvid.FrfData([0.0, 0.5, 1.0], [1.0, 2.0, 3.0, 4.0], G)
    >>> data.n_points, data.n_lines, data.n_outputs, data.n_inputs
    (3, 4, 1, 1)

    """

    def __init__(
        self,
        p: ArrayLike,
        freqs_hz: ArrayLike,
        G: ArrayLike,
        sigma: ArrayLike | float | None = None,
        Ts: float | None = None,
    ) -> None:
        self.Ts = sample_time(Ts)
        p_arr = real_array(p, "p", ndim=(1, 2))
        if p_arr.shape[0] == 0:
            raise ValueError("p: needs at least one scheduling point")
        if p_arr.ndim == 2 and p_arr.shape[1] == 0:
            raise ValueError("p: needs at least one scheduling parameter per point")
        rows = p_arr.reshape(p_arr.shape[0], -1)
        if len(np.unique(rows, axis=0)) != rows.shape[0]:
            raise ValueError("p: scheduling values must be distinct (found a duplicate point)")
        freqs = real_array(freqs_hz, "freqs_hz", ndim=1)
        if freqs.size == 0:
            raise ValueError("freqs_hz: needs at least one frequency line")
        if np.any(freqs < 0):
            raise ValueError("freqs_hz: frequencies must be >= 0")
        if np.any(np.diff(freqs) <= 0):
            raise ValueError("freqs_hz: frequencies must be strictly increasing")
        if self.Ts is not None and freqs[-1] > 0.5 / self.Ts * (1 + 1e-12):
            raise ValueError(
                f"freqs_hz: {freqs[-1]:g} Hz is above the Nyquist frequency "
                f"{0.5 / self.Ts:g} Hz of Ts={self.Ts:g} s"
            )
        g = complex_array(G, "G", ndim=(2, 4))
        if g.ndim == 2:
            g = g[:, :, None, None]
        n_points, n_lines = p_arr.shape[0], freqs.size
        if g.shape[:2] != (n_points, n_lines):
            raise ValueError(
                f"G: expected shape (N, F, l, r) with N={n_points} points and F={n_lines} "
                f"lines, got {g.shape}"
            )
        if g.shape[2] == 0 or g.shape[3] == 0:
            raise ValueError(f"G: needs at least one output and one input, got shape {g.shape}")
        if sigma is None:
            s = np.ones(g.shape)
        else:
            s = real_array(sigma, "sigma")
            if s.ndim == 0:
                s = np.full(g.shape, float(s))
            elif s.ndim == 2 and g.shape[2:] == (1, 1):
                s = s[:, :, None, None]
            if s.shape != g.shape:
                raise ValueError(f"sigma: expected the shape of G {g.shape}, got {s.shape}")
            if np.any(s <= 0):
                raise ValueError("sigma: standard deviations must be > 0 everywhere")
        self.p: NDArray[np.float64] = p_arr
        self.freqs_hz: NDArray[np.float64] = freqs
        self.G: NDArray[np.complex128] = g
        self.sigma: NDArray[np.float64] = s
        for arr in (self.p, self.freqs_hz, self.G, self.sigma):
            arr.setflags(write=False)

    # ------------------------------------------------------------------ sizes
    @property
    def n_points(self) -> int:
        """Number of scheduling points N."""
        return int(self.G.shape[0])

    @property
    def n_lines(self) -> int:
        """Number of frequency lines F."""
        return int(self.G.shape[1])

    @property
    def n_outputs(self) -> int:
        """Number of outputs l."""
        return int(self.G.shape[2])

    @property
    def n_inputs(self) -> int:
        """Number of inputs r."""
        return int(self.G.shape[3])

    @property
    def n_params(self) -> int:
        """Number of scheduling parameters Np."""
        return 1 if self.p.ndim == 1 else int(self.p.shape[1])

    @property
    def n_residuals(self) -> int:
        """Number of complex residuals ``N F l r``: the noise floor of V_NLS."""
        return int(self.G.size)

    @property
    def z(self) -> NDArray[np.complex128]:
        """Evaluation points ``exp(j w Ts)`` (discrete) or ``j w`` (continuous)."""
        return z_points(self.freqs_hz, self.Ts)

    @property
    def p_range(self) -> tuple[Any, Any]:
        """Smallest and largest scheduling value (per parameter when Np > 1)."""
        if self.p.ndim == 1:
            return float(self.p.min()), float(self.p.max())
        return tuple(self.p.min(axis=0)), tuple(self.p.max(axis=0))

    def subset(self, points: Any) -> FrfData:
        """Return the data of some scheduling points.

        Parameters
        ----------
        points : int, slice, sequence of int or boolean mask
            Which points to keep.

        Returns
        -------
        FrfData

        """
        idx = np.arange(self.n_points)[points]
        idx = np.atleast_1d(idx)
        return FrfData(self.p[idx], self.freqs_hz, self.G[idx], self.sigma[idx], self.Ts)

    @classmethod
    def stack(cls, parts: Sequence[FrfData]) -> FrfData:
        """Combine the data of several scheduling points into one data set.

        Typically the single-point results of :func:`lpvid.estimate_frf`,
        one per frozen scheduling value.

        Parameters
        ----------
        parts : sequence of FrfData
            Data sets with the same frequency lines, sample time, outputs,
            inputs and number of scheduling parameters; their scheduling
            values must all differ.

        Returns
        -------
        FrfData
            The points of ``parts[0]``, then those of ``parts[1]``, and so on.

        Raises
        ------
        ValueError, TypeError
            When ``parts`` is empty, holds something other than FrfData, or
            the parts disagree (the message names the first offending part).

        Examples
        --------
        >>> import numpy as np, lpvid
        >>> a = lpvid.FrfData([0.0], [1.0, 2.0], np.ones((1, 2)))
        >>> b = lpvid.FrfData([1.0], [1.0, 2.0], np.ones((1, 2)))
        >>> lpvid.FrfData.stack([a, b]).p
        array([0., 1.])

        """
        if isinstance(parts, FrfData):
            raise TypeError("parts: expected a sequence of FrfData, got a single FrfData")
        items = list(parts)
        if not items:
            raise ValueError("parts: needs at least one FrfData")
        for i, d in enumerate(items):
            if not isinstance(d, FrfData):
                raise TypeError(f"parts[{i}]: expected FrfData, got {type(d).__name__}")
        first = items[0]
        for i, d in enumerate(items[1:], start=1):
            if d.Ts != first.Ts:
                raise ValueError(f"parts[{i}]: Ts={d.Ts} differs from Ts={first.Ts} of parts[0]")
            if d.freqs_hz.shape != first.freqs_hz.shape or not np.allclose(
                d.freqs_hz, first.freqs_hz, rtol=1e-12, atol=0.0
            ):
                raise ValueError(f"parts[{i}]: frequency lines differ from those of parts[0]")
            if d.G.shape[2:] != first.G.shape[2:]:
                raise ValueError(
                    f"parts[{i}]: {d.n_outputs} outputs x {d.n_inputs} inputs, but parts[0] "
                    f"has {first.n_outputs} x {first.n_inputs}"
                )
            if d.n_params != first.n_params:
                raise ValueError(
                    f"parts[{i}]: {d.n_params} scheduling parameters, but parts[0] has "
                    f"{first.n_params}"
                )
        if all(d.p.ndim == 1 for d in items):
            p = np.concatenate([d.p for d in items])
        else:
            p = np.concatenate([d.p.reshape(d.n_points, -1) for d in items])
        G = np.concatenate([d.G for d in items])
        sigma = np.concatenate([d.sigma for d in items])
        try:
            return cls(p, first.freqs_hz, G, sigma, first.Ts)
        except ValueError as exc:
            if str(exc).startswith("p:"):
                raise ValueError(f"parts: {exc}") from exc
            raise

    def __repr__(self) -> str:
        kind = "continuous time" if self.Ts is None else f"Ts={self.Ts:g} s"
        return (
            f"FrfData(N={self.n_points} points, F={self.n_lines} lines "
            f"{self.freqs_hz[0]:g}-{self.freqs_hz[-1]:g} Hz, {self.n_outputs} outputs x "
            f"{self.n_inputs} inputs, {kind})"
        )

    # ------------------------------------------------------------------- files
    def save(self, path: str | os.PathLike[str]) -> Path:
        """Save to ``.npz`` (numpy) or ``.mat`` (MATLAB), by the file's suffix.

        The file is written whole or not at all. In a ``.mat`` file the
        variables are ``p``, ``freqs_hz``, ``G`` (N x F x l x r), ``sigma`` and
        ``Ts`` (empty for continuous time).

        Parameters
        ----------
        path : str or path-like
            Target file, ending in ``.npz`` or ``.mat``.

        Returns
        -------
        pathlib.Path
            The path written.

        """
        suffix = Path(path).suffix.lower()
        fields = {"p": self.p, "freqs_hz": self.freqs_hz, "G": self.G, "sigma": self.sigma}
        ts = np.array([]) if self.Ts is None else np.array(self.Ts)
        if suffix == ".npz":

            def write(fh: Any) -> None:
                buf = io.BytesIO()
                np.savez(buf, Ts=ts, format=np.array("lpvid-frf"), **fields)
                fh.write(buf.getvalue())

        elif suffix == ".mat":
            from scipy.io import savemat

            def write(fh: Any) -> None:
                savemat(fh, {**fields, "Ts": ts}, do_compression=True)

        else:
            raise ValueError(f"path: expected a .npz or .mat file, got {Path(path).name!r}")
        return write_atomic(path, write)

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> FrfData:
        """Load data saved by :meth:`save`, or a ``.mat`` file with the same variables.

        Parameters
        ----------
        path : str or path-like
            A ``.npz`` or ``.mat`` file holding ``p``, ``freqs_hz``, ``G`` and
            optionally ``sigma`` and ``Ts``.

        Returns
        -------
        FrfData

        """
        p = Path(path)
        suffix = p.suffix.lower()
        if suffix == ".npz":
            try:
                # np.load leaves a file it opened open when it is no zip file
                with open(p, "rb") as fh, np.load(fh, allow_pickle=False) as f:
                    raw = {k: f[k] for k in f.files}
            except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
                raise ValueError(f"path: {p.name} is not a readable .npz file ({exc})") from exc
        elif suffix == ".mat":
            from scipy.io import loadmat
            from scipy.io.matlab import MatReadError

            try:
                raw = {k: v for k, v in loadmat(p).items() if not k.startswith("__")}
            except FileNotFoundError:
                raise
            except (OSError, ValueError, TypeError, NotImplementedError, MatReadError) as exc:
                raise ValueError(f"path: {p.name} is not a readable .mat file ({exc})") from exc
        else:
            raise ValueError(f"path: expected a .npz or .mat file, got {p.name!r}")
        missing = [k for k in ("p", "freqs_hz", "G") if k not in raw]
        if missing:
            raise ValueError(f"path: {p.name} lacks the variables {', '.join(missing)}")
        G = np.asarray(raw["G"])
        p_val = real_array(raw["p"], "p")
        freqs = real_array(raw["freqs_hz"], "freqs_hz").ravel()
        if suffix == ".mat":
            # MATLAB stores vectors as 1 x N matrices.
            if p_val.ndim == 2 and 1 in p_val.shape and G.shape[0] == p_val.size:
                p_val = p_val.ravel()
            if G.ndim == 4 and G.shape[0] == 1 and p_val.size == 1:
                p_val = p_val.ravel()
        ts = None if raw.get("Ts") is None else real_array(raw["Ts"], "Ts")
        if ts is not None and ts.size > 1:
            raise ValueError(f"Ts: expected one number (or none), got shape {ts.shape}")
        ts_val = None if ts is None or ts.size == 0 else float(ts.ravel()[0])
        sigma = raw.get("sigma")
        return cls(p_val, freqs, G, sigma, ts_val)
