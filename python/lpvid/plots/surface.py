"""Magnitude (and phase) of a model over frequency and scheduling (Figs. 3 and 7)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from lpvid._checks import real_array
from lpvid.model.lpv import LpvModel
from lpvid.plots._style import (
    _channel,
    _check_model,
    _db,
    _degree_ticks,
    _figure,
    _frequency_scale,
    _names,
    _phase,
    _pretty,
    _pyplot,
)

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def magnitude_surface(
    model: LpvModel,
    freqs_hz: ArrayLike,
    p: ArrayLike,
    *,
    output: int = 0,
    input: int = 0,
    phase: bool = True,
    p_label: str = "scheduling p",
    f_label: str = "frequency [Hz]",
    p_marks: ArrayLike | None = None,
    inputs: Sequence[str] | None = None,
    outputs: Sequence[str] | None = None,
    title: str | None = None,
    fig: Figure | None = None,
) -> Figure:
    """Magnitude (and phase) of the model over frequency and scheduling.

    The frozen frequency response ``G_m(f, p)`` of one output and input on
    a grid, drawn as colour maps with frequency across and the scheduling
    value up (the paper's Figs. 3 and 7 seen from above): resonances
    appear as bright ridges whose drift with ``p`` can be read off.

    Parameters
    ----------
    model : LpvModel
        A model with one scheduling parameter.
    freqs_hz : array_like, shape (F,)
        Frequencies in Hz, increasing.
    p : array_like, shape (P,)
        Scheduling values, increasing, e.g. ``np.linspace(lo, hi, 60)``
        (``np.geomspace`` for a basis on the log scale, whose scheduling
        axis is then drawn on a log scale).
    output, input : int
        Which output and input (0-based).
    phase : bool
        Draw the phase (degrees, unwrapped over frequency) in a second panel.
    p_label, f_label : str
        Axis labels with units, e.g. ``"tube side p [mm]"``.
    p_marks : array_like, optional
        Scheduling values to mark with thin lines, e.g. the measured
        points ``data.p``.
    inputs, outputs : sequence of str, optional
        Channel names with units, for the default title.
    title : str, optional
        Figure title; default the output and input drawn (none for a
        single-input single-output model).
    fig : Figure, optional
        Draw into this figure (cleared first) instead of a new one.

    Returns
    -------
    matplotlib.figure.Figure
        The magnitude panel (gid ``"magnitude"``, values in dB with shape
        (P, F)) and, with ``phase``, the phase panel (gid ``"phase"``),
        each with its colour bar.

    Raises
    ------
    ValueError
        When the grid is not increasing or the channel does not exist.
    ImportError
        When matplotlib is not installed.

    """
    model = _check_model(model)
    f = real_array(freqs_hz, "freqs_hz", ndim=1)
    pp = real_array(p, "p", ndim=1)
    for arr, name in ((f, "freqs_hz"), (pp, "p")):
        if arr.size < 2 or np.any(np.diff(arr) <= 0):
            raise ValueError(f"{name}: expected at least two strictly increasing values")
    channels = ((output, model.n_outputs, "output"), (input, model.n_inputs, "input"))
    for value, count, name in channels:
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
            raise TypeError(f"{name}: expected an int, got {type(value).__name__}")
        if not 0 <= value < count:
            raise ValueError(f"{name}: expected 0 <= {name} < {count}, got {value}")
    marks = None if p_marks is None else real_array(p_marks, "p_marks").ravel()
    out_names = _names(outputs, model.n_outputs, "output", "outputs")
    in_names = _names(inputs, model.n_inputs, "input", "inputs")

    plt = _pyplot()
    G = model.frf(f, pp)[:, :, output, input]
    mag = _db(G)
    panels = [("magnitude", mag, "magnitude [dB]", "viridis")]
    if phase:
        ph = _phase(G)
        panels.append(("phase", ph, "phase [deg]", "cividis"))
    fig = _figure(plt, fig, (6.8, 3.0 * len(panels) + 0.5))
    axes = np.asarray(fig.subplots(len(panels), 1, sharex=True, squeeze=False))[:, 0]
    for ax, (gid, values, label, cmap) in zip(axes, panels, strict=True):
        mesh = ax.pcolormesh(f, pp, values, shading="gouraud", cmap=cmap, rasterized=True, gid=gid)
        bar = fig.colorbar(mesh, ax=ax, pad=0.01)
        bar.set_label(label)
        if gid == "phase":
            _degree_ticks(bar.ax.yaxis, float(np.min(values)), float(np.max(values)))
        ax.set_ylabel(_pretty(p_label))
        ax.set_yscale(model.basis.scales[0])
        ax.set_xscale(_frequency_scale(f))
        if marks is not None:
            for m in marks:
                ax.axhline(m, color="white", lw=0.6, ls="--", alpha=0.8)
    axes[-1].set_xlabel(_pretty(f_label))
    if title is None and (model.n_outputs > 1 or model.n_inputs > 1):
        title = _channel(out_names[output], in_names[input], width=60)
    if title:
        fig.suptitle(title)
    return fig
