"""What the process may still allocate: the address-space limit, the cgroup, MemAvailable.

Read on Linux from ``/proc`` and ``/sys/fs/cgroup``; elsewhere nothing is
known. :mod:`lpvid.fit.memory` compares it with what a run needs.
"""

from __future__ import annotations

import functools
from pathlib import Path

__all__ = ["available_memory", "human"]

#: Limits at or above this are "no limit" (cgroup v1 writes 2^63 - 4096).
UNLIMITED = 1 << 60


def human(nbytes: float) -> str:
    """A size in bytes for people: ``"2.95 GB"``, ``"340 MB"``, ``"12 kB"``."""
    b = float(nbytes)
    if b >= 1e9:
        return f"{b / 1e9:.2f} GB"
    if b >= 1e6:
        return f"{b / 1e6:.0f} MB"
    if b >= 1e3:
        return f"{b / 1e3:.0f} kB"
    return f"{int(b)} bytes"


def _read(path: str | Path) -> str | None:
    try:
        with open(path) as fh:
            return fh.read()
    except OSError:
        return None


def _int_file(path: Path) -> int | None:
    text = _read(path)
    if text is None:
        return None
    text = text.strip()
    if text == "max":
        return None
    try:
        value = int(text)
    except ValueError:
        return None
    return None if value >= UNLIMITED else value


def _stat_field(path: Path, key: str) -> int:
    """One field of a cgroup's ``memory.stat`` (0 when absent)."""
    for line in (_read(path) or "").splitlines():
        name, _, value = line.partition(" ")
        if name == key and value.strip().isdigit():
            return int(value)
    return 0


def _address_space() -> tuple[int, str] | None:
    """Room under the address-space limit (RLIMIT_AS): the limit less what is mapped."""
    try:
        import resource
    except ImportError:  # not on Windows
        return None
    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    if soft == resource.RLIM_INFINITY or soft < 0:
        return None
    used = 0
    for line in (_read("/proc/self/status") or "").splitlines():
        if line.startswith("VmSize:"):
            used = int(line.split()[1]) * 1024
    return soft - used, (
        f"the address-space limit (RLIMIT_AS) of {human(soft)} less {human(used)} in use"
    )


@functools.lru_cache(maxsize=1)
def _limited_cgroups(root: Path = Path("/sys/fs/cgroup")) -> tuple[tuple[Path, int, str, str], ...]:
    """The cgroups of this process (and their parents) that have a memory limit.

    Each as (folder, limit, usage file, inactive-file field of memory.stat);
    found once (a process does not change cgroups while it fits).
    """
    found = []
    for line in (_read("/proc/self/cgroup") or "").splitlines():
        parts = line.split(":", 2)
        if len(parts) != 3:
            continue
        _, controllers, rel = parts
        if controllers == "":  # v2: the unified hierarchy
            base, files = root, ("memory.max", "memory.current", "inactive_file")
        elif "memory" in controllers.split(","):  # v1
            base = root / "memory"
            files = ("memory.limit_in_bytes", "memory.usage_in_bytes", "total_inactive_file")
        else:
            continue
        # The cgroup and its parents (a parent's limit holds too); inside a
        # container the hierarchy may be mounted at the cgroup itself.
        here = base / rel.lstrip("/")
        dirs = [here, *here.parents] if here.is_dir() else [base]
        for d in dirs:
            if d != base and base not in d.parents:
                continue
            limit = _int_file(d / files[0])
            if limit is not None:
                found.append((d, limit, files[1], files[2]))
    return tuple(found)


def _cgroup() -> tuple[int, str] | None:
    """Room under the memory limit of this process's cgroups (v2 or v1)."""
    best: tuple[int, str] | None = None
    for folder, limit, usage_file, inactive in _limited_cgroups():
        usage = _int_file(folder / usage_file)
        if usage is None:
            continue
        # Page cache that the kernel reclaims before it runs out counts as free.
        usage -= _stat_field(folder / "memory.stat", inactive)
        room = limit - max(usage, 0)
        if best is None or room < best[0]:
            best = room, f"the cgroup memory limit of {human(limit)} less {human(usage)} in use"
    return best


def _mem_available() -> tuple[int, str] | None:
    for line in (_read("/proc/meminfo") or "").splitlines():
        if line.startswith("MemAvailable:"):
            value = int(line.split()[1]) * 1024
            return value, f"the system's available memory (MemAvailable, {human(value)})"
    return None


def available_memory() -> tuple[int | None, str]:
    """Bytes this process may still allocate, and what limits it.

    The smallest of: the address-space limit (``RLIMIT_AS``) less the
    address space in use, the memory limit of the process's cgroup less its
    usage (reclaimable page cache not counted), and the system's
    ``MemAvailable``. Read on Linux; elsewhere ``(None, "unknown")``.

    Returns
    -------
    nbytes : int or None
        Never negative; None when nothing is known.
    source : str
        What the figure is, for messages.

    Examples
    --------
    >>> import lpvid
    >>> nbytes, source = lpvid.available_memory()
    >>> nbytes is None or nbytes >= 0
    True

    """
    found = [x for x in (_address_space(), _cgroup(), _mem_available()) if x is not None]
    if not found:
        return None, "unknown"
    room, source = min(found, key=lambda x: x[0])
    return max(room, 0), source
