"""A whole experiment from its manifest: every point's files read, matched, aligned.

:func:`read_experiment` is what :meth:`lpvid.FrfData.from_files` calls; it
returns plain arrays and says where each number came from.
"""

from __future__ import annotations

import math
import os
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from lpvid.readers.lines import LINE_MODES, align_lines
from lpvid.readers.manifest import Manifest, PointSpec, read_manifest
from lpvid.readers.matlab import read_mat
from lpvid.readers.pairing import select_records
from lpvid.readers.records import COHERENCE, FRF, VARIANCE, FileError, Record, same_units
from lpvid.readers.sigma import sigma_from_coherence, sigma_from_variance, sigma_relative
from lpvid.readers.table import read_csv
from lpvid.readers.uff import read_uff

__all__ = ["Experiment", "read_experiment", "read_file"]


@dataclass(frozen=True)
class Experiment:
    """The arrays of an experiment, ready for :class:`lpvid.FrfData`.

    Attributes
    ----------
    p : ndarray, shape (N,) or (N, Np)
    freqs_hz : ndarray, shape (F,)
    G : ndarray, shape (N, F, l, r), complex
    sigma : ndarray of the shape of G, or None (no sigma source given)
    Ts : float or None
    outputs, inputs : tuple of str
        Names from the manifest.
    parameters : tuple of str or None
        Names of the scheduling parameters, when the manifest gives them.
    provenance : dict
        The manifest, per point its files, records and sigma source, the
        frequency lines kept and dropped, the names of the outputs, inputs
        and scheduling parameters.
    """

    p: NDArray[np.float64]
    freqs_hz: NDArray[np.float64]
    G: NDArray[np.complex128]
    sigma: NDArray[np.float64] | None
    Ts: float | None
    outputs: tuple[str, ...]
    inputs: tuple[str, ...]
    parameters: tuple[str, ...] | None
    provenance: dict[str, Any] = field(default_factory=dict)


def read_file(
    path: Path, fmt: str, variable: str | None = None
) -> tuple[list[Record], float | None]:
    """Records of one file and the sample time it states (MATLAB files only)."""
    if fmt == "uff":
        return read_uff(path), None
    if fmt == "csv":
        return read_csv(path), None
    if fmt == "mat":
        return read_mat(path, variable)
    raise ValueError(f"fmt: expected 'uff', 'csv' or 'mat', got {fmt!r}")


def _point_label(pt: PointSpec) -> str:
    value = pt.p[0] if len(pt.p) == 1 else list(pt.p)
    return f"points[{pt.index}] (p={value})"


def read_experiment(manifest: str | os.PathLike[str], *, lines: str = "same") -> Experiment:
    """Read the FRFs an experiment manifest lists.

    Parameters
    ----------
    manifest : str or path-like
        The TOML manifest (format: :meth:`lpvid.FrfData.from_files`).
    lines : {"same", "common"}
        ``"same"``: every record must have the same frequency lines, else a
        ValueError names the point that differs; ``"common"``: keep the
        lines all records share (a warning says how many were dropped).

    Returns
    -------
    Experiment

    Raises
    ------
    ValueError
        (:class:`~lpvid.readers.records.FileError`) naming the manifest, file
        and record for anything that cannot be used.
    """
    if not isinstance(manifest, str | os.PathLike):
        raise TypeError(
            f"manifest: expected the path of a .toml file, got {type(manifest).__name__}"
        )
    if lines not in LINE_MODES:
        raise ValueError(f"lines: expected one of {LINE_MODES}, got {lines!r}")
    m = read_manifest(manifest)
    l, r = len(m.outputs), len(m.inputs)
    chosen: list[Record] = []
    labels: list[str] = []
    slots: list[tuple[int, str, int, int]] = []
    file_ts: list[tuple[str, float]] = []
    for pt in m.points:
        records: list[Record] = []
        for path, fmt in zip(pt.files, pt.formats, strict=True):
            recs, ts = read_file(path, fmt, pt.variable)
            records.extend(recs)
            if ts is not None:
                file_ts.append((path.name, ts))
        kinds = [FRF]
        if pt.sigma is not None and pt.sigma.source in (COHERENCE, VARIANCE):
            kinds.append(pt.sigma.source)
        files = ", ".join(path.name for path in pt.files)
        grids = select_records(records, pt.outputs, pt.inputs, pt.records, kinds, files)
        for kind, grid in grids.items():
            for i in range(l):
                for j in range(r):
                    chosen.append(grid[i][j])
                    labels.append(_point_label(pt))
                    slots.append((pt.index, kind, i, j))
    _check_units(m, chosen, slots)
    ts = _sample_time(m, file_ts)
    axis = align_lines(chosen, labels, lines)
    n_points, n_lines = len(m.points), axis.freqs_hz.size
    arrays = {
        kind: np.zeros((n_points, n_lines, l, r), complex if kind == FRF else float)
        for kind in {s[1] for s in slots}
    }
    where: dict[tuple[int, str, int, int], str] = {}
    for rec, idx, slot in zip(chosen, axis.index, slots, strict=True):
        q, kind, i, j = slot
        arrays[kind][q, :, i, j] = np.asarray(rec.values)[idx]
        where[slot] = rec.where
    G = arrays[FRF]
    sigma = _sigma(m, G, arrays, where)
    dropped = [0] * n_points
    for (q, _, _, _), d in zip(slots, axis.dropped, strict=True):
        dropped[q] = max(dropped[q], d)
    if any(dropped):
        shown = ", ".join(
            f"{d} at {_point_label(pt)}" for pt, d in zip(m.points, dropped, strict=True) if d
        )
        warnings.warn(
            f"{m.name}: lines='common' kept the {n_lines} frequency lines every record has; "
            f"dropped {shown}",
            UserWarning,
            stacklevel=3,
        )
    p = np.array([pt.p for pt in m.points], dtype=np.float64)
    if p.shape[1] == 1:
        p = p[:, 0]
    provenance = {
        "manifest": str(m.path),
        "points": [
            {
                "p": list(pt.p),
                "files": [path.name for path in pt.files],
                "records": [where[(pt.index, FRF, i, j)] for i in range(l) for j in range(r)],
                "sigma": _describe_sigma(pt),
            }
            for pt in m.points
        ],
        "lines": {"mode": lines, "kept": n_lines, "dropped": dropped},
    }
    outputs = tuple(c.name for c in m.outputs)
    inputs = tuple(c.name for c in m.inputs)
    provenance["outputs"], provenance["inputs"] = list(outputs), list(inputs)
    provenance["parameters"] = None if m.parameters is None else list(m.parameters)
    return Experiment(p, axis.freqs_hz, G, sigma, ts, outputs, inputs, m.parameters, provenance)


