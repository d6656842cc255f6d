"""The experiment manifest: a small TOML file naming what was measured where.

The format is documented in :meth:`lpvid.FrfData.from_files` and in
docs/data.md. This module reads it into plain, checked values; it opens none of
the data files. Every error names the manifest and the key that is wrong.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from lpvid.readers.records import FileError, parse_direction

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

__all__ = ["ChannelSpec", "Manifest", "PointSpec", "SigmaSpec", "read_manifest"]

#: How records are assigned to output/input pairs.
RECORD_ORDERS = ("output-major", "input-major", "labels")
#: File formats and the suffixes that imply them.
FORMATS = {".uff": "uff", ".unv": "uff", ".uf": "uff", ".csv": "csv", ".mat": "mat"}
SIGMA_SOURCES = ("coherence", "variance", "relative")

_TOP_KEYS = {
    "description",
    "Ts",
    "parameters",
    "outputs",
    "inputs",
    "records",
    "sigma",
    "format",
    "variable",
    "points",
}
_POINT_KEYS = {"p", "file", "files", "sigma", "format", "variable", "records", "outputs", "inputs"}
_CHANNEL_KEYS = {"name", "label", "node", "dir", "unit"}
#: What a point may say anew about how its files name a channel.
_NAMING_KEYS = ("label", "node", "dir")


@dataclass(frozen=True)
class ChannelSpec:
    """An output or input as the manifest names it.

    ``label``, ``node`` and ``direction`` say how the files name it (used
    when ``records = "labels"``: ``node`` and ``direction`` in files with
    nodes (UFF), ``label``, by default ``name``, in the others and in UFF
    files when no node is given); ``unit`` is checked against the units
    the files state.
    """

    name: str
    label: str | None = None
    node: int | None = None
    direction: int | None = None
    unit: str | None = None


@dataclass(frozen=True)
class SigmaSpec:
    """Where sigma comes from: ``coherence`` (with ``averages``), ``variance``, ``relative``."""

    source: str
    averages: int | None = None
    level: float | None = None


@dataclass(frozen=True)
class PointSpec:
    """One scheduling point: its value, its files and how to read them.

    ``records``, ``outputs`` and ``inputs`` are those of the manifest with
    this point's own ``records`` and channel naming put in.
    """

    index: int
    p: tuple[float, ...]
    files: tuple[Path, ...]
    sigma: SigmaSpec | None
    formats: tuple[str, ...]
    variable: str | None
    records: str
    outputs: tuple[ChannelSpec, ...]
    inputs: tuple[ChannelSpec, ...]


@dataclass(frozen=True)
class Manifest:
    """A checked manifest."""

    path: Path
    Ts: float | None
    parameters: tuple[str, ...] | None
    outputs: tuple[ChannelSpec, ...]
    inputs: tuple[ChannelSpec, ...]
    records: str
    points: tuple[PointSpec, ...]

    @property
    def name(self) -> str:
        """The manifest's file name, for messages."""
        return self.path.name


