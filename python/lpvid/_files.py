"""Files: written whole or not at all, and read with one answer to damage."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

import numpy as np


def write_atomic(path: str | os.PathLike[str], write: Callable[[IO[bytes]], None]) -> Path:
    """Write a file through ``write`` into a temporary file, then rename it.

    The rename is atomic on the same file system, so a reader sees either the
    old file or the complete new one, never a partial write.
    """
    target = Path(path)
    directory = target.parent if str(target.parent) else Path(".")
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=directory)
    try:
        # mkstemp makes the file private (0600); give it the mode a plain
        # open() would, so that others can read what lpvid writes.
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        with os.fdopen(fd, "wb") as fh:
            write(fh)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, target)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise
    return target


def mat_variables(path: str | os.PathLike[str]) -> dict[str, Any]:
    """The variables of a MATLAB file (``__``-names left out), or a ValueError naming it.

    scipy answers a damaged file with many kinds of exception (IndexError,
    EOFError, struct.error, ...); they all become one ValueError here, the
    original chained.
    """
    from scipy.io import loadmat

    p = Path(path)
    try:
        raw = loadmat(p)
    except NotImplementedError as exc:  # scipy's answer to -v7.3 files
        raise ValueError(f"{p.name}: a MATLAB -v7.3 (HDF5) file; save it with -v7") from exc
    except Exception as exc:
        raise ValueError(
            f"{p.name}: not a readable .mat file ({type(exc).__name__}: {exc})"
        ) from exc
    return {k: v for k, v in raw.items() if not k.startswith("__")}


def npz_arrays(path: str | os.PathLike[str]) -> dict[str, Any]:
    """The arrays of a ``.npz`` file (no pickles), or a ValueError naming it."""
    p = Path(path)
    try:
        # opened here: np.load leaves a file it opened open when it is no zip file
        with open(p, "rb") as fh, np.load(fh, allow_pickle=False) as f:
            return {k: f[k] for k in f.files}
    except Exception as exc:
        raise ValueError(
            f"{p.name}: not a readable .npz file ({type(exc).__name__}: {exc})"
        ) from exc
