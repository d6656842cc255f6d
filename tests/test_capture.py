"""Warnings collected per thread while pieces of a run collect theirs on other threads."""

from __future__ import annotations

import threading
import warnings
from types import SimpleNamespace
from typing import Any

import lpvid
import lpvid.pipeline.routes as routes
from lpvid._capture import collected


def test_a_collection_inside_another_gives_the_thread_back_to_it():
    with collected() as outer:
        warnings.warn("first", UserWarning, stacklevel=2)
        with collected() as inner:
            warnings.warn("second", UserWarning, stacklevel=2)
        warnings.warn("third", UserWarning, stacklevel=2)
    assert [m for _, m in outer] == ["first", "third"]
    assert inner == [(UserWarning, "second")]


def test_a_route_holds_its_warnings_while_a_piece_on_another_thread_ends(monkeypatch):
    """The main path's warnings stay its own, and the caller's display is left as it was.

    A piece on another thread starts collecting before the route does and
    ends while the route's fits run (as the blocks route's starts, handed
    out before the main path). A route that held its warnings with
    ``warnings.catch_warnings`` left the piece's router in place of the
    caller's display when it ended: the run's later warnings went past a
    caller that shows them (the command line) to Python's default display.
    """
    started, release, ended = threading.Event(), threading.Event(), threading.Event()

    def piece() -> None:
        with collected() as theirs:
            started.set()
            release.wait(10)
            warnings.warn("the piece's", UserWarning, stacklevel=2)
        assert theirs == [(UserWarning, "the piece's")]
        ended.set()

    def path(*args: Any) -> tuple[list, list]:
        release.set()
        assert ended.wait(10)  # the piece's collection ends inside the route's
        warnings.warn("a slow fit", lpvid.ConvergenceWarning, stacklevel=2)
        return [], []

    monkeypatch.setattr(routes, "run_path", path)
    monkeypatch.setattr(routes, "path_choice", lambda entries, tolerance: (0, "the only one"))
    shown: list[str] = []
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        warnings.showwarning = lambda message, *rest, **kw: shown.append(str(message))
        display, filters = warnings.showwarning, list(warnings.filters)
        worker = threading.Thread(target=piece)
        worker.start()
        assert started.wait(10)
        route = routes.follow(
            "main", None, [0.1], None, None, SimpleNamespace(stable=False, tolerance=0.1)
        )
        worker.join(10)
        assert route.warned == [(lpvid.ConvergenceWarning, "a slow fit")]
        assert warnings.showwarning is display and warnings.filters == filters
        warnings.warn("after the run", lpvid.ConvergenceWarning, stacklevel=2)
    assert shown == ["after the run"]
