"""Reports of an identification: Markdown with figures, model files, key numbers."""

from __future__ import annotations

import json
import os
from concurrent.futures import Executor
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from lpvid._files import write_atomic, write_folder_atomic
from lpvid.pipeline.result import IdentifyResult
from lpvid.report.figures import FigurePool, report_jobs, start_drawing
from lpvid.selection.result import SelectResult, basis_label
from lpvid.stable.scan import stability
from lpvid.trust.steps import refit_line

__all__ = [
    "FigurePool",
    "REPORT_ENTRIES",
    "write_report",
    "key_numbers",
    "select_numbers",
    "write_select_report",
]

#: What a report folder holds (:func:`write_report`, :func:`write_select_report`):
#: a folder holding anything else is not replaced.
REPORT_ENTRIES = (
    "report.md",
    "model.json",
    "model.mat",
    "result.json",
    "figures",
    "select.md",
    "grid.json",
)


def key_numbers(result: IdentifyResult) -> dict[str, Any]:
    """The numbers a report states, JSON-ready (also written as ``result.json``)."""
    e = result.final
    return {
        "order": result.model.n_states,
        "basis": result.model.basis.names,
        "start": result.start,
        "chosen_gamma": e.gamma,
        "chosen_index": result.chosen,
        "reason": result.reason,
        "groups_smile": result.initial.group_norms().count(),
        "groups_chosen": e.n_groups,
        "nonzero_groups": {k: [int(i) for i in v] for k, v in e.nonzero_groups.items()},
        "vnls": e.vnls,
        "noise_floor": e.noise_floor,
        "validation_vnls": e.validation_vnls,
        "validation_floor": e.validation_floor,
        "vnls_unregularised": result.entries[0].vnls,
        "validation_vnls_unregularised": result.entries[0].validation_vnls,
        "path": [
            {
                "gamma": p.gamma,
                "n_groups": p.n_groups,
                "vnls": p.vnls,
                "validation_vnls": p.validation_vnls,
                "seconds": p.seconds,
                "converged": p.converged,
                "pinned": p.pinned,
            }
            for p in result.entries
        ],
        "timings": result.timings,
        "refitted": result.refitted,
        "vnls_before_refit": result.entry.vnls,
        "validation_vnls_before_refit": result.entry.validation_vnls,
        "covariance_rank": None if result.covariance is None else result.covariance.rank,
        **_between_numbers(result),
        "stable": None if result.stability is None else result.stability.stable,
        "stability_margin": None if result.stability is None else result.stability.margin,
        "worst_p": None
        if result.stability is None
        else np.ravel(result.stability.worst_p).tolist(),
    }


def _between_numbers(result: IdentifyResult) -> dict[str, Any]:
    """What the points leave open, as key numbers (None where not counted)."""
    b = result.between
    count = None if b is None else b.count
    return {
        "silent_directions": None if count is None else count.silent,
        "directions_over_range": None if count is None else count.over_range,
        "points_needed": None if count is None else count.points_needed,
        "committee_members": 0 if b is None else len(b.members),
    }


def write_report(
    result: IdentifyResult,
    out_dir: str | os.PathLike[str],
    *,
    title: str = "lpvid identification",
    description: str | None = None,
    figures: bool = True,
    inputs: Any = None,
    outputs: Any = None,
    p_label: str | None = None,
    pool: Executor | None = None,
) -> Path:
    """Write a Markdown report, its figures, the model files and the key numbers.

    Files written to ``out_dir``: ``report.md``, ``model.json`` (lpvid's
    model file), ``model.mat`` (MATLAB), ``result.json``
    (:func:`key_numbers`) and, when ``figures`` and matplotlib is installed,
    PNG figures in ``figures/``. The folder is written whole or not at all:
    everything goes into a temporary folder beside it, which takes its place
    once complete; an error or Ctrl-C on the way leaves ``out_dir`` as it
    was. A folder already there is replaced, once the new one is complete,
    when it holds nothing but the entries of :data:`REPORT_ENTRIES` (an
    earlier report); holding anything else it raises FileExistsError before
    anything is written.

    Parameters
    ----------
    result : IdentifyResult
        What :func:`lpvid.identify` returned.
    out_dir : str or path-like
        Target folder.
    title : str
        Report title.
    description : str, optional
        A paragraph on the system and the data.
    figures : bool
        Draw the figures (needs matplotlib).
    inputs, outputs : sequence of str, optional
        Names (with units) of the inputs and outputs, for the figures.
    p_label : str, optional
        Name (with unit) of the scheduling parameter, for the figures.
    pool : concurrent.futures.Executor, optional
        Draws the figures in its workers while the rest of the report is
        written: a process pool (:class:`FigurePool`) puts
        them on other cores; threads do not help, matplotlib holds the GIL.
        Without, they are drawn here one after the other.

    Returns
    -------
    pathlib.Path
        The path of ``report.md``.
    """
    out = Path(out_dir)
    text = _Text(title, description, figures, _labels(inputs, outputs, p_label))

    def fill(folder: Path) -> None:
        _fill_report(result, folder, text, pool)

    write_folder_atomic(out, fill, REPORT_ENTRIES)
    return out / "report.md"


