"""One BLAS thread inside lpvid's pipeline functions.

lpvid's heavy work runs in its Rust core, spread over the cores by its own
thread pool. numpy's BLAS (OpenBLAS) starts threads of its own for the small
dense problems of the initial estimates (QR, SVD, least squares), and the
two pools then fight over the cores: measured on a 2-core machine, a
3000 x 400 QR took 1.4-1.8 s with OpenBLAS's threads and 0.14-0.24 s with
one. The pipeline entry points run with BLAS limited to one thread (through
threadpoolctl) and restore the caller's setting on return. Within one,
the functions it calls that are entry points too (the local models, the
SMILE candidates, ...) leave the limit as it is: threadpoolctl looks up
the loaded libraries at every call (0.8 ms, nine times in a gantry
``identify``).
"""

from __future__ import annotations

import functools
import threading
from collections.abc import Callable
from typing import Any, TypeVar

from threadpoolctl import threadpool_limits

F = TypeVar("F", bound=Callable[..., Any])

# Whether this thread runs inside a limit set here (the limit itself is
# process-wide; a piece on an executor's thread sets its own).
_inside = threading.local()


def single_blas(fn: F) -> F:
    """Run ``fn`` with numpy's BLAS limited to one thread (already so within another)."""

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        if getattr(_inside, "limited", False):
            return fn(*args, **kwargs)
        with threadpool_limits(limits=1, user_api="blas"):
            _inside.limited = True
            try:
                return fn(*args, **kwargs)
            finally:
                _inside.limited = False

    return wrapper  # type: ignore[return-value]
