"""MATLAB ``frd``/``idfrd`` data saved as a struct (``s = struct(sys); save f s``).

The struct (or the file's top-level variables, for data saved by hand)
holds:

- ``ResponseData``: l x r x F complex (a 1 x F vector for one pair);
- ``Frequency``: F lines, in ``FrequencyUnit`` (MATLAB's default
  ``'rad/TimeUnit'``; also ``'Hz'``, ``'kHz'``, ``'rpm'``, ``'cycles/TimeUnit'``),
  ``TimeUnit`` defaulting to ``'seconds'``;
- optionally ``Ts`` (0 continuous time, -1 discrete with unknown sample
  time, > 0 the sample time in ``TimeUnit``), ``OutputName``/``InputName``
  (labels), ``OutputUnit``/``InputUnit``, ``CovarianceData`` (idfrd: l x r x
  F x 2 x 2, covariance of the real and imaginary parts), or by hand
  ``Variance`` (l x r x F, ``E|dG|^2``) and ``Coherence`` (l x r x F).

Files saved with ``-v7.3`` (HDF5) are not read: save with ``-v7``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from lpvid._files import mat_variables
from lpvid.readers.records import COHERENCE, FRF, VARIANCE, Channel, FileError, Record, hz_per_unit

__all__ = ["read_mat"]

_NEEDED = ("ResponseData", "Frequency")


def read_mat(path: Path, variable: str | None = None) -> tuple[list[Record], float | None]:
    """Read the FRF records of a MATLAB file holding frd/idfrd data.

    Parameters
    ----------
    path : pathlib.Path
        A ``.mat`` file (v4 to v7).
    variable : str, optional
        Name of the struct; by default the one struct with a
        ``ResponseData`` field, else the file's top-level variables.

    Returns
    -------
    records : list of Record
        One FRF record per output/input pair (output-major), then the
        variance and coherence records when the data have them.
    Ts : float or None
        The sample time in seconds the file states: 0.0 for continuous
        time, -1.0 for discrete time with an unknown sample time, None when
        the file does not say.

    Raises
    ------
    FileError
        When the file cannot be read or lacks a field (the message names it).
    """
    name = path.name
    try:
        raw = mat_variables(path)
    except ValueError as exc:
        raise FileError(str(exc)) from exc
    fields, var = _fields(raw, name, variable)
    where = name if var is None else f"{name}, {var}"
    prefix = "" if var is None else f"{var}."
    missing = [k for k in _NEEDED if k not in fields]
    if missing:
        raise FileError(
            f"{where}: no field {' and '.join(missing)} (frd/idfrd data need ResponseData "
            "(l x r x F) and Frequency)"
        )
    rd = _response_array(fields["ResponseData"], f"{where}.ResponseData")
    l, r, n_lines = rd.shape
    freq = np.asarray(fields["Frequency"]).ravel()
    if not np.issubdtype(freq.dtype, np.number) or np.iscomplexobj(freq):
        raise FileError(f"{where}.Frequency: expected real numbers")
    if freq.size != n_lines:
        raise FileError(
            f"{where}: Frequency has {freq.size} lines, ResponseData {n_lines} (l x r x F)"
        )
    time_unit = _string(fields.get("TimeUnit"))
    unit = _string(fields.get("FrequencyUnit")) or "rad/TimeUnit"
    freqs = freq.astype(np.float64) * hz_per_unit(unit, f"{where}.FrequencyUnit", time_unit)
    outputs = _names(fields.get("OutputName"), l, f"{where}.OutputName")
    inputs = _names(fields.get("InputName"), r, f"{where}.InputName")
    out_units = _names(fields.get("OutputUnit"), l, f"{where}.OutputUnit")
    in_units = _names(fields.get("InputUnit"), r, f"{where}.InputUnit")
    extra = _extras(fields, (l, r, n_lines), where)

    records = []
    for kind, data, tag in [(FRF, rd, "ResponseData")] + extra:
        for i in range(l):
            for j in range(r):
                units = None
                if kind == FRF and out_units[i] and in_units[j]:
                    units = f"{out_units[i]}/{in_units[j]}"
                records.append(
                    Record(
                        file=name,
                        name=f"{prefix}{tag}({i + 1},{j + 1},:)",
                        kind=kind,
                        response=Channel(label=outputs[i], index=i),
                        reference=Channel(label=inputs[j], index=j),
                        freqs_hz=freqs,
                        values=data[i, j],
                        units=units,
                        freq_unit="Hz",
                    )
                )
    return records, _sample_time(fields.get("Ts"), time_unit, where)


def _fields(
    raw: dict[str, Any], name: str, variable: str | None
) -> tuple[dict[str, Any], str | None]:
    structs = {k: v for k, v in raw.items() if isinstance(v, np.ndarray) and v.dtype.names}
    if variable is not None:
        if variable not in structs:
            raise FileError(
                f"{name}: no struct named {variable!r} (structs: {sorted(structs) or 'none'})"
            )
        chosen = variable
    else:
        with_data = [k for k, v in structs.items() if "ResponseData" in v.dtype.names]
        if len(with_data) > 1:
            raise FileError(
                f"{name}: several structs with ResponseData ({', '.join(sorted(with_data))}); "
                'say which with variable = "..." in the manifest'
            )
        if with_data:
            chosen = with_data[0]
        elif "ResponseData" in raw or len(structs) != 1:
            return raw, None  # data saved by hand as top-level variables
        else:
            chosen = next(iter(structs))  # the one struct: its missing fields get named
    s = structs[chosen]
    if s.size != 1:
        raise FileError(f"{name}, {chosen}: a struct array of {s.size}; expected one struct")
    return {k: s[k].ravel()[0] for k in s.dtype.names}, chosen


def _response_array(value: Any, where: str) -> np.ndarray:
    arr = np.asarray(value)
    if not np.issubdtype(arr.dtype, np.number):
        raise FileError(f"{where}: expected numbers, got {arr.dtype}")
    if arr.ndim == 2 and 1 in arr.shape:
        arr = arr.reshape(1, 1, -1)  # one pair saved as a vector
    if arr.ndim != 3:
        raise FileError(f"{where}: expected an l x r x F array, got shape {arr.shape}")
    return arr.astype(np.complex128)


def _extras(
    fields: dict[str, Any], shape: tuple[int, int, int], where: str
) -> list[tuple[str, np.ndarray, str]]:
    out = []
    if "CovarianceData" in fields and np.asarray(fields["CovarianceData"]).size:
        cov = np.asarray(fields["CovarianceData"], dtype=np.float64)
        if cov.shape != (*shape, 2, 2):
            raise FileError(
                f"{where}.CovarianceData: expected l x r x F x 2 x 2 = {(*shape, 2, 2)}, "
                f"got {cov.shape}"
            )
        out.append((VARIANCE, cov[..., 0, 0] + cov[..., 1, 1], "CovarianceData"))
    for key, kind in (("Variance", VARIANCE), ("Coherence", COHERENCE)):
        if key in fields:
            arr = np.asarray(fields[key])
            if np.iscomplexobj(arr) or not np.issubdtype(arr.dtype, np.number):
                raise FileError(f"{where}.{key}: expected real numbers")
            if arr.ndim == 2 and shape[:2] == (1, 1) and 1 in arr.shape:
                arr = arr.reshape(1, 1, -1)
            if arr.shape != shape:
                raise FileError(f"{where}.{key}: expected l x r x F = {shape}, got {arr.shape}")
            if kind == VARIANCE and any(k == VARIANCE for k, _, _ in out):
                raise FileError(f"{where}: both CovarianceData and Variance; keep one")
            out.append((kind, arr.astype(np.float64), key))
    return out


def _string(value: Any) -> str | None:
    if value is None:
        return None
    arr = np.asarray(value).ravel()
    if arr.size == 0:
        return None
    if arr.dtype.kind in "US":
        return "".join(str(x) for x in arr).strip() or None
    if arr.dtype == object and arr.size == 1:
        return _string(arr[0])
    return None


def _names(value: Any, count: int, where: str) -> list[str | None]:
    if value is None:
        return [None] * count
    arr = np.asarray(value)
    if arr.size == 0:
        return [None] * count
    items = [_string(x) for x in arr.ravel()] if arr.dtype == object else [_string(arr)]
    if len(items) != count:
        raise FileError(f"{where}: {len(items)} names for {count} channels")
    return items


def _sample_time(value: Any, time_unit: str | None, where: str) -> float | None:
    if value is None or np.asarray(value).size == 0:
        return None
    arr = np.asarray(value).ravel()
    if arr.size != 1 or not np.issubdtype(arr.dtype, np.number):
        raise FileError(f"{where}.Ts: expected one number")
    ts = float(arr[0])
    if ts in (0.0, -1.0):
        return ts
    if not np.isfinite(ts) or ts < 0:
        raise FileError(f"{where}.Ts: expected 0 (continuous), -1 or a sample time > 0, got {ts}")
    # Ts is in TimeUnit: hz_per_unit gives cycles per TimeUnit in Hz, its inverse the unit in s.
    return ts / hz_per_unit("cycles/TimeUnit", f"{where}.TimeUnit", time_unit)
