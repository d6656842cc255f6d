"""The warnings of one task, collected in the thread that runs it.

Python's warning filters and ``warnings.showwarning`` are global to the
process, so ``warnings.catch_warnings`` in several threads at once mixes
their warnings and can leave the filters changed. :func:`collected` instead
installs one router for as long as any task in the process runs (counted
under a lock): in a thread that collects, every warning is appended to that
thread's list; in any other thread it goes to the ``showwarning`` found at
installation. The same code runs in a worker process of another executor, so
a task's warnings are collected the same way wherever it runs.
"""

from __future__ import annotations

import threading
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

__all__ = ["collected"]

_lock = threading.Lock()
_local = threading.local()
_state: dict[str, Any] = {"count": 0, "show": None, "filter": None}


def _filters_changed() -> None:
    """Tell the warnings machinery that ``warnings.filters`` changed (drops its caches).

    A private hook of CPython (``_filters_mutated`` up to 3.13); where it is
    missing, changing the filters through the public API has the same effect.
    """
    hook = getattr(warnings, "_filters_mutated", None)
    if hook is not None:
        hook()
    else:  # pragma: no cover - other Pythons
        warnings.filterwarnings("default", message="\\Z.never-matches\\A", append=True)
        warnings.filters.pop()


def _route(message: Any, category: Any, filename: Any, lineno: Any, *rest: Any) -> None:
    sink = getattr(_local, "sink", None)
    if sink is not None:
        sink.append((category, str(message)))
        return
    show = _state["show"]
    if show is None or show is warnings._showwarning_orig:  # type: ignore[attr-defined]
        # the default display, or that of catch_warnings(record=True)
        msg = warnings.WarningMessage(message, category, filename, lineno, *rest)
        warnings._showwarnmsg_impl(msg)  # type: ignore[attr-defined]
    else:
        show(message, category, filename, lineno, *rest)


@contextmanager
def collected() -> Iterator[list[tuple[type[Warning], str]]]:
    """Collect the warnings raised in this thread as ``(category, message)`` pairs.

    Inside another collection of the same thread, this one takes the
    warnings until it ends, then the other again.

    While any thread collects, warnings of every thread are shown whatever
    the filters (an ``"always"`` filter is in front); those of threads that do
    not collect are passed to the ``showwarning`` in place before.
    """
    sink: list[tuple[type[Warning], str]] = []
    with _lock:
        if _state["count"] == 0:
            _state["show"] = warnings.showwarning
            warnings.showwarning = _route
            # inserted as is: simplefilter would first remove an equal filter in place
            _state["filter"] = ("always", None, Warning, None, 0)
            warnings.filters.insert(0, _state["filter"])
            _filters_changed()
        _state["count"] += 1
    outer = getattr(_local, "sink", None)  # a collection this one is inside
    _local.sink = sink
    try:
        yield sink
    finally:
        _local.sink = outer
        with _lock:
            _state["count"] -= 1
            if _state["count"] == 0:
                warnings.showwarning = _state["show"]
                # this very entry (an equal one of the caller's stays)
                ours = [k for k, f in enumerate(warnings.filters) if f is _state["filter"]]
                if ours:  # else the filters were replaced meanwhile
                    del warnings.filters[ours[0]]
                _filters_changed()
                _state["show"] = _state["filter"] = None
