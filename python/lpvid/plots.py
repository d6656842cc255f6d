"""Figures for papers and reports (matplotlib, an optional extra).

Every function returns the :class:`matplotlib.figure.Figure` it drew, so
that it can be shown (``plt.show()``), adjusted or written with
:func:`save`. matplotlib is imported only when a figure is drawn; install it
with ``pip install "lpvid[plot]"``. Without a display (a server, CI) the
non-interactive Agg backend is selected, unless a backend was chosen already.

Each curve and surface carries a ``gid`` naming what it shows (for example
``"model/2"`` for the model FRF at the third point), so that scripts and
tests can find it again.

Functions
---------
frf_fit
    Measured FRF, model FRF, error ``|G - Gm|`` and sigma against frequency
    (the paper's Figs. 2, 5 and 8).
magnitude_surface
    Magnitude and phase of the model over frequency and scheduling (Figs. 3
    and 7).
group_norms
    Relative group magnitudes of one or several models, per matrix and basis
    function.
accuracy_path
    Accuracy against simplicity along an l2,1 path.
save
    Write a figure to PNG or SVG, whole or not at all.
"""

from __future__ import annotations

import os
import re
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lpvid._checks import real_array
from lpvid._files import write_atomic
from lpvid.data import FrfData
from lpvid.layout import MATRICES
from lpvid.model import LpvModel

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = ["accuracy_path", "frf_fit", "group_norms", "magnitude_surface", "save"]

_INSTALL = 'lpvid.plots needs matplotlib, an optional extra: pip install "lpvid[plot]"'

#: Line styles of the four kinds of curve in :func:`frf_fit`.
_KINDS: dict[str, dict[str, Any]] = {
    "measured": {"ls": "-", "lw": 1.3, "alpha": 1.0, "zorder": 2.2, "label": "measured $G$"},
    "model": {"ls": "--", "lw": 1.0, "alpha": 1.0, "zorder": 2.4, "label": "model $G_m$"},
    "error": {"ls": "-", "lw": 0.6, "alpha": 0.5, "zorder": 2.0, "label": r"error $|G - G_m|$"},
    "sigma": {"ls": ":", "lw": 1.4, "alpha": 1.0, "zorder": 2.3, "label": r"$\sigma$"},
}


def _pyplot() -> Any:
    """Import ``matplotlib.pyplot``, choosing Agg when there is no display."""
    try:
        import matplotlib
    except ImportError as exc:
        raise ImportError(_INSTALL) from exc
    headless = sys.platform.startswith("linux") and not (
        os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
    )
    if headless and "MPLBACKEND" not in os.environ and "matplotlib.pyplot" not in sys.modules:
        matplotlib.use("Agg")
    try:
        import matplotlib.pyplot as plt
    except ImportError as exc:
        raise ImportError(_INSTALL) from exc
    return plt


def _figure(plt: Any, fig: Figure | None, size: tuple[float, float]) -> Figure:
    """A new figure of the given size, or ``fig`` cleared (keeping its size)."""
    if fig is None:
        return plt.figure(figsize=size, layout="constrained")
    from matplotlib.figure import Figure as _Figure

    if not isinstance(fig, _Figure):
        raise TypeError(f"fig: expected a matplotlib Figure, got {type(fig).__name__}")
    fig.clear()
    fig.set_layout_engine("constrained")
    return fig


def _db(x: NDArray[Any]) -> NDArray[np.float64]:
    """``20 log10 |x|``; exact zeros become NaN (a gap in the curve)."""
    a = np.abs(x)
    out = np.full(a.shape, np.nan)
    np.log10(a, out=out, where=a > 0)
    return 20.0 * out


def _names(value: Any, count: int, default: str, name: str) -> list[str]:
    """Channel names: ``value`` checked against ``count``, or numbered defaults."""
    if value is None:
        return [f"{default} {k + 1}" for k in range(count)]
    if isinstance(value, str):
        value = [value]
    names = [_pretty(str(v)) for v in value]
    if len(names) != count:
        raise ValueError(f"{name}: expected {count} names, got {len(names)}")
    return names


_SUPERSCRIPT = str.maketrans(
    "-0123456789", "\u207b\u2070\u00b9\u00b2\u00b3\u2074\u2075\u2076\u2077\u2078\u2079"
)


def _pretty(label: str) -> str:
    """Units as typeset: ``m/s^2`` -> ``m/s\u00b2`` (labels with ``$`` are left alone)."""
    if "$" in label:
        return label
    return re.sub(r"\^(-?\d+)", lambda m: m.group(1).translate(_SUPERSCRIPT), label)


