"""Which record of a point's files is which output/input pair.

Two ways, as the manifest's ``records`` says:

- by order (``"output-major"``, the default, or ``"input-major"``): the
  function records of the point's files, in file order, are the pairs
  (y1,u1), (y1,u2), ... (output-major) or (y1,u1), (y2,u1), ...
  (input-major); coherence and variance records likewise, each kind on its
  own. Records that carry their position (MATLAB ``ResponseData(i,j,:)``)
  are placed by it. Every function record must then be an FRF.
- by labels (``"labels"``): the pair of output k and input m is the record
  whose response matches output k and whose reference matches input m, in
  the terms of the record's file: in a file with nodes (UFF), the node (and
  direction) when the manifest gives ``node`` (and ``dir``); otherwise the
  file's label (UFF entity name, CSV ``OUTPUT/INPUT`` label, MATLAB
  ``OutputName``/``InputName``) against ``label``, by default the name. So
  one manifest names its channels by node for UFF files and by label for
  CSV and MATLAB files, at the same point or at different ones.

When no record matches, the message lists, file by file, what was looked
for and the records the file holds, in that file's terms.
"""

from __future__ import annotations

from collections.abc import Sequence

from lpvid.readers.manifest import ChannelSpec
from lpvid.readers.records import (
    COHERENCE,
    FRF,
    VARIANCE,
    Channel,
    FileError,
    Record,
    direction_name,
)

__all__ = ["select_records"]

Grid = list[list[Record]]
_SIGMA_KINDS = (COHERENCE, VARIANCE)


def select_records(
    records: Sequence[Record],
    outputs: Sequence[ChannelSpec],
    inputs: Sequence[ChannelSpec],
    mode: str,
    kinds: Sequence[str],
    files: str,
) -> dict[str, Grid]:
    """The l x r grid of checked records of each kind in ``kinds``.

    Parameters
    ----------
    records : sequence of Record
        All records of one point's files, in file order.
    outputs, inputs : sequence of ChannelSpec
        The manifest's outputs and inputs.
    mode : str
        ``"output-major"``, ``"input-major"`` or ``"labels"``.
    kinds : sequence of str
        ``"frf"`` and, for sigma, ``"coherence"`` or ``"variance"``.
    files : str
        The point's files, for messages.

    Raises
    ------
    FileError
        A missing record, a record of the wrong type, or two records for one
        pair; the message names the files and the record or the pair.
    """
    if mode == "labels":
        return {kind: _by_labels(records, outputs, inputs, kind, files) for kind in kinds}
    return {kind: _by_order(records, outputs, inputs, mode, kind, files) for kind in kinds}


def _wrong_type(rec: Record, mode: str) -> FileError:
    hint = (
        f'with records = "{mode}", every function record of the files must be an FRF '
        "(coherence records aside): remove the others or match records by labels"
        if mode != "labels"
        else "it is the record the manifest's labels point to"
    )
    return FileError(f"{rec.where}: a record of type {rec.kind}, expected an FRF; {hint}")


def _by_order(
    records: Sequence[Record],
    outputs: Sequence[ChannelSpec],
    inputs: Sequence[ChannelSpec],
    mode: str,
    kind: str,
    files: str,
) -> Grid:
    l, r = len(outputs), len(inputs)
    if kind == FRF:
        chosen = [rec for rec in records if rec.kind not in _SIGMA_KINDS]
        for rec in chosen:
            if rec.kind != FRF:
                raise _wrong_type(rec, mode)
    else:
        chosen = [rec for rec in records if rec.kind == kind]
    what = "FRF" if kind == FRF else kind
    indexed = [rec for rec in chosen if rec.response.index is not None]
    if indexed and len(indexed) == len(chosen):
        rows = 1 + max(rec.response.index or 0 for rec in chosen)
        cols = 1 + max(rec.reference.index or 0 for rec in chosen)
        if (rows, cols) != (l, r):
            raise FileError(
                f"{files}: the {what} data are {rows} outputs x {cols} inputs, the manifest "
                f"names {l} x {r}"
            )
        grid: list[list[Record | None]] = [[None] * r for _ in range(l)]
        for rec in chosen:
            grid[rec.response.index or 0][rec.reference.index or 0] = rec
        return [[_checked(g) for g in row] for row in grid]
    if len(chosen) != l * r:
        missing = "missing " if len(chosen) < l * r else "too many "
        raise FileError(
            f"{files}: {missing}{what} records: found {len(chosen)}, expected {l * r} "
            f"({l} output(s) x {r} input(s), taken in {mode} order)"
        )
    if mode == "output-major":
        return [[chosen[i * r + j].checked() for j in range(r)] for i in range(l)]
    return [[chosen[j * l + i].checked() for j in range(r)] for i in range(l)]


