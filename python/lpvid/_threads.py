"""One BLAS thread inside lpvid's pipeline functions.

lpvid's heavy work runs in its Rust core, spread over the cores by its own
thread pool. numpy's BLAS (OpenBLAS) starts threads of its own for the small
dense problems of the initial estimates (QR, SVD, least squares), and the
two pools then fight over the cores: measured on a 2-core machine, a
3000 x 400 QR took 1.4-1.8 s with OpenBLAS's threads and 0.14-0.24 s with
one. On one thread the results are also the same on any number of cores
(on two, OpenBLAS took other last bits for a 12-state 2x2 subspace
estimate). The pipeline entry points, and the public functions whose numpy
work is dense linear algebra (``fd_subspace``, ``order_hints``,
``consistency``, ``refit``, ``stability``, ``rate_stability``, ``max_rate``,
``estimate_frf``, ``next_points``), run with BLAS limited to one thread
(through threadpoolctl) and restore the caller's setting on return. The
limit is process-wide, and so is its count here: the first entry point to
start (in any thread) sets it, the last to return restores the caller's
setting, and those that run meanwhile (nested ones, and the pieces of a
run on its threads: the local models, the SMILE candidates, ...) leave it
as it is. threadpoolctl looks up the loaded libraries at every call (0.8
ms; a small ``identify`` hands out some fifty pieces).

Two things make the limit hold whichever thread sets and restores it:

- scipy's own OpenBLAS (its wheels bundle one beside numpy's) is loaded
  before the limit is set: a library loaded later keeps its own threads,
  and scipy is otherwise first imported inside a run, so the first run of
  a process ran scipy's LAPACK on every core and later runs on one.
- threadpoolctl 3.8 lets one thread only, the first that sets a limit on a
  pthreads OpenBLAS, change it for as long as it lives, and ignores the
  others' calls without a word; a limit set without its context manager
  (as here, where the first entry point to start and the last to return
  may be on different threads) keeps that thread in control. Measured
  before this was handled: an interrupted ``select`` (its last run ending
  on a pool thread) left the caller's numpy on one thread, after which
  the data that ``lpvid.testing.noisy_data`` simulates for a 101-state
  model took other last bits; and after one call on the main thread, the
  runs on other threads were not limited at all. Control is released
  before the limit is set and on both sides of its restoring.
"""

from __future__ import annotations

import functools
import threading
from collections.abc import Callable
from typing import Any, TypeVar

import threadpoolctl
from threadpoolctl import threadpool_limits

F = TypeVar("F", bound=Callable[..., Any])

_lock = threading.Lock()
# How many entry points run (in every thread), and the limit they hold.
_held: dict[str, Any] = {"count": 0, "limit": None}


def _release_control() -> None:
    """Let the next thread that sets a BLAS limit have it (threadpoolctl 3.8 and later)."""
    controller = getattr(threadpoolctl, "OpenBLASController", None)
    clear = getattr(controller, "clear_controlling_thread", None)
    if clear is not None:
        clear(force=True)


def _enter() -> None:
    with _lock:
        if _held["count"] == 0:
            import scipy.linalg  # noqa: F401  (loads scipy's own BLAS, so that the limit holds it)

            _release_control()
            _held["limit"] = threadpool_limits(limits=1, user_api="blas")
        _held["count"] += 1


def _leave() -> None:
    with _lock:
        _held["count"] -= 1
        if _held["count"] == 0:
            limit, _held["limit"] = _held["limit"], None
            _release_control()
            limit.restore_original_limits()
            _release_control()


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
