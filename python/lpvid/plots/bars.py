"""Relative group magnitudes of models, per matrix and basis function."""

from __future__ import annotations

import re
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from lpvid.model.layout import MATRICES
from lpvid.model.lpv import LpvModel
from lpvid.plots._style import _check_model, _figure, _pyplot

if TYPE_CHECKING:
    from matplotlib.figure import Figure

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
