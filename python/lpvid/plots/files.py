"""Writing figures to PNG or SVG, whole or not at all."""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

from lpvid._files import write_atomic
from lpvid.plots._style import _pyplot

if TYPE_CHECKING:
    from matplotlib.figure import Figure


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
            target,
            lambda fh: fig.savefig(
                fh, format=fmt, dpi=dpi, metadata=_metadata(fmt), **_encoder(fmt)
            ),
        )
    finally:
        plt.close(fig)


def _metadata(fmt: str) -> dict[str, Any]:
    """No creation date in the files, so that the same figure gives the same bytes."""
    return {"Software": "lpvid"} if fmt == "png" else {"Date": None, "Creator": "lpvid"}


def _encoder(fmt: str) -> dict[str, Any]:
    """PNG at zlib level 1: encoding a report's figures took 0.55 s of 3.6 s at level 6.

    The pixels are the same; the files are about 15 % larger.
    """
    return {"pil_kwargs": {"compress_level": 1}} if fmt == "png" else {}