def read_manifest(path: Any) -> Manifest:
    """Read and check a manifest; data file paths are resolved against its folder.

    Raises
    ------
    FileError
        When the manifest is missing, not TOML, or a key is missing, unknown
        or of the wrong kind (the message names the key).
    """
    mpath = Path(path)
    where = mpath.name
    try:
        with open(mpath, "rb") as fh:
            doc = tomllib.load(fh)
    except FileNotFoundError as exc:
        raise FileError(f"{where}: no such manifest: {mpath}") from exc
    except OSError as exc:
        raise FileError(f"{where}: cannot read the manifest ({exc})") from exc
    except tomllib.TOMLDecodeError as exc:
        raise FileError(f"{where}: not a valid TOML file ({exc})") from exc
    _no_unknown(doc, _TOP_KEYS, where)
    folder = mpath.resolve().parent

    ts = doc.get("Ts")
    if ts is not None:
        ts = _positive(ts, f"{where}: Ts")
    outputs = _channels(doc, "outputs", where)
    inputs = _channels(doc, "inputs", where)
    records = _records(doc.get("records", "output-major"), f"{where}: records")
    default_sigma = _sigma(doc.get("sigma"), f"{where}: sigma")
    default_format = _format(doc.get("format"), f"{where}: format")
    default_variable = _text(doc.get("variable"), f"{where}: variable")

    raw_points = doc.get("points")
    if not isinstance(raw_points, list) or not raw_points:
        raise FileError(
            f"{where}: points: expected one or more [[points]] tables with p and file, "
            f"got {type(raw_points).__name__ if raw_points is not None else 'nothing'}"
        )
    points = []
    for q, raw in enumerate(raw_points):
        at = f"{where}: points[{q}]"
        if not isinstance(raw, dict):
            raise FileError(f"{at}: expected a table with p and file")
        _no_unknown(raw, _POINT_KEYS, at)
        p = _scheduling(raw.get("p"), f"{at}.p")
        files = _files(raw, folder, at)
        fmt = _format(raw.get("format"), f"{at}.format") or default_format
        formats = tuple(fmt or _format_of(f, at) for f in files)
        sigma = _sigma(raw["sigma"], f"{at}.sigma") if "sigma" in raw else default_sigma
        variable = _text(raw.get("variable"), f"{at}.variable") or default_variable
        mode = _records(raw["records"], f"{at}.records") if "records" in raw else records
        outs = _overrides(raw, "outputs", outputs, at)
        ins = _overrides(raw, "inputs", inputs, at)
        points.append(PointSpec(q, p, files, sigma, formats, variable, mode, outs, ins))
    sizes = {len(pt.p) for pt in points}
    if len(sizes) > 1:
        q = next(pt.index for pt in points if len(pt.p) != len(points[0].p))
        raise FileError(
            f"{where}: points[{q}].p: {len(points[q].p)} scheduling values, but points[0] "
            f"has {len(points[0].p)}"
        )
    parameters = doc.get("parameters")
    if parameters is not None:
        if not isinstance(parameters, list) or not all(isinstance(x, str) for x in parameters):
            raise FileError(f"{where}: parameters: expected a list of names")
        if len(parameters) != len(points[0].p):
            raise FileError(
                f"{where}: parameters: {len(parameters)} names for {len(points[0].p)} "
                "scheduling values per point"
            )
        parameters = tuple(parameters)
    return Manifest(mpath, ts, parameters, outputs, inputs, records, tuple(points))


def _records(value: Any, where: str) -> str:
    if value not in RECORD_ORDERS:
        raise FileError(f"{where}: expected one of {RECORD_ORDERS}, got {value!r}")
    return str(value)


def _no_unknown(table: dict[str, Any], known: set[str], where: str) -> None:
    unknown = sorted(set(table) - known)
    if unknown:
        raise FileError(
            f"{where}: unknown key(s) {', '.join(unknown)} (known: {', '.join(sorted(known))})"
        )


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise FileError(f"{where}: expected a number, got {value!r}")
    v = float(value)
    if not math.isfinite(v):
        raise FileError(f"{where}: expected a finite number, got {value!r}")
    return v


def _positive(value: Any, where: str) -> float:
    v = _number(value, where)
    if v <= 0:
        raise FileError(f"{where}: expected a number > 0, got {value!r}")
    return v


def _text(value: Any, where: str) -> str | None:
    if value is None:
        return None
    if not isinstance(value, str) or not value.strip():
        raise FileError(f"{where}: expected a non-empty string, got {value!r}")
    return value.strip()


def _scheduling(value: Any, where: str) -> tuple[float, ...]:
    if value is None:
        raise FileError(f"{where}: missing (the scheduling value of this point)")
    if isinstance(value, list):
        if not value:
            raise FileError(f"{where}: expected at least one scheduling value")
        return tuple(_number(v, f"{where}[{i}]") for i, v in enumerate(value))
    return (_number(value, where),)


def _files(raw: dict[str, Any], folder: Path, at: str) -> tuple[Path, ...]:
    if ("file" in raw) == ("files" in raw):
        raise FileError(f'{at}: give either file = "..." or files = [...]')
    names = [raw["file"]] if "file" in raw else raw["files"]
    key = "file" if "file" in raw else "files"
    if not isinstance(names, list) or not names:
        raise FileError(f"{at}.{key}: expected a list of file names")
    out = []
    for name in names:
        if not isinstance(name, str) or not name.strip():
            raise FileError(f"{at}.{key}: expected file names (strings), got {name!r}")
        path = Path(name)
        path = path if path.is_absolute() else folder / path
        if not path.is_file():
            raise FileError(f"{at}.{key}: no such file: {name} (looked for {path})")
        out.append(path)
    return tuple(out)


def _format(value: Any, where: str) -> str | None:
    if value is None:
        return None
    formats = sorted(set(FORMATS.values()))
    if value not in formats:
        raise FileError(f"{where}: expected one of {formats}, got {value!r}")
    return str(value)


