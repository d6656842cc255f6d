"""One BLAS thread inside lpvid's pipeline functions.

lpvid's heavy work runs in its Rust core, spread over the cores by its own
thread pool. numpy's BLAS (OpenBLAS) starts threads of its own for the small
dense problems of the initial estimates (QR, SVD, least squares), and the
two pools then fight over the cores: measured on a 2-core machine, a
3000 x 400 QR took 1.4-1.8 s with OpenBLAS's threads and 0.14-0.24 s with
one. The pipeline entry points run with BLAS limited to one thread (through
threadpoolctl) and restore the caller's setting on return. The limit is
process-wide, and so is its count here: the first entry point to start (in
any thread) sets it, the last to return restores the caller's setting, and
those that run meanwhile (nested ones, and the pieces of a run on its
threads: the local models, the SMILE candidates, ...) leave it as it is.
threadpoolctl looks up the loaded libraries at every call (0.8 ms; a small
``identify`` hands out some fifty pieces).
"""

from __future__ import annotations

import functools
import threading
from collections.abc import Callable
from typing import Any, TypeVar

from threadpoolctl import threadpool_limits

F = TypeVar("F", bound=Callable[..., Any])

_lock = threading.Lock()
# How many entry points run (in every thread), and the limit they hold.
_held: dict[str, Any] = {"count": 0, "limit": None}


def _enter() -> None:
    with _lock:
        if _held["count"] == 0:
            _held["limit"] = threadpool_limits(limits=1, user_api="blas")
        _held["count"] += 1


def _leave() -> None:
    with _lock:
        _held["count"] -= 1
        if _held["count"] == 0:
            limit, _held["limit"] = _held["limit"], None
            limit.restore_original_limits()


def single_blas(fn: F) -> F:
    """Run ``fn`` with numpy's BLAS limited to one thread (already so while another runs)."""

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        _enter()
        try:
            return fn(*args, **kwargs)
        finally:
            _leave()

    return wrapper  # type: ignore[return-value]
