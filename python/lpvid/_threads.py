"""One BLAS thread inside lpvid's pipeline functions.

lpvid's heavy work runs in its Rust core, spread over the cores by its own
thread pool. numpy's BLAS (OpenBLAS) starts threads of its own for the small
dense problems of the initial estimates (QR, SVD, least squares), and the
two pools then fight over the cores: measured on a 2-core machine, a
3000 x 400 QR took 1.4-1.8 s with OpenBLAS's threads and 0.14-0.24 s with
one. The pipeline entry points run with BLAS limited to one thread (through
threadpoolctl) and restore the caller's setting on return.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any, TypeVar

from threadpoolctl import threadpool_limits

F = TypeVar("F", bound=Callable[..., Any])


def single_blas(fn: F) -> F:
    """Run ``fn`` with numpy's BLAS limited to one thread."""

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        with threadpool_limits(limits=1, user_api="blas"):
            return fn(*args, **kwargs)

    return wrapper  # type: ignore[return-value]
