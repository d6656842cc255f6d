"""One frequency axis for every record: the same lines everywhere, or the shared ones.

Two lines are the same when they agree to ``RTOL`` relative (1e-5: UFF
stores the abscissa with 6 significant digits) or ``ATOL`` Hz. Where two
files round a line differently, the value of the first record is kept.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from lpvid.readers.records import FileError, Record

__all__ = ["ATOL", "LINE_MODES", "RTOL", "Lines", "align_lines"]

RTOL = 1e-5
ATOL = 1e-9
LINE_MODES = ("same", "common")


@dataclass(frozen=True)
class Lines:
    """The shared axis and, per record, the indices of its lines on it.

    Attributes
    ----------
    freqs_hz : ndarray, shape (F,)
    index : list of ndarray of int
        ``record.values[index[k]]`` are record k's values on ``freqs_hz``.
    dropped : list of int
        Per record, how many of its lines are not on the axis.
    """

    freqs_hz: NDArray[np.float64]
    index: list[NDArray[np.intp]]
    dropped: list[int]


def _nearest(ref: NDArray[np.float64], f: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
    """For each line of ``ref``: the index of the nearest line of ``f`` and whether it matches."""
    if f.size == 1:
        j = np.zeros(ref.size, dtype=np.intp)
    else:
        j = np.clip(np.searchsorted(f, ref), 1, f.size - 1)
        j = np.where(np.abs(ref - f[j - 1]) <= np.abs(ref - f[j]), j - 1, j)
    gap = np.abs(ref - f[j])
    ok = gap <= RTOL * np.maximum(np.abs(ref), np.abs(f[j])) + ATOL
    return j, ok


def align_lines(records: Sequence[Record], labels: Sequence[str], mode: str) -> Lines:
    """Put every record on one frequency axis.

    Parameters
    ----------
    records : sequence of Record
        Checked records (axes in Hz), the first one's axis the reference.
    labels : sequence of str
        Per record, the point it belongs to (``"points[2] (p=36)"``), for messages.
    mode : str
        ``"same"``: every record must have the reference's lines (else a
        FileError naming the point and record that differ); ``"common"``:
        keep the lines every record has.

    Returns
    -------
    Lines
    """
    if mode not in LINE_MODES:
        raise ValueError(f"lines: expected one of {LINE_MODES}, got {mode!r}")
    ref_rec = records[0]
    ref = ref_rec.freqs_hz
    keep = np.ones(ref.size, dtype=bool)
    for rec, label in zip(records, labels, strict=True):
        f = rec.freqs_hz
        _, ok = _nearest(ref, f)
        if mode == "same" and (f.size != ref.size or not np.all(ok)):
            raise FileError(_differ(rec, label, ref_rec, labels[0]))
        keep &= ok
    if not np.any(keep):
        raise FileError(
            f"no frequency line is shared by every record (the first is {ref_rec.where}, "
            f"{labels[0]}, {ref.size} lines {ref[0]:g}-{ref[-1]:g} Hz)"
        )
    freqs = ref[keep]
    index = []
    dropped = []
    for rec in records:
        j, ok = _nearest(freqs, rec.freqs_hz)
        if not np.all(ok) or np.any(np.diff(j) <= 0):
            raise FileError(
                f"{rec.where}: frequency lines closer than {RTOL:g} relative cannot be told apart"
            )
        index.append(j)
        dropped.append(int(rec.freqs_hz.size - freqs.size))
    return Lines(freqs, index, dropped)


def _differ(rec: Record, label: str, ref_rec: Record, ref_label: str) -> str:
    f, ref = rec.freqs_hz, ref_rec.freqs_hz
    head = (
        f"{label}: {rec.where} has {f.size} frequency lines ({f[0]:g}-{f[-1]:g} Hz) that "
        f"differ from the {ref.size} lines ({ref[0]:g}-{ref[-1]:g} Hz) of {ref_rec.where} "
        f"({ref_label})"
    )
    n = min(f.size, ref.size)
    gap = np.abs(f[:n] - ref[:n]) > RTOL * np.maximum(np.abs(f[:n]), np.abs(ref[:n])) + ATOL
    if np.any(gap):
        k = int(np.argmax(gap))
        head += f"; first at line {k + 1}: {f[k]:.8g} Hz against {ref[k]:.8g} Hz"
    return head + "; pass lines='common' to keep the lines all records share"