def _channel(output: str, input: str, width: int = 40) -> str:
    """``"<output> per <input>"``, on two lines when long."""
    text = f"{output} per {input}"
    return text if len(text) <= width else f"{output}\nper {input}"


def _point_label(p: NDArray[np.float64]) -> str:
    if p.ndim == 0 or p.size == 1:
        return f"{float(p.ravel()[0]):.4g}"
    return "(" + ", ".join(f"{v:.3g}" for v in p) + ")"


def _point_colours(p: NDArray[np.float64]) -> list[Any]:
    """One colour per point, ordered along the (first) scheduling parameter."""
    from matplotlib import colormaps

    n = p.shape[0]
    key = p if p.ndim == 1 else p[:, 0]
    rank = np.empty(n, dtype=int)
    rank[np.argsort(key, kind="stable")] = np.arange(n)
    cmap = colormaps["viridis"]
    if n == 1:
        return [cmap(0.0)]
    return [cmap(0.88 * r / (n - 1)) for r in rank]


def _phase(g: NDArray[np.complex128]) -> NDArray[np.float64]:
    """Phase in degrees, unwrapped along the last axis (frequency)."""
    return np.degrees(np.unwrap(np.angle(g), axis=-1))


def _degree_ticks(axis: Any, lo: float, hi: float) -> None:
    """Put phase ticks on multiples of 45, 90, 180, ... degrees."""
    from matplotlib.ticker import MultipleLocator

    span = max(float(hi - lo), 1.0)
    step = next((s for s in (45, 90, 180, 360, 720, 1440) if span / s <= 6), 2880)
    axis.set_major_locator(MultipleLocator(step))


def _frequency_scale(freqs: NDArray[np.float64]) -> str:
    lo, hi = float(freqs.min()), float(freqs.max())
    return "log" if lo > 0 and hi / lo >= 20 else "linear"


def _check_model(model: Any, name: str = "model") -> LpvModel:
    if not isinstance(model, LpvModel):
        raise TypeError(f"{name}: expected an lpvid.LpvModel, got {type(model).__name__}")
    return model


# ---------------------------------------------------------------------------- FRF fit
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
    model = _check_model(model)
    if not isinstance(data, FrfData):
        raise TypeError(f"data: expected an lpvid.FrfData, got {type(data).__name__}")
    if (model.n_outputs, model.n_inputs) != (data.n_outputs, data.n_inputs):
        raise ValueError(
            f"data: {data.n_outputs} outputs x {data.n_inputs} inputs, but the model has "
            f"{model.n_outputs} x {model.n_inputs}"
        )
    if model.Ts != data.Ts:
        raise ValueError(f"data: sample time Ts={data.Ts} differs from the model's Ts={model.Ts}")
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


# ------------------------------------------------------------------------ surface
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
        Scheduling values, increasing, e.g. ``np.linspace(lo, hi, 60)``.
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


# -------------------------------------------------------------------- group norms
_MONOMIAL = re.compile(r"([A-Za-z])(\d*)(?:\^(\d+))?")


def _power(x: float) -> str:
    """``1e-06`` -> ``$10^{-6}$``; other numbers in ``%g``."""
    e = np.log10(x)
    return f"$10^{{{int(round(e))}}}$" if abs(e - round(e)) < 1e-9 else f"{x:g}"


def _tick(name: str) -> str:
    r"""A basis function name as a tick label: ``s1^2*s2`` -> ``$s_{1}^{2}\,s_{2}$``."""
    factors = name.split("*")
    parts = [_MONOMIAL.fullmatch(f) for f in factors]
    if not all(parts):
        return name
    out = []
    for m in parts:
        assert m is not None
        var, sub, sup = m.groups()
        out.append(var + (f"_{{{sub}}}" if sub else "") + (f"^{{{sup}}}" if sup else ""))
    return "$" + r"\,".join(out) + "$"