@dataclass(frozen=True)
class _Text:
    """What a report says besides the result: title, description, figures and their labels."""

    title: str
    description: str | None
    figures: bool
    labels: dict[str, Any]


def _labels(inputs: Any, outputs: Any, p_label: str | None) -> dict[str, Any]:
    """The figures' labels that were given."""
    given = (("inputs", inputs), ("outputs", outputs), ("p_label", p_label))
    return {k: v for k, v in given if v is not None}


def _fill_report(result: IdentifyResult, out: Path, text: _Text, pool: Executor | None) -> None:
    """Write the files of :func:`write_report` into the (new) folder ``out``."""
    result.model.save(out / "model.json")
    result.model.save(out / "model.mat")
    numbers = json.dumps(key_numbers(result), indent=1, allow_nan=True).encode()
    write_atomic(out / "result.json", lambda fh: fh.write(numbers))
    drawn: list[tuple[str, str]] = []
    figure_note = ""
    jobs = report_jobs(result, text.labels)
    wait = start_drawing(jobs, out / "figures", pool) if text.figures else None
    try:
        trust = _trust(result)  # while the pool draws
        if wait is not None:
            try:
                drawn = wait()
            except ImportError as exc:
                figure_note = f"(figures skipped: {exc})"
    except BaseException:
        # No worker may write into the folder once the caller removes it.
        if wait is not None:
            wait.abandon()
        raise
    md = _markdown(result, text.title, text.description, drawn, figure_note, trust)
    write_atomic(out / "report.md", lambda fh: fh.write(md.encode()))


def _trust(result: IdentifyResult) -> list[str]:
    """The report's section on the refit, the covariance and stability over the range."""
    lines = ["## Between the points: uncertainty and stability", ""]
    if result.refit_entry is not None:
        lines.append(f"- {refit_line(result.entry, result.refit_entry, result.refitted)}")
    c = result.covariance
    if c is not None:
        lines.append(
            f"- parameter covariance (first order, sigma-weighted): rank {c.rank} of "
            f"{c.n_free} free parameters, {c.n_similarity} similarity directions left out"
            + (
                f", {c.n_unidentified} directions not determined by the data"
                if c.n_unidentified
                else ""
            )
        )
    if result.between is not None:
        lines += [f"- {line.strip()}" for line in result.between.summary().splitlines()]
    rng = result.stability.p_range if result.stability is not None else None
    rep = stability(result.model, rng, rate="small")
    lines += [f"- {line}" for line in rep.summary().splitlines()]
    lines.append(f"- stability check: {rep.seconds:.2f} s")
    return lines + [""]


def _markdown(
    result: IdentifyResult,
    title: str,
    description: str | None,
    drawn: list[tuple[str, str]],
    figure_note: str,
    trust: list[str],
) -> str:
    data, e = result.data, result.final
    kind = "continuous time" if data.Ts is None else f"discrete time, Ts = {data.Ts:g} s"
    lines = [f"# {title}", ""]
    if description:
        lines += [description.strip(), ""]
    lines += [
        "## Data",
        "",
        f"- identification: {data.n_points} scheduling points, {data.n_lines} lines "
        f"({data.freqs_hz[0]:g}-{data.freqs_hz[-1]:g} Hz), {data.n_outputs} outputs x "
        f"{data.n_inputs} inputs, {kind}; noise floor M = {data.n_residuals}",
    ]
    if result.validation is not None:
        v = result.validation
        lines.append(
            f"- validation: {v.n_points} scheduling points; noise floor M = {v.n_residuals}"
        )
    lines += [
        "",
        "## Result",
        "",
        f"- order {result.model.n_states}, basis {', '.join(result.model.basis.names)}",
        f"- start: {result.start} ({result.initial_reason})",
        f"- chosen: gamma = {e.gamma:g} with {e.n_groups} groups kept "
        f"(SMILE: {result.initial.group_norms().count()}); {result.reason}",
        f"- V_NLS = {e.vnls:.6g} on the identification data: {e.vnls / e.noise_floor:.4f} "
        "times the noise floor",
    ]
    if e.validation_vnls is not None and e.validation_floor:
        lines.append(
            f"- V_NLS = {e.validation_vnls:.6g} on the validation data: "
            f"{e.validation_vnls / e.validation_floor:.4f} times the noise floor"
        )
    lines += [
        f"- time: {result.timings['total_s']:.2f} s (local models "
        f"{result.timings['local_s']:.2f} s, SMILE and NLS {result.timings['smile_s']:.2f} s, "
        f"l2,1 path {result.timings['path_s']:.2f} s)",
        "",
        "### Accuracy against simplicity (-> the chosen model)",
        "",
        "```",
        result.table(),
        "```",
        "",
        *(
            [
                "(pinned): the fit kept its steps off the directions that are flat at "
                "the data (state transformations at one scheduling point alone), because "
                "the warm fit lost interpolation or there were no validation data "
                "(`lpvid.pipeline.path`).",
                "",
            ]
            if any(e.pinned for e in result.entries)
            else []
        ),
        "### Group magnitudes of the SMILE model (left: ||theta_X(i)||, right: relative)",
        "",
        "```",
        str(result.initial.group_norms()),
        "```",
        "",
        "### Group magnitudes of the chosen model",
        "",
        "```",
        str(result.model.group_norms()),
        "```",
        "",
        "Files: `model.json` (lpvid model file), `model.mat` (MATLAB), `result.json`.",
        "",
        *trust,
    ]
    if drawn or figure_note:
        lines += ["## Figures", ""]
        if figure_note:
            lines += [figure_note, ""]
        for caption, rel in drawn:
            lines += [f"![{caption}]({rel})", "", f"*{caption}*", ""]
    return "\n".join(lines)


