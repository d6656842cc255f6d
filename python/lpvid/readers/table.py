"""FRFs in a CSV table: one row per frequency line, columns named with units.

Layout (docs/data.md shows an example):

- Lines starting with ``#`` before the header are comments.
- The header names every column as ``[LABEL] QUANTITY [UNIT]``; the first
  column is the frequency, ``freq [Hz]`` (or ``[kHz]``, ``[rad/s]``, ``[rpm]``).
- Every output/input pair has the label ``OUTPUT/INPUT`` (may be left out
  when the file holds one pair) and either one ``frf`` column of complex
  numbers, or ``re`` and ``im`` columns, or ``mag`` (or ``db``, 20 log10 of
  the magnitude) and ``phase`` columns; the unit of ``phase`` is ``deg`` or
  ``rad``, that of the others the unit of the FRF (``[m/s^2/N]``; units may
  be left out).
- Optional per pair: ``coh`` (magnitude-squared coherence, in [0, 1]) and
  ``var`` (variance ``E|dG|^2`` of the FRF).
- Cells are separated by commas (or semicolons, or tabs), decimals by a point.
  Complex cells as numpy writes them (``(1+2j)``, ``(1+-2j)``) or MATLAB
  (``1+2i``, ``1+-2i``, ``1 - 2i``); in the other columns a complex cell
  must have a zero imaginary part (numpy writes a real column of a complex
  array as ``(50+0j)``).
- The header may be the last ``#`` line when the first line after the
  comments holds numbers: ``np.savetxt(path, table, delimiter=",",
  header="freq [Hz], y/u frf")`` writes it so.

Examples::

    # gantry, tube side 24 mm
    freq [Hz], head/torque re [m/s^2/(N m)], head/torque im [m/s^2/(N m)], head/torque coh
    50.0, 0.0132, -0.0021, 0.9991

    freq [Hz], head/torque frf [m/s^2/(N m)]
    50.0, 0.0132-0.0021i
"""

from __future__ import annotations

import csv
import math
import re
from pathlib import Path

import numpy as np

from lpvid.readers.records import COHERENCE, FRF, VARIANCE, Channel, FileError, Record

__all__ = ["read_csv"]

_COLUMN = re.compile(
    r"^(?:(?P<label>.*?)\s+)?(?P<q>freq|frequency|f|frf|re|im|mag|db|phase|coh|var)"
    r"\s*(?:\[(?P<unit>[^\]]*)\])?$",
    re.IGNORECASE,
)
_PHASE_UNITS = {"deg": math.pi / 180.0, "rad": 1.0}
_FREQ = ("freq", "frequency", "f")
#: Sign pairs that numpy and old MATLAB releases write between the parts: 1+-2j.
_SIGNS = (("+-", "-"), ("-+", "-"), ("--", "+"), ("++", "+"))


def read_csv(path: Path) -> list[Record]:
    """Read the FRF, coherence and variance records of a CSV table.

    Parameters
    ----------
    path : pathlib.Path
        A CSV file in the layout of this module's docstring.

    Returns
    -------
    list of Record
        Per pair, in the order of the columns: the FRF, then the coherence
        and variance when present.

    Raises
    ------
    FileError
        For a header that does not follow the layout, a cell that is not a
        number, or units that disagree within a pair.
    """
    name = path.name
    try:
        text = path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise FileError(f"{name}: cannot read the CSV file ({exc})") from exc
    lines = text.splitlines()
    start, comment = 0, None
    while start < len(lines) and (not lines[start].strip() or lines[start].lstrip()[:1] == "#"):
        if lines[start].strip():
            comment = start
        start += 1
    if start == len(lines):
        raise FileError(f"{name}: no header line (expected e.g. 'freq [Hz], y1/u1 re, y1/u1 im')")
    delimiter = max(",;\t", key=lines[start].count)
    rows = list(csv.reader(lines[start:], delimiter=delimiter))
    header_line, first_data = start + 1, 1
    if comment is not None and rows[0] and _is_number(rows[0][0]):
        # np.savetxt(..., header=...) writes the header as the last comment line.
        header_line, first_data = comment + 1, 0
        rows.insert(0, next(csv.reader([lines[comment].lstrip()[1:]], delimiter=delimiter)))
    header = [h.strip() for h in rows[0]]
    columns = [_parse_column(h, name, header_line) for h in header]
    if columns[0][1] not in _FREQ:
        raise FileError(f"{name}: the first column must be the frequency, e.g. 'freq [Hz]'")
    complex_ok = [quantity == "frf" for _, quantity, _ in columns]
    table = _numbers(rows[1:], header, complex_ok, name, first_line=start + 1 + first_data)
    freq_unit = columns[0][2]
    if freq_unit is None:
        raise FileError(f"{name}: column '{header[0]}': state the frequency unit, e.g. 'freq [Hz]'")
    pairs: dict[str, dict[str, tuple[int, str | None]]] = {}
    for c, (label, quantity, unit) in enumerate(columns[1:], start=1):
        if quantity in _FREQ:
            raise FileError(f"{name}: column '{header[c]}': a second frequency column")
        slot = pairs.setdefault(label, {})
        if quantity in slot:
            raise FileError(f"{name}: column '{header[c]}': {quantity} of {label!r} twice")
        slot[quantity] = (c, unit)
    if not pairs:
        raise FileError(f"{name}: no FRF columns after the frequency column")
    freqs = table[:, 0].real
    records = []
    for label, slot in pairs.items():
        records.extend(_pair_records(label, slot, table, freqs, freq_unit, header, name))
    return records