def group_norms(
    models: LpvModel | Mapping[str, LpvModel],
    p_range: Any = None,
    *,
    floor: float = 1e-12,
    threshold: float = 1e-6,
    title: str | None = None,
    fig: Figure | None = None,
) -> Figure:
    """Relative group magnitudes of one or several models, as grouped bars.

    One panel per matrix A, B, C, D; in each, one group of bars per basis
    function and one bar per model, on a log scale: the magnitude of
    ``theta_X(i)`` times ``||psi_i||_inf`` relative to ``||theta_X(0)||``
    (the right-hand side of the paper's Tables 1-4). Groups below the
    threshold count as removed; values below ``floor`` (exact zeros
    included) are drawn at the floor.

    Parameters
    ----------
    models : LpvModel or mapping of str to LpvModel
        E.g. ``{"SMILE": model0, "chosen": model}``; all with the same
        number of basis functions.
    p_range : (lo, hi), optional
        Scheduling range for ``||psi_i||_inf``; default each model's own.
    floor : float
        Smallest value drawn (> 0).
    threshold : float
        Relative magnitude under which a group counts as removed, drawn as
        a horizontal line.
    title : str, optional
        Figure title.
    fig : Figure, optional
        Draw into this figure (cleared first) instead of a new one.

    Returns
    -------
    matplotlib.figure.Figure
        Four axes (A, B, C, D); in each, one bar container per model, in
        the order given, with bar ``i`` of height ``max(relative, floor)``.

    Raises
    ------
    ValueError
        When no model is given, the models differ in their number of basis
        functions, they have no basis functions, or ``floor`` is not
        positive.
    ImportError
        When matplotlib is not installed.

    """
    if isinstance(models, LpvModel):
        models = {"model": models}
    if not isinstance(models, Mapping) or not models:
        raise ValueError("models: expected an LpvModel or a non-empty dict name -> LpvModel")
    for name, m in models.items():
        _check_model(m, f"models[{name!r}]")
    nbs = {m.n_basis for m in models.values()}
    if len(nbs) != 1:
        raise ValueError(f"models: the models differ in their number of basis functions {nbs}")
    nb = nbs.pop()
    if nb == 0:
        raise ValueError("models: LTI models (no basis function) have no groups to draw")
    if not (np.isfinite(floor) and floor > 0):
        raise ValueError(f"floor: expected a positive number, got {floor}")
    if not (np.isfinite(threshold) and threshold > 0):
        raise ValueError(f"threshold: expected a positive number, got {threshold}")
    norms = {name: m.group_norms(p_range) for name, m in models.items()}

    plt = _pyplot()
    names = next(iter(norms.values())).names
    n_models = len(norms)
    fig = _figure(plt, fig, (min(2.2 + 1.9 * nb, 12.0) + 1.5, 3.4))
    axes = fig.subplots(1, 4, sharey=True)
    width = 0.8 / n_models
    x = np.arange(nb)
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    top = floor
    for k, (ax, mat) in enumerate(zip(axes, MATRICES, strict=True)):
        for j, (name, g) in enumerate(norms.items()):
            heights = np.maximum(g.relative[k], floor)
            top = max(top, float(heights.max()))
            ax.bar(
                x + (j - (n_models - 1) / 2) * width,
                heights,
                width=width,
                color=colours[j % len(colours)],
                label=name,
                gid=f"{mat}/{name}",
            )
        cut = f"threshold {_power(threshold)}"
        ax.axhline(threshold, color="crimson", lw=1.0, ls="--", label=cut)
        ax.set_xticks(x, [_tick(s) for s in names])
        ax.set_title(mat)
        ax.set_xlim(-0.6, nb - 0.4)
        ax.grid(True, axis="y", which="major", alpha=0.3)
    axes[0].set_yscale("log")
    axes[0].set_ylim(floor / 10, max(top, threshold) * 10)
    axes[0].set_ylabel(r"$\|\theta_X(i)\|\,\|\psi_i\|_\infty / \|\theta_X(0)\|$")
    fig.supxlabel("basis function $\\psi_i$", fontsize="medium")
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside right upper", fontsize="small", frameon=False)
    if title:
        fig.suptitle(title)
    return fig


# -------------------------------------------------------------------- path curve
def _path_rows(path: Any) -> list[Any]:
    rows = getattr(path, "results", path)
    try:
        rows = list(rows)
    except TypeError as exc:
        raise TypeError(
            f"path: expected a PathResult or a sequence of path entries, got {type(path).__name__}"
        ) from exc
    if not rows:
        raise ValueError("path: holds no model")
    for r in rows:
        if not all(hasattr(r, a) for a in ("gamma", "vnls", "n_groups")):
            raise TypeError(
                f"path: each entry needs .gamma, .vnls and .n_groups (got {type(r).__name__})"
            )
    return rows


