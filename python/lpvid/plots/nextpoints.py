"""Where to measure next: the band over the scheduling range, measured and suggested points."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from lpvid.experiment.nextpoints import Suggestion
from lpvid.plots._style import _figure, _pretty, _pyplot

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def suggested_points(
    suggestion: Suggestion,
    *,
    p_label: str = "scheduling p",
    title: str | None = None,
    fig: Figure | None = None,
) -> Figure:
    """The relative 95 % band over the scheduling range now and after the suggested points.

    One scheduling parameter: the band against ``p`` (log scale), now
    (solid) and predicted once the suggested points are measured (dashed),
    the measured points as triangles on the axis and the suggested ones as
    numbered stars on the band. Two parameters: the two bands as colour
    maps over the range (one colour scale) with the measured points as
    white dots and the suggested ones as numbered stars.

    Parameters
    ----------
    suggestion : Suggestion
        From :func:`lpvid.suggest_points`.
    p_label : str
        Name (and unit) of the scheduling parameter(s), e.g. ``"load [kg]"``;
        for two parameters, the two names separated by a comma.
    title : str, optional
        Figure title.
    fig : Figure, optional
        Draw into this figure (cleared first).

    Returns
    -------
    matplotlib.figure.Figure
        Curves or maps with gid ``"band"`` and ``"band-after"``, markers
        ``"measured"`` and ``"suggested"``.
    """
    if not isinstance(suggestion, Suggestion):
        raise TypeError(
            f"suggestion: expected an lpvid.Suggestion, got {type(suggestion).__name__}"
        )
    n_params = 1 if suggestion.grid.ndim == 1 else suggestion.grid.shape[1]
    if n_params > 2:
        raise ValueError(
            f"suggestion: the figure shows one or two scheduling parameters, this one has "
            f"{n_params} (Suggestion.summary() lists the points)"
        )
    plt = _pyplot()
    if n_params == 1:
        fig = _figure(plt, fig, (6.4, 3.4))
        _one(fig.subplots(), suggestion, _pretty(p_label))
    else:
        fig = _figure(plt, fig, (9.6, 4.0))
        _two(fig, suggestion, p_label)
    if title:
        fig.suptitle(title)
    return fig


def _percent(x: Any) -> Any:
    return 100.0 * np.asarray(x)


def _one(ax: Any, s: Suggestion, label: str) -> None:
    p = s.grid
    ax.plot(p, _percent(s.band), color="C0", lw=1.4, label="now", gid="band")
    ax.plot(
        p,
        _percent(s.band_after),
        color="C0",
        lw=1.2,
        ls="--",
        label=f"after the {len(s.points)} suggested point(s)",
        gid="band-after",
    )
    ax.set_yscale("log")
    lo = float(np.min(_percent(np.concatenate([s.band, s.band_after]))))
    ax.plot(
        s.measured,
        np.full(len(s.measured), lo),
        ls="",
        marker="^",
        ms=8,
        color="0.2",
        label="measured",
        gid="measured",
        clip_on=False,
    )
    at = np.interp(s.points, p, _percent(s.band))
    ax.plot(s.points, at, ls="", marker="*", ms=13, color="C3", label="suggested", gid="suggested")
    for k, (x, y) in enumerate(zip(s.points, at, strict=True)):
        ax.annotate(str(k + 1), (x, y), xytext=(4, 6), textcoords="offset points", color="C3")
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    ax.yaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
    ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    ax.yaxis.set_minor_formatter(NullFormatter())
    ax.set_xlabel(label)
    ax.set_ylabel("95 % band / ||G_m|| [%]")
    ax.set_xlim(p.min(), p.max())
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize="small", frameon=False)


def _two(fig: Any, s: Suggestion, p_label: str) -> None:
    names = [_pretty(x.strip()) for x in p_label.split(",")]
    if len(names) != 2:
        names = [f"{_pretty(p_label)} 1", f"{_pretty(p_label)} 2"]
    g = s.grid
    n0 = int(np.sum(g[:, 1] == g[0, 1]))  # values along the first parameter
    shape = (n0, len(g) // n0)
    x, y = g[:, 0].reshape(shape), g[:, 1].reshape(shape)
    values = [_percent(s.band), _percent(s.band_after)]
    lo = float(np.min([v.min() for v in values]))
    hi = float(np.max([v.max() for v in values]))
    from matplotlib.colors import LogNorm

    norm = LogNorm(vmin=max(lo, hi * 1e-6), vmax=hi) if lo > 0 else None
    axes = fig.subplots(1, 2, sharey=True)
    titles = ["now", f"after the {len(s.points)} suggested point(s)"]
    for ax, v, gid, text in zip(axes, values, ("band", "band-after"), titles, strict=True):
        mesh = ax.pcolormesh(
            x,
            y,
            v.reshape(shape),
            shading="gouraud",
            cmap="magma",
            norm=norm,
            gid=gid,
            rasterized=True,
        )
        for pts, gid, style in (
            (s.measured, "measured", {"marker": "o", "ms": 6, "mfc": "white", "mec": "0.2"}),
            (s.points, "suggested", {"marker": "*", "ms": 14, "color": "C2", "mec": "white"}),
        ):
            ax.plot(*pts.T, ls="", gid=gid, clip_on=False, **style)
        for k, pt in enumerate(s.points):
            ax.annotate(str(k + 1), pt, xytext=(5, 5), textcoords="offset points", color="white")
        ax.set_title(text, fontsize="medium")
        ax.set_xlabel(names[0])
    axes[0].set_ylabel(names[1])
    bar = fig.colorbar(mesh, ax=list(axes), pad=0.01)
    bar.set_label("95 % band / ||G_m|| [%]")
