"""Which record of a point's files is which output/input pair.

Two ways, as the manifest's ``records`` says:

- by order (``"output-major"``, the default, or ``"input-major"``): the
  function records of the point's files, in file order, are the pairs
  (y1,u1), (y1,u2), ... (output-major) or (y1,u1), (y2,u1), ...
  (input-major); coherence and variance records likewise, each kind on its
  own. Records that carry their position (MATLAB ``ResponseData(i,j,:)``)
  are placed by it. Every function record must then be an FRF.
- by labels (``"labels"``): the pair of output k and input m is the record
  whose response matches output k and whose reference matches input m: the
  UFF node (and direction) when the manifest gives ``node`` (and ``dir``),
  else the file's label (UFF entity name, CSV ``OUTPUT/INPUT`` label,
  MATLAB ``OutputName``/``InputName``) against ``label``, by default the name.
"""

from __future__ import annotations

from collections.abc import Sequence

from lpvid.readers.manifest import ChannelSpec
from lpvid.readers.records import COHERENCE, FRF, VARIANCE, Channel, FileError, Record

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


def _matches(spec: ChannelSpec, channel: Channel) -> bool:
    if spec.node is not None:
        if channel.node != spec.node:
            return False
        if spec.direction is not None and channel.direction != spec.direction:
            return False
    label = spec.label if spec.label is not None else (spec.name if spec.node is None else None)
    return label is None or channel.label == label


def _describe(spec: ChannelSpec) -> str:
    if spec.node is not None:
        return Channel(spec.label, spec.node, spec.direction).describe()
    return repr(spec.label if spec.label is not None else spec.name)


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
            what = "FRF" if kind == FRF else kind
            pair = (
                f"output {out.name!r} (file label {_describe(out)}) / input {inp.name!r} "
                f"(file label {_describe(inp)})"
            )
            if len(same) > 1:
                raise FileError(
                    f"{files}: {len(same)} {what} records for {pair}: "
                    f"{', '.join(rec.name for rec in same)}"
                )
            if not same:
                other = [rec for rec in hits if rec.kind not in _SIGMA_KINDS]
                if kind == FRF and other:
                    raise _wrong_type(other[0], "labels")
                have = sorted(
                    {
                        f"{rec.response.describe()} / {rec.reference.describe()}"
                        for rec in records
                        if rec.kind == kind
                    }
                )
                raise FileError(
                    f"{files}: missing {what} record for {pair}; the {what} records there are "
                    f"{'; '.join(have) if have else 'none'}"
                )
            row.append(same[0].checked())
        grid.append(row)
    return grid