def _floors(value: Any, rows: list[Any], attr: str, name: str) -> NDArray[np.float64] | None:
    """Noise floors: ``value`` (one number or one per row), or each row's ``attr``."""
    if value is None:
        got = [getattr(r, attr, None) for r in rows]
        if any(g is None for g in got):
            return None
        value = got
    v = real_array(value, name, ndim=(0, 1))
    v = np.broadcast_to(v, (len(rows),)) if v.ndim == 0 else v
    if v.shape != (len(rows),):
        raise ValueError(f"{name}: expected one number or {len(rows)}, got {v.shape[0]}")
    if np.any(v <= 0):
        raise ValueError(f"{name}: noise floors must be > 0")
    return np.asarray(v, dtype=float)


def accuracy_path(
    path: Any,
    validation_vnls: ArrayLike | None = None,
    chosen: int | None = None,
    noise_floor: ArrayLike | None = None,
    *,
    validation_floor: ArrayLike | None = None,
    title: str | None = None,
    fig: Figure | None = None,
    ax: Axes | None = None,
) -> Figure:
    """Accuracy against simplicity along an l2,1 path.

    Left: V_NLS relative to its noise floor against the number of groups
    kept, for the identification data and, when given, the validation
    data; a ratio of 1 is a fit to the noise. Right: the same against
    gamma, with the number of groups on a second axis (omitted when ``ax``
    is given). The chosen model is ringed in both.

    Parameters
    ----------
    path : PathResult or sequence of entries
        What :func:`lpvid.l21_path` returned, or any sequence of objects
        with ``.gamma``, ``.vnls``, ``.n_groups`` and ``.noise_floor``,
        such as ``IdentifyResult.entries`` (whose ``.validation_vnls`` and
        ``.validation_floor`` are then used when not given here). Entries
        with ``gamma <= 0`` (the unregularised model) appear only in the
        left panel.
    validation_vnls : array_like, optional
        V_NLS on validation data, one per entry of ``path`` (NaN to skip).
    chosen : int, optional
        Index of the chosen model in ``path``.
    noise_floor : float or array_like, optional
        Noise floor of the identification data; default each entry's
        ``.noise_floor``.
    validation_floor : float or array_like, optional
        Noise floor of the validation data (``validation.n_residuals``);
        needed with ``validation_vnls`` unless the entries carry it.
    title : str, optional
        Figure title.
    fig : Figure, optional
        Draw into this figure (cleared first) instead of a new one.
    ax : Axes, optional
        Draw only the left panel, into these axes.

    Returns
    -------
    matplotlib.figure.Figure
        Lines with gid ``"identification"`` (x: groups kept, y: V_NLS /
        floor), ``"validation"``, ``"chosen"`` and, in the gamma panel,
        ``"identification-gamma"``, ``"validation-gamma"``, ``"groups-gamma"``
        (and ``"chosen-gamma"``). Points follow the path: gamma
        decreasing, an unregularised model (gamma = 0) last.

    Raises
    ------
    ValueError
        When lengths disagree, a floor is missing or not positive, or
        ``chosen`` is out of range.
    ImportError
        When matplotlib is not installed.

    """
    rows = _path_rows(path)
    n = len(rows)
    gammas = np.array([float(r.gamma) for r in rows])
    vn = np.array([float(r.vnls) for r in rows])
    groups = np.array([int(r.n_groups) for r in rows])
    floor = _floors(noise_floor, rows, "noise_floor", "noise_floor")
    if floor is None:
        raise ValueError("noise_floor: the path entries carry none; pass noise_floor")
    ratio = vn / floor
    val = None
    if validation_vnls is None and all(
        getattr(r, "validation_vnls", None) is not None for r in rows
    ):
        validation_vnls = [r.validation_vnls for r in rows]
    if validation_vnls is not None:
        v = np.asarray(validation_vnls, dtype=float).ravel()
        if v.shape != (n,):
            raise ValueError(f"validation_vnls: expected {n} values (one per entry), got {v.size}")
        vfloor = _floors(validation_floor, rows, "validation_floor", "validation_floor")
        if vfloor is None:
            raise ValueError(
                "validation_floor: needed with validation_vnls (the validation data's n_residuals)"
            )
        val = v / vfloor
    if chosen is not None:
        if isinstance(chosen, bool) or not isinstance(chosen, (int, np.integer)):
            raise TypeError(f"chosen: expected an int, got {type(chosen).__name__}")
        if not -n <= chosen < n:
            raise ValueError(f"chosen: expected an index into {n} entries, got {chosen}")
        chosen = int(chosen) % n

    # Draw in path order: gamma decreasing, the unregularised model (gamma = 0) last.
    order = np.argsort(-np.where(gammas > 0, gammas, -np.inf), kind="stable")
    plt = _pyplot()
    if ax is not None:
        fig = ax.figure
        left, right = ax, None
    else:
        fig = _figure(plt, fig, (9.5, 3.6))
        left, right = fig.subplots(1, 2)
    ident = {"color": "C0", "marker": "o", "ms": 5, "lw": 1.2}
    valid = {"color": "C1", "marker": "s", "ms": 5, "lw": 1.2, "ls": "--"}
    ring = {"marker": "o", "ms": 13, "mfc": "none", "mec": "crimson", "mew": 1.6, "ls": "none"}
    ylabel = r"$V_\mathrm{NLS}$ / noise floor"
    left.plot(groups[order], ratio[order], label="identification", gid="identification", **ident)
    if val is not None:
        left.plot(groups[order], val[order], label="validation", gid="validation", **valid)
    left.axhline(1.0, color="0.4", lw=0.9, ls=":", label="noise floor")
    if chosen is not None:
        ys = [ratio[chosen]] + ([val[chosen]] if val is not None else [])
        left.plot([groups[chosen]] * len(ys), ys, label="chosen", gid="chosen", **ring)
    for k in np.flatnonzero(gammas <= 0):
        left.annotate(
            r"$\gamma = 0$",
            (groups[k], ratio[k]),
            xytext=(-4, 7),
            textcoords="offset points",
            ha="right",
            fontsize="small",
            color="0.3",
        )
    left.set_xlabel("groups kept")
    left.set_ylabel(ylabel)
    left.xaxis.get_major_locator().set_params(integer=True)
    left.grid(True, alpha=0.3)
    left.legend(fontsize="small")
    pos = order[gammas[order] > 0]
    if right is not None and pos.size:
        g = gammas[pos]
        right.plot(g, ratio[pos], gid="identification-gamma", **ident)
        if val is not None:
            right.plot(g, val[pos], gid="validation-gamma", **valid)
        right.axhline(1.0, color="0.4", lw=0.9, ls=":")
        if chosen is not None and gammas[chosen] > 0:
            ys = [ratio[chosen]] + ([val[chosen]] if val is not None else [])
            right.plot([gammas[chosen]] * len(ys), ys, gid="chosen-gamma", **ring)
        right.set_xscale("log")
        right.invert_xaxis()  # more groups to the right, as in the left panel
        right.set_xlabel(r"regularisation weight $\gamma$")
        right.set_ylabel(ylabel)
        right.grid(True, alpha=0.3)
        twin = right.twinx()
        twin.plot(
            g,
            groups[pos],
            color="0.45",
            lw=0.9,
            marker="d",
            ms=4,
            label="groups kept",
            gid="groups-gamma",
        )
        twin.set_ylabel("groups kept", color="0.35")
        twin.tick_params(axis="y", colors="0.35")
        twin.yaxis.get_major_locator().set_params(integer=True)
        twin.set_ylim(0, int(groups[pos].max()) + 1)
    elif right is not None:
        right.set_axis_off()
        right.text(0.5, 0.5, r"no model with $\gamma > 0$", ha="center", transform=right.transAxes)
    if title:
        fig.suptitle(title)
    return fig


