"""The grid of :func:`lpvid.select`: V_NLS against the order, one line per basis."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from lpvid.plots._style import _figure, _pyplot
from lpvid.selection.result import SelectResult, basis_label

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def select_grid(
    sel: SelectResult, *, title: str | None = None, fig: Figure | None = None
) -> Figure:
    """V_NLS relative to its noise floor against the model order, one line per basis.

    What judged the pairs is drawn: the validation V_NLS (rule
    ``"validation"``), the V_NLS summed over the held-out points
    (``"held-out"``) or the identification V_NLS (``"noise floor"``), each
    over its own noise floor, on a logarithmic axis. Pairs that failed are
    gaps; the chosen pair is ringed; the noise floor is the dotted line.

    Parameters
    ----------
    sel : SelectResult
        What :func:`lpvid.select` returned.
    title : str, optional
        Figure title.
    fig : Figure, optional
        Draw into this figure (cleared first) instead of a new one.

    Returns
    -------
    matplotlib.figure.Figure
        One line per basis with gid ``"basis/<label>"`` (x: order, y: the
        ratio, NaN where the pair failed) and the ring with gid ``"chosen"``.

    Raises
    ------
    TypeError
        When ``sel`` is not a SelectResult.
    ImportError
        When matplotlib is not installed.
    """
    if not isinstance(sel, SelectResult):
        raise TypeError(f"sel: expected an lpvid.SelectResult, got {type(sel).__name__}")
    judged = sel.rule != "noise floor"

    def ratio(row: Any) -> float:
        v, m = (
            (row.validation_vnls, row.validation_floor) if judged else (row.vnls, row.noise_floor)
        )
        return float("nan") if v is None or not m else float(v) / float(m)

    plt = _pyplot()
    fig = _figure(plt, fig, (6.4, 4.0))
    ax = fig.subplots()
    labels: list[str] = []
    for row in sel.grid:
        if basis_label(row.basis) not in labels:
            labels.append(basis_label(row.basis))
    for k, label in enumerate(labels):
        rows = [r for r in sel.grid if basis_label(r.basis) == label]
        x = np.array([r.order for r in rows])
        y = np.array([ratio(r) for r in rows])
        ax.plot(x, y, marker="o", ms=5, lw=1.2, color=f"C{k}", label=label, gid=f"basis/{label}")
    ax.plot(
        [sel.row.order],
        [ratio(sel.row)],
        marker="o",
        ms=13,
        mfc="none",
        mec="crimson",
        mew=1.6,
        ls="none",
        label=f"chosen ({sel.row.label})",
        gid="chosen",
    )
    ax.axhline(1.0, color="0.4", lw=0.9, ls=":", label="noise floor")
    what = {"validation": "validation", "held-out": "held-out", "noise floor": "identification"}
    ax.set_yscale("log")
    ax.set_xlabel("model order")
    ax.set_ylabel(rf"{what[sel.rule]} $V_\mathrm{{NLS}}$ / noise floor")
    ax.xaxis.get_major_locator().set_params(integer=True)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize="small")
    if title:
        ax.set_title(title)
    return fig
