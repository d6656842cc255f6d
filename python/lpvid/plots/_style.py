"""Shared pieces of the figures: matplotlib on demand, styles, labels, colours."""

from __future__ import annotations

import os
import re
import sys
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from lpvid.model.lpv import LpvModel

if TYPE_CHECKING:
    from matplotlib.figure import Figure

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
