"""Files: written whole or not at all, and read with one answer to damage."""

from __future__ import annotations

import ctypes
import errno
import io
import os
import shutil
import tempfile
from collections.abc import Callable, Collection
from pathlib import Path
from typing import IO, Any, TypeVar

import numpy as np

T = TypeVar("T")


def _public_mode(path: str) -> None:
    """Give a file or folder made private by tempfile the mode a plain open() or mkdir() would."""
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(path, (0o777 if os.path.isdir(path) else 0o666) & ~umask)


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
        _public_mode(tmp)
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


def write_mat(path: str | os.PathLike[str], variables: dict[str, Any]) -> Path:
    """``variables`` as a compressed MATLAB file, written whole or not at all."""
    from scipy.io import savemat

    return write_atomic(path, lambda fh: savemat(fh, variables, do_compression=True))


def write_npz(path: str | os.PathLike[str], arrays: dict[str, Any]) -> Path:
    """``arrays`` as a numpy ``.npz`` file, written whole or not at all."""
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return write_atomic(path, lambda fh: fh.write(buf.getvalue()))


def check_replaceable(path: Path, names: Collection[str]) -> None:
    """FileExistsError unless ``path`` is missing or a folder holding only entries in ``names``."""
    if path.exists() and not path.is_dir():
        raise FileExistsError(f"{path} exists and is not a folder")
    if not path.is_dir():
        return
    here = Path.cwd()
    if path.resolve() in (here, *here.parents):
        raise FileExistsError(f"{path} is the current folder or holds it: it cannot be replaced")
    foreign = sorted(e.name for e in path.iterdir() if e.name not in names)
    if foreign:
        raise FileExistsError(
            f"{path} holds files that lpvid does not write ({', '.join(foreign[:3])}"
            f"{', ...' if len(foreign) > 3 else ''}); the new folder would replace it whole: "
            "choose another folder or remove them"
        )


def _exchange(a: Path, b: Path) -> bool:
    """Swap two paths in one step (Linux ``renameat2``); False where that is not supported."""
    try:
        renameat2 = ctypes.CDLL(None, use_errno=True).renameat2
    except (OSError, AttributeError, TypeError):  # not Linux, or an old C library
        return False
    at_fdcwd, rename_exchange = -100, 2
    if renameat2(at_fdcwd, os.fsencode(a), at_fdcwd, os.fsencode(b), rename_exchange) == 0:
        return True
    code = ctypes.get_errno()
    if code in (errno.ENOSYS, errno.EINVAL, errno.EOPNOTSUPP):  # a file system without it
        return False
    raise OSError(code, os.strerror(code), str(b))


def write_folder_atomic(
    path: str | os.PathLike[str], write: Callable[[Path], T], replaceable: Collection[str]
) -> T:
    """Fill a folder through ``write(folder)`` beside ``path``, then put it in place whole.

    ``write`` fills a temporary sibling folder; only when it returns is the
    folder moved to ``path``, so ``path`` holds a complete result or nothing
    new: an error or Ctrl-C while writing removes the temporary folder and
    leaves ``path`` as it was. A folder already at ``path`` is replaced when
    the new one is complete, and only when it holds nothing but entries
    named in ``replaceable`` (an earlier result: anything else would be
    lost; FileExistsError then, before ``write`` runs). On Linux the two
    folders are exchanged in one step; elsewhere the old one is moved aside
    first, so ``path`` is missing for the moment between two renames.
    """
    target = Path(path)
    check_replaceable(target, replaceable)
    parent = target.parent if str(target.parent) else Path(".")
    parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".tmp", dir=parent))
    try:
        _public_mode(str(tmp))
        out = write(tmp)
        if not target.exists():
            os.rename(tmp, target)
        elif _exchange(tmp, target):
            shutil.rmtree(tmp)  # the old folder, now at the temporary name
        else:
            aside = Path(tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".old", dir=parent))
            os.rmdir(aside)
            os.rename(target, aside)
            try:
                os.rename(tmp, target)
            except BaseException:
                os.rename(aside, target)
                raise
            shutil.rmtree(aside)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return out


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


def read_arrays(reader: Callable[[Path], dict[str, Any]], path: Path) -> dict[str, Any]:
    """``reader(path)``, its ValueError naming the ``path`` argument."""
    try:
        return reader(path)
    except ValueError as exc:
        raise ValueError(f"path: {exc}") from exc
