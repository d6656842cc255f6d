"""Measured against model FRF, with the error and sigma (the paper's Figs. 2, 5 and 8)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from lpvid.data.frf import FrfData
from lpvid.fit.cost import check_compatible
from lpvid.model.lpv import LpvModel
from lpvid.plots._style import (
    _KINDS,
    _channel,
    _db,
    _degree_ticks,
    _figure,
    _frequency_scale,
    _names,
    _phase,
    _point_colours,
    _point_label,
    _pretty,
    _pyplot,
)

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def frf_fit(
    model: LpvModel,
    data: FrfData,
    points: Any = None,
    *,
    title: str | None = None,
    phase: bool = False,
    kinds: Sequence[str] = ("measured", "model", "error", "sigma"),
    inputs: Sequence[str] | None = None,
    outputs: Sequence[str] | None = None,
    p_label: str = "p",
    fig: Figure | None = None,
) -> Figure:
    """Measured FRF, model FRF, error and sigma against frequency, in dB.

    One subplot per output (rows) and input (columns), as in the paper's
    Figs. 2, 5 and 8. Each scheduling point has its own colour; the kind of
    curve is told by its line style: measured ``G`` (solid), model ``G_m``
    (dashed), error ``|G - G_m|`` (thin, light) and ``sigma`` (dotted).
    The error lying on or below ``sigma`` means the model fits to the noise.

    Parameters
    ----------
    model : LpvModel
        The model; its sample time and sizes must match the data.
    data : FrfData
        The measurements (identification or validation points).
    points : int, slice, sequence of int or boolean mask, optional
        Which scheduling points to draw; default all.
    title : str, optional
        Figure title.
    phase : bool
        Also draw the phase (degrees, unwrapped over frequency) of the
        measured and the model FRF, in a row under each magnitude row.
    kinds : sequence of str
        Which curves to draw, among ``"measured"``, ``"model"``,
        ``"error"`` and ``"sigma"``.
    inputs, outputs : sequence of str, optional
        Channel names with units, e.g. ``["motor torque [N m]"]``; default
        ``input 1``, ``output 1``, ...
    p_label : str
        Name (and unit) of the scheduling parameter, the legend's title.
    fig : Figure, optional
        Draw into this figure (cleared first) instead of a new one.

    Returns
    -------
    matplotlib.figure.Figure
        Axes in row-major order (outputs by inputs; with ``phase``, each
        output has a magnitude row and a phase row). Lines carry the gid
        ``"<kind>/<q>"`` with ``q`` the index of the point in ``data``;
        phase lines ``"<kind>-phase/<q>"``.

    Raises
    ------
    ValueError
        When the model and the data disagree in sizes or sample time, or an
        argument is not one of the allowed values.
    ImportError
        When matplotlib is not installed.

    Examples
    --------
    >>> fig = lpvid.plots.frf_fit(result.model, data, title="identification")  # doctest: +SKIP
    >>> lpvid.plots.save(fig, "frf.png")  # doctest: +SKIP

    """
    check_compatible(model, data)
    kinds = [kinds] if isinstance(kinds, str) else list(kinds)
    unknown = [k for k in kinds if k not in _KINDS]
    if unknown or not kinds:
        raise ValueError(f"kinds: expected some of {list(_KINDS)}, got {kinds}")
    try:
        idx = np.atleast_1d(np.arange(data.n_points)[points if points is not None else slice(None)])
    except (IndexError, TypeError) as exc:
        raise ValueError(f"points: not a valid selection of {data.n_points} points") from exc
    if idx.size == 0:
        raise ValueError("points: selects no point")
    l, r = data.n_outputs, data.n_inputs
    out_names = _names(outputs, l, "output", "outputs")
    in_names = _names(inputs, r, "input", "inputs")

    plt = _pyplot()
    f = data.freqs_hz
    p = data.p[idx]
    G = data.G[idx]
    Gm = model.frf(f, p)
    colours = _point_colours(p)
    curves = {
        "measured": _db(G),
        "model": _db(Gm),
        "error": _db(G - Gm),
        "sigma": _db(data.sigma[idx]),
    }
    rows = 2 * l if phase else l
    fig = _figure(plt, fig, (3.8 * r + 2.4, (2.0 if phase else 2.7) * rows + 0.6))
    axes = np.asarray(fig.subplots(rows, r, sharex=True, squeeze=False))
    scale = _frequency_scale(f)
    for i in range(l):
        for j in range(r):
            ax = axes[2 * i if phase else i, j]
            for k, q in enumerate(idx):
                for kind in kinds:
                    st = _KINDS[kind]
                    ax.plot(
                        f,
                        curves[kind][k, :, i, j],
                        color="black" if kind == "model" else colours[k],
                        ls=st["ls"],
                        lw=st["lw"],
                        alpha=st["alpha"],
                        zorder=st["zorder"],
                        gid=f"{kind}/{q}",
                    )
            ax.set_title(_channel(out_names[i], in_names[j]), fontsize="medium")
            if j == 0:
                ax.set_ylabel("magnitude [dB]")
            if phase:
                pax = axes[2 * i + 1, j]
                for k, q in enumerate(idx):
                    ph_model = _phase(Gm[k, :, i, j])
                    # The measured phase is unwrapped around the model's, so that
                    # noise at low magnitude cannot throw it by whole turns.
                    ph_meas = ph_model + np.degrees(
                        np.angle(G[k, :, i, j] * np.conj(Gm[k, :, i, j]))
                    )
                    for kind, values in (("measured", ph_meas), ("model", ph_model)):
                        if kind not in kinds:
                            continue
                        st = _KINDS[kind]
                        pax.plot(
                            f,
                            values,
                            color="black" if kind == "model" else colours[k],
                            ls=st["ls"],
                            lw=st["lw"],
                            zorder=st["zorder"],
                            gid=f"{kind}-phase/{q}",
                        )
                _degree_ticks(pax.yaxis, *pax.dataLim.intervaly)
                if j == 0:
                    pax.set_ylabel("phase [deg]")
    for ax in axes.ravel():
        ax.set_xscale(scale)
        ax.grid(True, which="major", alpha=0.3)
        ax.set_xlim(f.min(), f.max())
    for ax in axes[-1]:
        ax.set_xlabel("frequency [Hz]")

    from matplotlib.lines import Line2D

    point_handles = [
        Line2D([], [], color=colours[k], lw=2.0, label=_point_label(p[k]))
        for k in np.argsort(p if p.ndim == 1 else p[:, 0], kind="stable")
    ]
    kind_handles = [
        Line2D(
            [],
            [],
            color="black" if kind == "model" else "0.35",
            ls=_KINDS[kind]["ls"],
            lw=max(_KINDS[kind]["lw"], 1.0),
            alpha=_KINDS[kind]["alpha"],
            label=_KINDS[kind]["label"],
        )
        for kind in kinds
    ]
    small = "small" if len(idx) <= 10 else "x-small"
    fig.legend(
        handles=kind_handles,
        loc="outside right upper",
        fontsize="small",
        title="curve",
        title_fontsize="small",
        frameon=False,
    )
    fig.legend(
        handles=point_handles,
        loc="outside right lower" if len(idx) <= 10 else "outside right center",
        fontsize=small,
        title=_pretty(p_label),
        title_fontsize="small",
        frameon=False,
        ncols=1 if len(idx) <= 16 else 2,
    )
    if title:
        fig.suptitle(title)
    return fig
