"""Accuracy against simplicity along an l2,1 path."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lpvid._checks import real_array
from lpvid.plots._style import _figure, _pyplot

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure


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
        (kept,) = twin.plot(
            g,
            groups[pos],
            color="0.45",
            lw=0.9,
            marker="d",
            ms=4,
            label="groups kept (right axis)",
            gid="groups-gamma",
        )
        # drawn by the right panel, so that it is placed clear of its V_NLS lines
        right.legend(handles=[kept], fontsize="small", loc="best")
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
