"""What every reader returns: function records with their axis, labels and units.

A reader turns one file into a list of :class:`Record`: one function of
frequency each (an FRF, a coherence or a variance) with the response and
reference channel it belongs to, in the file's own words. The checks that
every format needs (a finite, increasing frequency axis in Hz; finite
values) live here, so that each reader states only what is particular to
its format.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lpvid.errors import FileError

__all__ = [
    "COHERENCE",
    "FRF",
    "VARIANCE",
    "Channel",
    "FileError",
    "Record",
    "check_axis",
    "check_values",
    "direction_name",
    "hz_per_unit",
    "parse_direction",
    "same_units",
]

#: Record kinds the assembler knows; readers may give other kinds (an auto
#: spectrum, a time response) so that a wrong record can be named.
FRF, COHERENCE, VARIANCE = "frf", "coherence", "variance"

_TIME_UNITS = {
    "s": 1.0,
    "sec": 1.0,
    "second": 1.0,
    "seconds": 1.0,
    "ms": 1e-3,
    "millisecond": 1e-3,
    "milliseconds": 1e-3,
    "us": 1e-6,
    "microsecond": 1e-6,
    "microseconds": 1e-6,
    "min": 60.0,
    "minute": 60.0,
    "minutes": 60.0,
    "h": 3600.0,
    "hour": 3600.0,
    "hours": 3600.0,
}


@dataclass(frozen=True)
class Channel:
    """How a file names one end (response or reference) of a record.

    Attributes
    ----------
    label : str or None
        The file's label: a UFF entity name, the output or input part of a
        CSV column label, a MATLAB ``OutputName``/``InputName``.
    node, direction : int or None
        UFF node number and direction code (1..3 translation, 4..6
        rotation about X, Y, Z; negative for the minus direction).
    index : int or None
        Position in the file's matrix (MATLAB ``ResponseData``), 0-based.
    """

    label: str | None = None
    node: int | None = None
    direction: int | None = None
    index: int | None = None

    def describe(self) -> str:
        """A short text for messages: ``'head' node 3 +X``."""
        parts = []
        if self.label:
            parts.append(repr(self.label))
        if self.node is not None:
            parts.append(f"node {self.node}")
            if self.direction:
                parts.append(direction_name(self.direction))
        if self.index is not None:
            parts.append(f"#{self.index + 1}")
        return " ".join(parts) or "unlabelled"


@dataclass(frozen=True)
class Record:
    """One function of frequency read from a file.

    Attributes
    ----------
    file : str
        The file's name, for messages.
    name : str
        Where in the file: ``record 3``, ``column 'y1/u1 re'``, ``ResponseData(2,1,:)``.
    kind : str
        ``"frf"``, ``"coherence"`` (magnitude-squared, in [0, 1]),
        ``"variance"`` (``E|dG|^2``) or another kind the file declares (then
        the record is not usable, and the assembler says so).
    response, reference : Channel
        Output and input end of the function.
    freqs_hz : ndarray, shape (F,)
        Frequency axis in Hz.
    values : ndarray, shape (F,)
        Complex for an FRF, real otherwise.
    units : str or None
        Units of the values as the file states them (``"m/s^2/N"``), None
        when it does not.
    freq_unit : str or None
        Unit of ``freqs_hz`` as read (``"rad/s"``); None or ``"Hz"`` for Hz.
        :meth:`checked` converts to Hz.

    A reader checks only what every record of the file needs; what a record
    needs to be used (a frequency axis in Hz, finite values) is checked by
    :meth:`checked` when the record is chosen, so that a broken record the
    manifest does not ask for does not stop the reading.
    """

    file: str
    name: str
    kind: str
    response: Channel
    reference: Channel
    freqs_hz: NDArray[np.float64]
    values: NDArray[np.generic]
    units: str | None = None
    freq_unit: str | None = None

    @property
    def where(self) -> str:
        """``file, record`` for messages."""
        return f"{self.file}, {self.name}"

    def checked(self) -> Record:
        """The record with its axis in Hz, checked, and its values checked finite."""
        scale = hz_per_unit(self.freq_unit, f"{self.where}: frequency axis")
        f = check_axis(np.asarray(self.freqs_hz, dtype=np.float64) * scale, self.where)
        v = check_values(self.values, f, self.where)
        return replace(self, freqs_hz=f, values=v, freq_unit=None)


def direction_name(code: int | None) -> str:
    """UFF direction code as text: 1 -> ``+X``, -5 -> ``-RY``, None -> ``''``."""
    if code is None or code == 0:
        return ""
    axis = ("X", "Y", "Z", "RX", "RY", "RZ")[abs(code) - 1]
    return f"{'+' if code > 0 else '-'}{axis}"


def parse_direction(value: object, where: str) -> int:
    """A direction as a UFF code: ``"+X"``, ``"-RZ"``, ``"Z"`` or an int in -6..6."""
    if isinstance(value, bool):
        raise FileError(f"{where}: expected a direction such as '+X' or 3, got {value!r}")
    if isinstance(value, int):
        if -6 <= value <= 6:
            return value
        raise FileError(f"{where}: direction codes run from -6 to 6, got {value}")
    if isinstance(value, str):
        text = value.strip().upper()
        sign = -1 if text.startswith("-") else 1
        axis = text.lstrip("+-")
        names = ("X", "Y", "Z", "RX", "RY", "RZ")
        if axis in names:
            return sign * (names.index(axis) + 1)
    raise FileError(f"{where}: expected a direction such as '+X', '-Z', 'RY' or 3, got {value!r}")


def hz_per_unit(unit: str | None, where: str, time_unit: str | None = None) -> float:
    """Factor that turns a frequency in ``unit`` into Hz.

    Knows ``Hz``, ``kHz``, ``rad/s``, ``rpm`` and MATLAB's
    ``rad/TimeUnit`` and ``cycles/TimeUnit`` (``time_unit`` seconds,
    milliseconds, ...). An empty unit or ``NONE`` means Hz.
    """
    text = (unit or "").strip()
    key = text.lower().replace(" ", "")
    if key in ("", "none", "hz", "1/s", "cycles/s", "cycles/second"):
        return 1.0
    if key == "khz":
        return 1e3
    if key in ("rpm", "rev/min"):
        return 1.0 / 60.0
    head, _, tail = key.partition("/")
    if tail == "timeunit" and head in ("rad", "cycles"):
        tail = (time_unit or "seconds").strip().lower()
        if tail not in _TIME_UNITS:
            raise FileError(
                f"{where}: unknown TimeUnit {time_unit!r} (known: seconds, milliseconds, "
                "microseconds, minutes, hours)"
            )
    if head in ("rad", "cycles") and tail in _TIME_UNITS:
        per_cycle = 2.0 * math.pi if head == "rad" else 1.0
        return 1.0 / (per_cycle * _TIME_UNITS[tail])
    raise FileError(
        f"{where}: unknown frequency unit {text!r} (known: Hz, kHz, rad/s, rpm, "
        "rad/TimeUnit, cycles/TimeUnit)"
    )


def check_axis(freqs: ArrayLike, where: str) -> NDArray[np.float64]:
    """A frequency axis in Hz: finite, >= 0, strictly increasing, not empty."""
    f = np.asarray(freqs, dtype=np.float64).ravel()
    if f.size == 0:
        raise FileError(f"{where}: no frequency lines")
    bad = ~np.isfinite(f)
    if np.any(bad):
        raise FileError(f"{where}: frequency axis has NaN or Inf at line {int(np.argmax(bad)) + 1}")
    if np.any(f < 0):
        raise FileError(f"{where}: negative frequency {f[f < 0][0]:g} Hz")
    steps = np.diff(f)
    if np.any(steps <= 0):
        k = int(np.argmax(steps <= 0))
        raise FileError(
            f"{where}: frequencies must increase strictly; line {k + 2} ({f[k + 1]:g} Hz) "
            f"follows {f[k]:g} Hz"
        )
    return f


def check_values(values: ArrayLike, freqs_hz: NDArray[np.float64], where: str) -> NDArray:
    """Values of a record, one per line, all finite; NaN lines are named."""
    v = np.asarray(values).ravel()
    if v.size != freqs_hz.size:
        raise FileError(f"{where}: {v.size} values for {freqs_hz.size} frequency lines")
    bad = ~np.isfinite(v)
    if np.any(bad):
        lines = np.flatnonzero(bad)
        shown = ", ".join(f"{freqs_hz[k]:g}" for k in lines[:5])
        more = f" and {lines.size - 5} more" if lines.size > 5 else ""
        raise FileError(
            f"{where}: NaN or Inf at {lines.size} of {freqs_hz.size} frequency lines "
            f"({shown}{more} Hz); remove those lines or fix the export"
        )
    return v


def same_units(a: str | None, b: str | None) -> bool:
    """Whether two unit texts agree (blanks ignored; an unstated unit agrees with any)."""
    if a is None or b is None:
        return True
    return a.replace(" ", "") == b.replace(" ", "")