def _checked(rec: Record | None) -> Record:
    if rec is None:  # pragma: no cover - a full index grid has every cell
        raise FileError("a record position is missing")
    return rec.checked()


def _has_nodes(channel: Channel) -> bool:
    return channel.node is not None


def _matches(spec: ChannelSpec, channel: Channel) -> bool:
    if _has_nodes(channel) and spec.node is not None:
        if channel.node != spec.node:
            return False
        return spec.direction is None or channel.direction == spec.direction
    return channel.label == (spec.label if spec.label is not None else spec.name)


def _sought(spec: ChannelSpec, nodes: bool) -> str:
    """What identifies ``spec`` in a file with (``nodes``) or without nodes."""
    if nodes and spec.node is not None:
        return f"node {spec.node} {direction_name(spec.direction)}".strip()
    label = spec.label if spec.label is not None else spec.name
    return f"{'entity name' if nodes else 'label'} {label!r}"


def _held(rec: Record) -> str:
    """A record's pair as its file names it."""
    out, inp = rec.response, rec.reference
    if _has_nodes(out) or _has_nodes(inp):  # UFF: nodes, directions, entity names
        return f"{out.describe()} / {inp.describe()} ({rec.name})"
    if out.index is not None:  # MATLAB: OutputName / InputName at a position
        return f"{out.label!r} / {inp.label!r} ({rec.name})"
    return repr(f"{out.label or ''}/{inp.label or ''}")  # CSV: the OUT/IN column label


def _no_match(
    records: Sequence[Record], out: ChannelSpec, inp: ChannelSpec, kind: str, files: str
) -> FileError:
    what = "FRF" if kind == FRF else kind
    per_file: dict[str, list[Record]] = {}
    for rec in records:
        per_file.setdefault(rec.file, []).append(rec)
    parts = []
    for file, recs in per_file.items():
        nodes = any(_has_nodes(rec.response) for rec in recs)
        held = [_held(rec) for rec in recs if rec.kind == kind]
        holds = f"the {what} records {', '.join(held)}" if held else f"no {what} records"
        parts.append(
            f"{file} (looked for {_sought(out, nodes)} / {_sought(inp, nodes)}) holds {holds}"
        )
    return FileError(
        f"{files}: no {what} record matches output {out.name!r} / input {inp.name!r}; "
        + "; ".join(parts)
    )


def _by_labels(
    records: Sequence[Record],
    outputs: Sequence[ChannelSpec],
    inputs: Sequence[ChannelSpec],
    kind: str,
    files: str,
) -> Grid:
    grid = []
    for out in outputs:
        row = []
        for inp in inputs:
            hits = [
                rec
                for rec in records
                if _matches(out, rec.response) and _matches(inp, rec.reference)
            ]
            same = [rec for rec in hits if rec.kind == kind]
            if len(same) > 1:
                what = "FRF" if kind == FRF else kind
                raise FileError(
                    f"{files}: {len(same)} {what} records for output {out.name!r} / input "
                    f"{inp.name!r}: {', '.join(rec.where for rec in same)}"
                )
            if not same:
                other = [rec for rec in hits if rec.kind not in _SIGMA_KINDS]
                if kind == FRF and other:
                    raise _wrong_type(other[0], "labels")
                raise _no_match(records, out, inp, kind, files)
            row.append(same[0].checked())
        grid.append(row)
    return grid
