"""Frequency-response data measured at frozen scheduling values."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lpvid import _checks as checks
from lpvid._files import mat_variables, npz_arrays, read_arrays, write_mat, write_npz
from lpvid._rows import unique_rows
from lpvid.data.schedule import scheduling_range
from lpvid.readers import read_experiment

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
        self.Ts = checks.sample_time(Ts)
        p_arr = checks.real_array(p, "p", ndim=(1, 2), axes=checks.POINT_AXES)
        if p_arr.shape[0] == 0:
            raise ValueError("p: needs at least one scheduling point")
        if p_arr.ndim == 2 and p_arr.shape[1] == 0:
            raise ValueError("p: needs at least one scheduling parameter per point")
        rows = p_arr.reshape(p_arr.shape[0], -1)
        if len(unique_rows(rows)[0]) != rows.shape[0]:
            raise ValueError("p: scheduling values must be distinct (found a duplicate point)")
        freqs = checks.real_array(freqs_hz, "freqs_hz", ndim=1, axes=("line",))
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
        g = checks.complex_array(G, "G", ndim=(2, 4), axes=checks.FRF_AXES)
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
            s = checks.real_array(sigma, "sigma", axes=checks.FRF_AXES)
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
        #: Where the data came from (set by :meth:`from_files`), else None.
        self.provenance: dict[str, Any] | None = None

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
    def p_rows(self) -> NDArray[np.float64]:
        """The scheduling values as rows, shape (N, Np), one parameter or several (a view)."""
        return self.p.reshape(self.n_points, -1)

    @property
    def n_residuals(self) -> int:
        """Number of complex residuals ``N F l r``: the noise floor of V_NLS."""
        return int(self.G.size)

    @property
    def z(self) -> NDArray[np.complex128]:
        """Evaluation points ``exp(j w Ts)`` (discrete) or ``j w`` (continuous)."""
        return z_points(self.freqs_hz, self.Ts)

    @property
    def p_range(self) -> Any:
        """The scheduling range of the points: ``(lo, hi)``, or ``[(lo, hi), ...]`` per parameter.

        The convention of every scheduling range in lpvid (see :mod:`lpvid.data.schedule`).
        """
        return scheduling_range(self.p)

    def subset(self, points: Any) -> FrfData:
        """Return the data of some scheduling points (at least one, none twice; not checked again).

        Parameters
        ----------
        points : int, slice, sequence of int or boolean mask
            Which points to keep.

        Returns
        -------
        FrfData

        """
        idx = np.atleast_1d(np.arange(self.n_points)[points])
        if idx.size == 0:
            raise ValueError("p: needs at least one scheduling point")
        if np.unique(idx).size != idx.size:
            raise ValueError("p: scheduling values must be distinct (found a duplicate point)")
        out = object.__new__(FrfData)
        out.Ts, out.freqs_hz, out.provenance = self.Ts, self.freqs_hz, None
        out.p, out.G, out.sigma = self.p[idx], self.G[idx], self.sigma[idx]
        for arr in (out.p, out.G, out.sigma):
            arr.setflags(write=False)
        return out

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
            if not checks.same_sample_time(d.Ts, first.Ts):
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
            p = np.concatenate([d.p_rows for d in items])
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
            return write_npz(path, {"Ts": ts, "format": np.array("lpvid-frf"), **fields})
        if suffix == ".mat":
            return write_mat(path, {**fields, "Ts": ts})
        raise ValueError(f"path: expected a .npz or .mat file, got {Path(path).name!r}")

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
        reader = {".npz": npz_arrays, ".mat": mat_variables}.get(suffix)
        if reader is None:
            raise ValueError(f"path: expected a .npz or .mat file, got {p.name!r}")
        raw = read_arrays(reader, p)
        missing = [k for k in ("p", "freqs_hz", "G") if k not in raw]
        if missing:
            raise ValueError(f"path: {p.name} lacks the variables {', '.join(missing)}")
        G = np.asarray(raw["G"])
        p_val = checks.real_array(raw["p"], "p")
        freqs = checks.real_array(raw["freqs_hz"], "freqs_hz").ravel()
        if suffix == ".mat":
            # MATLAB stores vectors as 1 x N matrices.
            if p_val.ndim == 2 and 1 in p_val.shape and G.shape[0] == p_val.size:
                p_val = p_val.ravel()
            if G.ndim == 4 and G.shape[0] == 1 and p_val.size == 1:
                p_val = p_val.ravel()
        ts = None if raw.get("Ts") is None else checks.real_array(raw["Ts"], "Ts")
        if ts is not None and ts.size > 1:
            raise ValueError(f"Ts: expected one number (or none), got shape {ts.shape}")
        ts_val = None if ts is None or ts.size == 0 else float(ts.ravel()[0])
        sigma = raw.get("sigma")
        return cls(p_val, freqs, G, sigma, ts_val)

    # ---------------------------------------------------------- measured files
    @classmethod
    def from_files(cls, manifest: str | os.PathLike[str], *, lines: str = "same") -> FrfData:
        """Load measured FRFs (UFF 58, CSV, MATLAB frd/idfrd) listed in a TOML manifest.

        The manifest lists, per scheduling value, the file(s) measured there;
        paths are relative to the manifest's folder. Example::

            Ts = 0.0005               # sample time in s; leave out for continuous time
            parameters = ["tube side [mm]"]            # optional names of p
            records = "labels"        # or "output-major" (default), "input-major"
            sigma = { from = "coherence", averages = 20 }   # for every point

            [[outputs]]               # or outputs = ["head", "carriage"]
            name = "head"
            node = 3                  # UFF response node; dir = "+X" optional
            unit = "m/s^2"            # checked against the files' units
            [[outputs]]
            name = "carriage"
            node = 2
            [[inputs]]
            name = "torque"
            node = 1
            unit = "N m"

            [[points]]
            p = 24.0                  # or p = [24.0, 20.0] for two parameters
            file = "tube24.uff"       # or files = ["a.uff", "b.uff"]
            [[points]]
            p = 30.0
            file = "tube30.uff"
            sigma = { from = "relative", level = 0.01 }    # this point only

        Top-level keys: ``outputs`` and ``inputs`` (required: names, or
        tables with ``name`` and optionally ``label``, ``node``, ``dir``,
        ``unit``), ``points`` (required: tables with ``p`` and ``file`` or
        ``files``, optionally ``sigma``, ``format``, ``variable``,
        ``records``, and ``outputs``/``inputs``: tables with ``name`` and
        any of ``label``, ``node``, ``dir`` that say anew how this point's
        files name the channel), ``Ts``,
        ``parameters``, ``records``, ``sigma``, ``format``, ``variable``,
        ``description`` (free text). Unknown keys are errors.

        Formats, by suffix (``.uff``, ``.unv``, ``.uf``; ``.csv``; ``.mat``)
        or ``format = "uff" | "csv" | "mat"``:

        - UFF dataset 58, ASCII or binary (needs ``pip install "lpvid[uff]"``):
          FRF records (function type 4) and coherence records (type 6);
          units from the ordinate numerator/denominator unit labels, the
          frequency unit from the abscissa unit label (Hz when absent); a
          truncated file is refused, naming the dataset and its line.
        - CSV: ``freq [Hz]``, then per pair ``OUT/IN frf [unit]`` (complex
          cells, ``(1+2j)`` or ``1+2i``), or ``OUT/IN re [unit]`` and
          ``OUT/IN im [unit]``, or ``OUT/IN mag [unit]`` (or ``db``) and
          ``OUT/IN phase [deg]``; optional ``OUT/IN coh`` and ``OUT/IN var``
          (see :mod:`lpvid.readers.table`).
        - MATLAB: a struct (``s = struct(sys)`` of an frd/idfrd, or by hand;
          ``variable`` names it when the file has several) or top-level
          variables with ``ResponseData`` (l x r x F), ``Frequency``,
          ``FrequencyUnit`` (default ``'rad/TimeUnit'`` as in MATLAB),
          ``Ts``, ``OutputName``/``InputName``, ``OutputUnit``/``InputUnit``,
          ``CovarianceData``, or ``Variance``/``Coherence`` (l x r x F).

        Which record is which pair (``records``): by order, the function
        records of a point's files in file order are (y1,u1), (y1,u2), ...
        (``"output-major"``) or (y1,u1), (y2,u1), ... (``"input-major"``),
        and every one must be an FRF (MATLAB data are placed by position);
        by ``"labels"``, in each file's own terms: in UFF files the node
        (and direction) when ``node`` is given, else the entity name; in
        CSV and MATLAB files the label (CSV ``OUT/IN``, MATLAB
        ``OutputName``/``InputName``); labels equal to ``label`` (default:
        the name). When no record matches, the error lists per file what
        was looked for and what the file holds.

        sigma (``sigma = {...}`` at the top for every point, or per point;
        without it sigma is 1): ``{ from = "coherence", averages = n }``
        uses the coherence records, ``sigma^2 = |G|^2 (1 - gamma^2) / (n
        gamma^2)`` per line, twice Bendat and Piersol's variance of the
        magnitude since lpvid's sigma is that of the complex estimate
        (:func:`lpvid.readers.sigma_from_coherence`); ``{ from = "variance" }``
        uses variance records ``E|dG|^2`` (CSV ``var``, MATLAB
        ``CovarianceData`` or ``Variance``); ``{ from = "relative", level =
        0.01 }`` gives ``sigma = level |G|``.

        Units: where the files state them, the units of a pair must agree
        across points and, when the manifest gives ``unit`` for the output
        and the input, equal ``"output unit/input unit"``. ``Ts``: a MATLAB
        file's ``Ts`` must agree with the manifest's (and fills it in when
        the manifest has none).

        Parameters
        ----------
        manifest : str or path-like
            The TOML manifest.
        lines : {"same", "common"}
            ``"same"`` (default): every record must have the same frequency
            lines (to 1e-5 relative, the precision of UFF's abscissa), else
            a ValueError names the point that differs; ``"common"``: keep
            the lines every record has, with a warning that says how many
            each point lost.

        Returns
        -------
        FrfData
            With :attr:`provenance`: the manifest, per point the files,
            records and sigma source, the lines kept and dropped, and the
            names of the outputs, inputs and scheduling parameters.

        Raises
        ------
        ValueError
            Naming the manifest, file and record: a missing file or record,
            a record of the wrong type (an auto spectrum where an FRF is
            expected), NaN lines, inconsistent units, frequency lines that
            differ, a bad manifest key. TypeError when ``manifest`` is no path.

        """
        exp = read_experiment(manifest, lines=lines)
        try:
            data = cls(exp.p, exp.freqs_hz, exp.G, exp.sigma, exp.Ts)
        except (ValueError, TypeError) as exc:
            raise type(exc)(f"{Path(manifest).name}: {exc}") from exc
        data.provenance = exp.provenance
        return data