def select_numbers(sel: SelectResult) -> dict[str, Any]:
    """The grid of :func:`lpvid.select` and its choice, JSON-ready (written as ``grid.json``)."""
    return {
        "rule": sel.rule,
        "tolerance": sel.tolerance,
        "chosen": {"order": sel.order, "basis": basis_label(sel.basis), "index": sel.chosen},
        "reason": sel.reason,
        "interrupted": sel.interrupted,
        "order_hints": sel.hints.orders,
        "timings": sel.timings,
        "grid": [
            {
                "order": r.order,
                "basis": basis_label(r.basis),
                "vnls": r.vnls,
                "noise_floor": r.noise_floor,
                "validation_vnls": r.validation_vnls,
                "validation_floor": r.validation_floor,
                "n_groups": r.n_groups,
                "n_free": r.n_free,
                "seconds": r.seconds,
                "error": r.error,
                "warnings": [f"{c.__name__}: {m}" for c, m in r.warnings],
            }
            for r in sel.grid
        ],
    }


def write_select_report(
    sel: SelectResult,
    out_dir: str | os.PathLike[str],
    *,
    title: str = "lpvid select",
    description: str | None = None,
    figures: bool = True,
    inputs: Any = None,
    outputs: Any = None,
    p_label: str | None = None,
) -> Path:
    """Write the grid of :func:`lpvid.select` and the report of the chosen model.

    Files written to ``out_dir``: everything :func:`write_report` writes for
    ``sel.best`` (``report.md``, ``model.json``, ``model.mat``,
    ``result.json``, figures), then ``select.md`` (the grid table, the
    summary and the figure of :func:`lpvid.plots.select_grid` as
    ``figures/select.png`` when ``figures`` and matplotlib is installed) and
    ``grid.json`` (:func:`select_numbers`). The folder is written whole or
    not at all, and replaces one already there as in :func:`write_report`.

    Parameters
    ----------
    sel : SelectResult
        What :func:`lpvid.select` returned.
    out_dir : str or path-like
        Target folder.
    title, description, figures, inputs, outputs, p_label
        As in :func:`write_report`.

    Returns
    -------
    pathlib.Path
        The path of ``select.md``.
    """
    out = Path(out_dir)
    text = _Text(title, description, figures, _labels(inputs, outputs, p_label))
    write_folder_atomic(out, lambda folder: _fill_select(sel, folder, text), REPORT_ENTRIES)
    return out / "select.md"


def _fill_select(sel: SelectResult, out: Path, text: _Text) -> None:
    """Write the files of :func:`write_select_report` into the (new) folder ``out``."""
    chosen = f"{text.title}: the chosen model ({sel.row.label})"
    _fill_report(sel.best, out, replace(text, title=chosen), None)
    title, description, figures = text.title, text.description, text.figures
    grid = json.dumps(select_numbers(sel), indent=1, allow_nan=True).encode()
    write_atomic(out / "grid.json", lambda fh: fh.write(grid))
    figure = []
    if figures:
        try:
            from lpvid import plots

            (out / "figures").mkdir(parents=True, exist_ok=True)
            plots.save(plots.select_grid(sel, title=title), out / "figures" / "select.png")
            caption = "V_NLS over its noise floor against the order, one line per basis"
            figure = [f"![{caption}](figures/select.png)", "", f"*{caption}*", ""]
        except ImportError as exc:
            figure = [f"(figure skipped: {exc})", ""]
    lines = [
        f"# {title}",
        "",
        *([description.strip(), ""] if description else []),
        "## The choice",
        "",
        *[f"- {line}" for line in sel.summary().splitlines()],
        "- the chosen model's report: [report.md](report.md)",
        "",
        "## The grid (-> the chosen pair)",
        "",
        "```",
        sel.table(),
        "```",
        "",
        *figure,
        "Files: `grid.json` (every pair), `report.md`, `model.json`, `model.mat`, `result.json`.",
        "",
    ]
    md = "\n".join(lines)
    write_atomic(out / "select.md", lambda fh: fh.write(md.encode()))