# ---------------------------------------------------------------------------- save
def save(fig: Figure, path: str | os.PathLike[str], *, dpi: int = 150) -> Path:
    """Write a figure to a PNG or SVG file, whole or not at all, and close it.

    Parameters
    ----------
    fig : Figure
        The figure; closed afterwards (also when writing fails).
    path : str or path-like
        Target file; its suffix ``.png`` or ``.svg`` chooses the format.
    dpi : int
        Resolution of PNG files.

    Returns
    -------
    pathlib.Path
        The path written.

    Raises
    ------
    ValueError
        When the suffix is neither ``.png`` nor ``.svg``.
    ImportError
        When matplotlib is not installed.

    """
    target = Path(path)
    fmt = target.suffix.lower().lstrip(".")
    if fmt not in ("png", "svg"):
        raise ValueError(f"path: expected a .png or .svg file, got {str(path)!r}")
    plt = _pyplot()
    from matplotlib.figure import Figure as _Figure

    if not isinstance(fig, _Figure):
        raise TypeError(f"fig: expected a matplotlib Figure, got {type(fig).__name__}")
    try:
        return write_atomic(
            target, lambda fh: fig.savefig(fh, format=fmt, dpi=dpi, metadata=_metadata(fmt))
        )
    finally:
        plt.close(fig)


def _metadata(fmt: str) -> dict[str, Any]:
    """No creation date in the files, so that the same figure gives the same bytes."""
    return {"Software": "lpvid"} if fmt == "png" else {"Date": None, "Creator": "lpvid"}