def _describe_sigma(pt: PointSpec) -> str:
    s = pt.sigma
    if s is None:
        return "none (sigma = 1)"
    if s.source == COHERENCE:
        return f"coherence, {s.averages} averages"
    if s.source == VARIANCE:
        return "variance records"
    return f"relative, level {s.level:g}"


def _sigma(
    m: Manifest,
    G: np.ndarray,
    arrays: dict[str, np.ndarray],
    where: dict[tuple[int, str, int, int], str],
) -> np.ndarray | None:
    with_sigma = [pt.sigma is not None for pt in m.points]
    if not any(with_sigma):
        return None
    if not all(with_sigma):
        q = with_sigma.index(False)
        raise FileError(
            f"{m.name}: points[{q}] has no sigma while other points have one; give sigma for "
            "every point (or one at the top of the manifest for all)"
        )
    sigma = np.empty(G.shape)
    for pt in m.points:
        spec, q = pt.sigma, pt.index
        if spec is None:  # pragma: no cover - every point has one (checked above)
            continue
        for i in range(G.shape[2]):
            for j in range(G.shape[3]):
                g = G[q, :, i, j]
                if spec.source == COHERENCE:
                    at = where[(q, COHERENCE, i, j)]
                    coh = arrays[COHERENCE][q, :, i, j]
                    s = sigma_from_coherence(g, coh, spec.averages or 0, where=at)
                elif spec.source == VARIANCE:
                    at = where[(q, VARIANCE, i, j)]
                    s = sigma_from_variance(arrays[VARIANCE][q, :, i, j], where=at)
                else:
                    s = sigma_relative(g, spec.level or 0.0, where=where[(q, FRF, i, j)])
                sigma[q, :, i, j] = s
    return sigma


def _check_units(m: Manifest, chosen: Sequence[Record], slots: Sequence[tuple]) -> None:
    first: dict[tuple[int, int], Record] = {}
    for rec, (_, kind, i, j) in zip(chosen, slots, strict=True):
        if kind != FRF or rec.units is None:
            continue
        out, inp = m.outputs[i], m.inputs[j]
        pair = f"{out.name}/{inp.name}"
        if out.unit and inp.unit and not same_units(rec.units, f"{out.unit}/{inp.unit}"):
            raise FileError(
                f"{rec.where}: inconsistent units: the file says {rec.units!r}, the manifest "
                f"'{out.unit}/{inp.unit}' for {pair} (unit of the output / unit of the input)"
            )
        seen = first.setdefault((i, j), rec)
        if not same_units(rec.units, seen.units):
            raise FileError(
                f"{rec.where}: inconsistent units: {rec.units!r} for {pair}, but "
                f"{seen.where} has {seen.units!r}"
            )


def _sample_time(m: Manifest, file_ts: Sequence[tuple[str, float]]) -> float | None:
    stated: tuple[str, float] | None = None
    for name, ts in file_ts:
        if ts == 0.0 and m.Ts is not None:
            raise FileError(
                f"{name}: continuous-time data (Ts = 0), but {m.name} gives Ts = {m.Ts:g} s"
            )
        if ts == -1.0 and m.Ts is None:
            raise FileError(
                f"{name}: discrete-time data with an unknown sample time (Ts = -1); give Ts "
                f"in {m.name}"
            )
        if ts > 0 and m.Ts is not None and not math.isclose(ts, m.Ts, rel_tol=1e-9):
            raise FileError(f"{name}: Ts = {ts:g} s, but {m.name} gives Ts = {m.Ts:g} s")
        if ts != -1.0 and m.Ts is None:
            if stated is not None and not math.isclose(ts, stated[1], rel_tol=1e-9):
                raise FileError(
                    f"{name}: Ts = {ts:g} s, but {stated[0]} has Ts = {stated[1]:g} s "
                    "(0: continuous time)"
                )
            stated = stated or (name, ts)
    if m.Ts is not None:
        return m.Ts
    return stated[1] if stated is not None and stated[1] > 0 else None
