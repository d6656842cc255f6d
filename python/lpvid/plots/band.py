"""The model FRF with its uncertainty band: at measured points, and as a map over the scheduling."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from lpvid._checks import real_array
from lpvid.data.frf import FrfData
from lpvid.fit.cost import check_compatible
from lpvid.plots._style import (
    _channel,
    _db,
    _figure,
    _frequency_scale,
    _names,
    _point_colours,
    _point_label,
    _pretty,
    _pyplot,
)
from lpvid.trust.uncertainty import Covariance, band_radius

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def _check_cov(cov: Any) -> Covariance:
    if not isinstance(cov, Covariance):
        raise TypeError(f"cov: expected an lpvid.Covariance, got {type(cov).__name__}")
    return cov


def frf_band(
    cov: Covariance,
    data: FrfData,
    *,
    level: float = 0.95,
    title: str | None = None,
    inputs: Sequence[str] | None = None,
    outputs: Sequence[str] | None = None,
    p_label: str = "p",
    fig: Figure | None = None,
) -> Figure:
    """Model FRF with its band and the measured FRF, in dB, at the points of ``data``.

    The band is the circle of radius ``band_radius(level) * sigma`` (sigma
    from :meth:`lpvid.Covariance.frf_std`) around the model FRF, drawn as the
    range of magnitudes it covers. At validation points it shows how far
    the model can be trusted where it was not fitted; the measured FRF
    carries its own noise (``data.sigma``, dotted).

    Parameters
    ----------
    cov : Covariance
        The covariance of the model (``cov.model`` is drawn).
    data : FrfData
        Identification or validation data.
    level : float
        Coverage of the band (0.95: radius ``sqrt(ln 20)`` sigma).
    title : str, optional
        Figure title.
    inputs, outputs : sequence of str, optional
        Channel names with units.
    p_label : str
        Name (and unit) of the scheduling parameter, the legend's title.
    fig : Figure, optional
        Draw into this figure (cleared first).

    Returns
    -------
    matplotlib.figure.Figure
        One axes per output and input; the bands carry gid ``"band/<q>"``,
        the model ``"model/<q>"``, the measurements ``"measured/<q>"`` and
        the measurement sigma ``"sigma/<q>"``.
    """
    cov = _check_cov(cov)
    model = cov.model
    check_compatible(model, data)
    radius = band_radius(level)
    l, r = data.n_outputs, data.n_inputs
    out_names = _names(outputs, l, "output", "outputs")
    in_names = _names(inputs, r, "input", "inputs")
    plt = _pyplot()
    f, p = data.freqs_hz, data.p
    Gm = model.frf(f, p)
    rad = radius * cov.frf_std(f, p)
    mag = np.abs(Gm)
    # A band wider than |G_m| reaches zero: its lower edge is drawn 60 dB down.
    lo = _db(np.maximum(mag - rad, 1e-3 * mag))
    hi = _db(mag + rad)
    colours = _point_colours(p)
    fig = _figure(plt, fig, (3.8 * r + 2.4, 2.7 * l + 0.6))
    axes = np.asarray(fig.subplots(l, r, sharex=True, squeeze=False))
    for i in range(l):
        for j in range(r):
            ax = axes[i, j]
            for q in range(data.n_points):
                c = colours[q]
                ax.fill_between(
                    f, lo[q, :, i, j], hi[q, :, i, j], color=c, alpha=0.3, lw=0, gid=f"band/{q}"
                )
                ax.plot(f, _db(Gm[q, :, i, j]), color=c, lw=1.0, gid=f"model/{q}")
                ax.plot(
                    f,
                    _db(data.G[q, :, i, j]),
                    color=c,
                    lw=0.6,
                    ls="",
                    marker=".",
                    ms=1.5,
                    gid=f"measured/{q}",
                )
                ax.plot(f, _db(data.sigma[q, :, i, j]), color=c, lw=0.8, ls=":", gid=f"sigma/{q}")
            ax.set_title(_channel(out_names[i], in_names[j]), fontsize="medium")
            ax.set_xscale(_frequency_scale(f))
            ax.set_xlim(f.min(), f.max())
            ax.grid(True, alpha=0.3)
            if j == 0:
                ax.set_ylabel("magnitude [dB]")
    for ax in axes[-1]:
        ax.set_xlabel("frequency [Hz]")
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    handles = [
        Line2D([], [], color="0.3", lw=1.0, label="model $G_m$"),
        Patch(color="0.3", alpha=0.3, label=f"{level:.0%} band"),
        Line2D([], [], color="0.3", ls="", marker=".", label="measured $G$"),
        Line2D([], [], color="0.3", ls=":", label=r"$\sigma$ of $G$"),
    ]
    fig.legend(handles=handles, loc="outside right upper", fontsize="small", frameon=False)
    order = np.argsort(p if p.ndim == 1 else p[:, 0], kind="stable")
    fig.legend(
        handles=[Line2D([], [], color=colours[k], lw=2, label=_point_label(p[k])) for k in order],
        loc="outside right lower",
        fontsize="small",
        title=_pretty(p_label),
        title_fontsize="small",
        frameon=False,
    )
    if title:
        fig.suptitle(title)
    return fig


def frf_std_map(
    cov: Covariance,
    freqs_hz: ArrayLike,
    p: ArrayLike,
    *,
    output: int = 0,
    input: int = 0,
    level: float = 0.95,
    p_marks: ArrayLike | None = None,
    p_label: str = "scheduling p",
    title: str | None = None,
    fig: Figure | None = None,
) -> Figure:
    """The band radius relative to the model FRF over frequency and scheduling.

    A colour map of ``20 log10(band_radius(level) * sigma / |G_m|)``: -20 dB
    means the model FRF is known to within 10 % (at ``level``). Marks at the
    measured points show how the uncertainty grows between them.

    Parameters
    ----------
    cov : Covariance
        The covariance of the model (one scheduling parameter).
    freqs_hz : array_like, shape (F,)
        Frequencies in Hz, increasing.
    p : array_like, shape (P,)
        Scheduling values, increasing (drawn on a log axis for a basis on
        the log scale).
    output, input : int
        Which output and input (0-based).
    level : float
        Coverage of the band.
    p_marks : array_like, optional
        Scheduling values to mark, e.g. the identification points.
    p_label : str
        Axis label of the scheduling parameter.
    title : str, optional
        Figure title.
    fig : Figure, optional
        Draw into this figure (cleared first).

    Returns
    -------
    matplotlib.figure.Figure
        The map carries gid ``"relative-band"`` (values in dB, shape (P, F)).
    """
    cov = _check_cov(cov)
    model = cov.model
    if model.basis.n_params != 1:
        raise ValueError("cov: the map needs a model with one scheduling parameter")
    f = real_array(freqs_hz, "freqs_hz", ndim=1)
    pp = real_array(p, "p", ndim=1)
    for arr, name in ((f, "freqs_hz"), (pp, "p")):
        if arr.size < 2 or np.any(np.diff(arr) <= 0):
            raise ValueError(f"{name}: expected at least two strictly increasing values")
    for value, count, name in (
        (output, model.n_outputs, "output"),
        (input, model.n_inputs, "input"),
    ):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
            raise TypeError(f"{name}: expected an int, got {type(value).__name__}")
        if not 0 <= value < count:
            raise ValueError(f"{name}: expected 0 <= {name} < {count}, got {value}")
    plt = _pyplot()
    G = model.frf(f, pp)[:, :, output, input]
    rel = band_radius(level) * cov.frf_std(f, pp)[:, :, output, input] / np.abs(G)
    values = _db(rel)
    fig = _figure(plt, fig, (6.8, 3.4))
    ax = fig.subplots()
    mesh = ax.pcolormesh(
        f, pp, values, shading="gouraud", cmap="magma", rasterized=True, gid="relative-band"
    )
    bar = fig.colorbar(mesh, ax=ax, pad=0.01)
    bar.set_label(f"{level:.0%} band / |G_m| [dB]")
    if p_marks is not None:
        for m in real_array(p_marks, "p_marks").ravel():
            ax.axhline(m, color="white", lw=0.6, ls="--", alpha=0.8)
    ax.set_xscale(_frequency_scale(f))
    ax.set_yscale(model.basis.scales[0])  # the scheduling on the basis's scale
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel(_pretty(p_label))
    if title:
        fig.suptitle(title)
    return fig