def _is_number(cell: str) -> bool:
    try:
        _value(cell)
    except ValueError:
        return False
    return True


def _value(cell: str) -> complex:
    """A cell as a number: real, or complex as numpy (``(1+2j)``) or MATLAB (``1+2i``) write it."""
    try:
        return complex(float(cell))
    except ValueError:
        pass
    text = "".join(cell.split())
    if text[:1] == "(" and text[-1:] == ")":
        text = text[1:-1]
    if text[-1:] in ("i", "I"):
        text = text[:-1] + "j"
    for pair, sign in _SIGNS:
        text = text.replace(pair, sign)
    if not text or "(" in text or ")" in text:
        raise ValueError(cell)
    return complex(text)


def _numbers(
    rows: list[list[str]], header: list[str], complex_ok: list[bool], name: str, first_line: int
) -> np.ndarray:
    out = np.empty((len(rows), len(header)), dtype=np.complex128)
    kept = 0
    for k, row in enumerate(rows):
        line = first_line + k
        if not row or all(not cell.strip() for cell in row):
            continue
        if len(row) != len(header):
            raise FileError(f"{name}, line {line}: {len(row)} cells, the header has {len(header)}")
        for c, cell in enumerate(row):
            at = f"{name}, line {line}, column '{header[c]}'"
            try:
                value = _value(cell)
            except ValueError as exc:
                raise FileError(f"{at}: not a number: {cell.strip()!r}") from exc
            if value.imag != 0 and not complex_ok[c]:
                raise FileError(
                    f"{at}: a complex number where a real one belongs: {cell.strip()!r} "
                    "(complex FRF values go in an 'OUT/IN frf' column)"
                )
            out[kept, c] = value
        kept += 1
    if kept == 0:
        raise FileError(f"{name}: no data rows under the header")
    return out[:kept]


def _parse_column(text: str, name: str, line: int) -> tuple[str, str, str | None]:
    m = _COLUMN.match(text)
    if m is None:
        raise FileError(
            f"{name}, line {line}: column '{text}': expected '[OUTPUT/INPUT] QUANTITY [UNIT]' "
            "with QUANTITY one of freq, frf, re, im, mag, db, phase, coh, var"
        )
    unit = m.group("unit")
    unit = unit.strip() or None if unit is not None else None
    return (m.group("label") or "").strip(), m.group("q").lower(), unit


def _pair_records(
    label: str,
    slot: dict[str, tuple[int, str | None]],
    table: np.ndarray,
    freqs: np.ndarray,
    freq_unit: str,
    header: list[str],
    name: str,
) -> list[Record]:
    shown = repr(label) if label else "the unlabelled pair"
    real = table.real  # every column but frf holds reals (checked by _numbers)
    out_label, _, in_label = label.partition("/")
    response = Channel(label=out_label.strip() or None)
    reference = Channel(label=in_label.strip() or None)
    forms = [f for f in ("frf", "re", "mag", "db") if f in slot]
    if len(forms) > 1 and forms != ["mag", "db"]:
        raise FileError(
            f"{name}: {shown}: give one of frf, re/im or mag/phase columns, not "
            f"{' and '.join(forms)}"
        )
    if "frf" in slot:
        if slot.keys() & {"im", "phase"}:
            raise FileError(f"{name}: {shown}: an frf column takes no im or phase column")
        c_frf, units = slot["frf"]
        values = table[:, c_frf]
        cols = f"column '{header[c_frf]}'"
    elif {"re", "im"} <= set(slot):
        if slot.keys() & {"phase"}:
            raise FileError(f"{name}: {shown}: give re/im or mag/phase columns, not both")
        (c_re, u_re), (c_im, u_im) = slot["re"], slot["im"]
        units = _agree(u_re, u_im, header[c_re], header[c_im], name)
        values = real[:, c_re] + 1j * real[:, c_im]
        cols = f"columns '{header[c_re]}', '{header[c_im]}'"
    elif "phase" in slot and ("mag" in slot) != ("db" in slot):
        c_ph, u_ph = slot["phase"]
        if u_ph is None or u_ph.lower() not in _PHASE_UNITS:
            raise FileError(
                f"{name}: column '{header[c_ph]}': state the phase unit, [deg] or [rad]"
            )
        c_mag, units = slot["mag"] if "mag" in slot else slot["db"]
        if units is not None and units.lower() == "db":
            units = None  # 'db [dB]' states no unit of the FRF itself
        mag = real[:, c_mag] if "mag" in slot else 10.0 ** (real[:, c_mag] / 20.0)
        values = mag * np.exp(1j * _PHASE_UNITS[u_ph.lower()] * real[:, c_ph])
        cols = f"columns '{header[c_mag]}', '{header[c_ph]}'"
    else:
        raise FileError(
            f"{name}: {shown}: needs an frf column, re and im columns, or mag (or db) and phase "
            "columns; "
            f"found {', '.join(sorted(slot))}"
        )
    records = [Record(name, cols, FRF, response, reference, freqs, values, units, freq_unit)]
    for quantity, kind in (("coh", COHERENCE), ("var", VARIANCE)):
        if quantity in slot:
            c, unit = slot[quantity]
            col = f"column '{header[c]}'"
            records.append(
                Record(name, col, kind, response, reference, freqs, real[:, c], unit, freq_unit)
            )
    return records


def _agree(a: str | None, b: str | None, col_a: str, col_b: str, name: str) -> str | None:
    if a is not None and b is not None and a.replace(" ", "") != b.replace(" ", ""):
        raise FileError(
            f"{name}: columns '{col_a}' and '{col_b}': inconsistent units [{a}] and [{b}]"
        )
    return a if a is not None else b
