"""Universal File Format dataset 58 (function at nodal DOF), ASCII and binary.

Dynamic signal analyzers and modal test suites export one dataset 58 per
function: an FRF (function type 4), a coherence (type 6), an auto or cross
spectrum, ... each with its response and reference node and direction, its
frequency axis and its units labels. The parsing is done by ``pyuff``
(``pip install "lpvid[uff]"``); this module turns its records into
:class:`~lpvid.readers.records.Record`.

Records are numbered as the datasets of the file, from 1 (a header dataset
151 counts). A dataset runs from a line ``    -1`` to the next such line;
a file that ends inside a dataset (an interrupted export or copy), or a
dataset 58 with fewer values than its header announces, is refused as
truncated with the dataset's number and line, never read as shorter.
Rounding: pyuff writes ordinates as ``E20.11`` (12 significant
digits) in ASCII and as IEEE doubles in binary, and abscissa values as
``E13.5`` (6 significant digits) in both.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from lpvid.readers.records import COHERENCE, FRF, Channel, FileError, Record

__all__ = ["FUNCTION_TYPES", "read_uff"]

#: UFF 58 record 6 field 1.
FUNCTION_TYPES = {
    0: "general or unknown function",
    1: "time response",
    2: "auto spectrum",
    3: "cross spectrum",
    4: "frequency response function",
    5: "transmissibility",
    6: "coherence",
    7: "auto correlation",
    8: "cross correlation",
    9: "power spectral density",
    10: "energy spectral density",
    11: "probability density function",
    12: "spectrum",
    13: "cumulative frequency distribution",
    14: "peaks valley",
    15: "stress/cycles",
    16: "strain/cycles",
    17: "orbit",
    18: "mode indicator function",
    19: "force pattern",
    20: "partial power",
    21: "partial coherence",
    22: "eigenvalue",
    23: "eigenvector",
    24: "shock response spectrum",
    25: "finite impulse response filter",
    26: "multiple coherence",
    27: "order function",
}
#: Abscissa specific data types (record 8 field 1) that are a frequency axis.
_FREQUENCY_AXES = {0: "unknown", 1: "general", 18: "frequency"}
_AXIS_NAMES = {17: "time", 19: "rpm", 20: "order", 8: "displacement"}
#: The line that opens and closes a dataset: six columns, "-1" right-aligned.
_DELIMITER = b"    -1"


def read_uff(path: Path) -> list[Record]:
    """Read the dataset 58 records of a UFF file (other datasets are skipped).

    Parameters
    ----------
    path : pathlib.Path
        An ASCII or binary UFF file.

    Returns
    -------
    list of Record
        One per dataset 58, in file order. FRF records are complex;
        coherence records real.

    Raises
    ------
    FileError
        When pyuff is missing, the file cannot be parsed, or it holds no
        dataset 58.
    """
    try:
        import pyuff
    except ImportError as exc:
        raise FileError(
            f'{path.name}: reading UFF files needs the pyuff package: pip install "lpvid[uff]"'
        ) from exc
    name = path.name
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise FileError(f"{name}: cannot read the file ({exc})") from exc
    starts = _set_lines(data, name)
    try:
        uff = pyuff.UFF(str(path))
        types = [int(t) for t in uff.get_set_types()]
    except Exception as exc:  # pyuff raises bare Exception for everything
        raise FileError(f"{name}: not a readable UFF file ({exc})") from exc
    records = []
    for k, set_type in enumerate(types):
        if set_type != 58:
            continue
        at = f"{name}, record {k + 1}"
        try:
            dset = uff.read_sets(k)
        except Exception as exc:  # pyuff raises bare Exception for everything
            raise FileError(
                f"{at} (line {starts[k]}): dataset 58 cannot be read ({exc}); a binary file "
                "from some analyzers needs pyuff.fix_58b first"
            ) from exc
        announced = dset.get("num_pts")
        got = np.size(dset.get("data"))
        if announced is not None and got != int(announced):
            raise FileError(
                f"{at} (dataset 58 from line {starts[k]}): truncated: {got} values where its "
                f"header announces {int(announced)} (record 7, number of data values)"
            )
        records.append(_record(dset, name, k + 1))
    if not records:
        found = f"datasets {sorted(set(types))}" if types else "no UFF datasets"
        raise FileError(f"{name}: no dataset 58 (function record) in the file ({found})")
    return records


def _delimiters(data: bytes) -> list[int]:
    """Byte offsets of the ``    -1`` lines that open and close datasets (pyuff's rule)."""
    out = []
    at = data.find(_DELIMITER)
    while at != -1:
        end = at + len(_DELIMITER)
        padded = at + 80 < len(data) and data[end : at + 80] == b" " * (80 - len(_DELIMITER))
        if end == len(data) or data[end] in b"\r\n" or padded:
            out.append(at)
        at = data.find(_DELIMITER, at + 1)
    return out


def _set_lines(data: bytes, name: str) -> list[int]:
    """The line where each dataset starts; a FileError when the file ends inside one."""
    marks = _delimiters(data)
    lines = [data.count(b"\n", 0, at) + 1 for at in marks[::2]]
    if len(marks) % 2:
        start = marks[-1]
        head = data[start:].splitlines()
        kind = head[1][:6].decode("ascii", "replace").strip() if len(head) > 1 else ""
        what = f"dataset {kind}" if kind.isdigit() else "a dataset"
        last = data.count(b"\n") + (0 if data.endswith(b"\n") else 1)
        raise FileError(
            f"{name}: truncated: the file ends at line {last}, inside {what} (record "
            f"{len(lines)}, from line {lines[-1]}), before the line '    -1' that closes it; "
            "export or copy the file again"
        )
    return lines


def _record(dset: dict[str, Any], file: str, number: int) -> Record:
    func = int(dset.get("func_type", 0))
    axis = int(dset.get("abscissa_spec_data_type", 0))
    if func == 4:
        kind = FRF
    elif func == 6:
        kind = COHERENCE
    else:
        kind = f"{FUNCTION_TYPES.get(func, 'unknown function')} (function type {func})"
    if axis not in _FREQUENCY_AXES:
        what = _AXIS_NAMES.get(axis, f"specific data type {axis}")
        kind = f"function over {what} (abscissa data type {axis}), not over frequency"
    values = np.asarray(dset.get("data"))
    if kind == FRF:
        values = values.astype(np.complex128)
    elif kind == COHERENCE:
        if np.iscomplexobj(values):
            raise FileError(f"{file}, record {number}: coherence record holds complex values")
        values = values.astype(np.float64)
    x = np.asarray(dset.get("x"), dtype=np.float64)
    return Record(
        file=file,
        name=f"record {number}",
        kind=kind,
        response=_channel(dset, "rsp"),
        reference=_channel(dset, "ref"),
        freqs_hz=x,
        values=values,
        units=_units(dset),
        freq_unit=_label(dset.get("abscissa_axis_units_lab")),
    )


def _label(value: Any) -> str | None:
    text = str(value).strip() if value is not None else ""
    return None if text.upper() in ("", "NONE") else text


def _channel(dset: dict[str, Any], end: str) -> Channel:
    node = dset.get(f"{end}_node")
    direction = dset.get(f"{end}_dir")
    return Channel(
        label=_label(dset.get(f"{end}_ent_name")),
        node=None if node is None else int(node),
        direction=None if direction is None else int(direction),
    )


def _units(dset: dict[str, Any]) -> str | None:
    num = _label(dset.get("ordinate_axis_units_lab"))
    den = _label(dset.get("orddenom_axis_units_lab"))
    if num is None:
        return None
    return num if den is None else f"{num}/{den}"