def _format_of(path: Path, at: str) -> str:
    fmt = FORMATS.get(path.suffix.lower())
    if fmt is None:
        raise FileError(
            f"{at}: cannot tell the format of {path.name} from its suffix "
            f'(known: {", ".join(FORMATS)}); say format = "uff", "csv" or "mat"'
        )
    return fmt


def _sigma(value: Any, where: str) -> SigmaSpec | None:
    if value is None:
        return None
    if not isinstance(value, dict):
        raise FileError(
            f'{where}: expected a table such as {{ from = "coherence", averages = 20 }}, '
            f"got {value!r}"
        )
    source = value.get("from")
    if source not in SIGMA_SOURCES:
        raise FileError(f"{where}.from: expected one of {SIGMA_SOURCES}, got {source!r}")
    keys = {"coherence": {"averages"}, "variance": set(), "relative": {"level"}}[source]
    _no_unknown(value, keys | {"from"}, where)
    if source == "coherence":
        n = value.get("averages")
        if isinstance(n, bool) or not isinstance(n, int) or n < 2:
            raise FileError(
                f"{where}.averages: expected the number of averages (an integer >= 2), got {n!r}"
            )
        return SigmaSpec(source, averages=n)
    if source == "relative":
        if "level" not in value:
            raise FileError(f"{where}.level: missing (sigma = level * |G|)")
        return SigmaSpec(source, level=_positive(value["level"], f"{where}.level"))
    return SigmaSpec(source)


def _channels(doc: dict[str, Any], key: str, where: str) -> tuple[ChannelSpec, ...]:
    raw = doc.get(key)
    if not isinstance(raw, list) or not raw:
        raise FileError(
            f'{where}: {key}: expected a list of names or tables, e.g. {key} = ["y1"] or '
            f"[[{key}]] with name = ..."
        )
    out = []
    for i, item in enumerate(raw):
        at = f"{where}: {key}[{i}]"
        if isinstance(item, str):
            item = {"name": item}
        if not isinstance(item, dict):
            raise FileError(f"{at}: expected a name or a table with name = ...")
        _no_unknown(item, _CHANNEL_KEYS, at)
        name = _text(item.get("name"), f"{at}.name")
        if name is None:
            raise FileError(f"{at}.name: missing")
        unit = _text(item.get("unit"), f"{at}.unit")
        out.append(_naming(ChannelSpec(name, unit=unit), item, at))
    names = [c.name for c in out]
    if len(set(names)) != len(names):
        raise FileError(f"{where}: {key}: names must differ, got {names}")
    return tuple(out)


def _naming(spec: ChannelSpec, item: dict[str, Any], at: str) -> ChannelSpec:
    """``spec`` with the ``label``, ``node`` and ``dir`` that ``item`` gives."""
    node = item.get("node", spec.node)
    if node is not None and (isinstance(node, bool) or not isinstance(node, int)):
        raise FileError(f"{at}.node: expected an integer node number, got {node!r}")
    direction = spec.direction
    if "dir" in item:
        direction = parse_direction(item["dir"], f"{at}.dir")
    if direction is not None and node is None:
        raise FileError(f"{at}.dir: needs node as well")
    label = _text(item.get("label"), f"{at}.label") if "label" in item else spec.label
    return replace(spec, label=label, node=node, direction=direction)


def _overrides(
    raw: dict[str, Any], key: str, channels: tuple[ChannelSpec, ...], at: str
) -> tuple[ChannelSpec, ...]:
    """The channels with a point's own naming of them (``[[points]]`` ``outputs``/``inputs``)."""
    if key not in raw:
        return channels
    items = raw[key]
    if not isinstance(items, list) or not items:
        raise FileError(
            f'{at}.{key}: expected a list of tables such as {{ name = "{channels[0].name}", '
            'label = "..." }'
        )
    by_name = {c.name: c for c in channels}
    seen: set[str] = set()
    for i, item in enumerate(items):
        where = f"{at}.{key}[{i}]"
        if not isinstance(item, dict):
            raise FileError(f"{where}: expected a table with name and label, node or dir")
        _no_unknown(item, {"name", *_NAMING_KEYS}, where)
        name = item.get("name")
        if name not in by_name:
            raise FileError(
                f"{where}.name: expected one of the {key} {sorted(by_name)}, got {name!r}"
            )
        if name in seen:
            raise FileError(f"{where}.name: {name!r} given twice for this point")
        seen.add(name)
        by_name[name] = _naming(by_name[name], item, where)
    return tuple(by_name[c.name] for c in channels)
