"""Fixtures of the lpvid test suite (helpers live in lpvid.testing)."""

from __future__ import annotations

import signal

import numpy as np
import pytest


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)


@pytest.fixture
def plt():
    """matplotlib.pyplot (the test is skipped without the plot extra); figures closed after."""
    pyplot = pytest.importorskip("matplotlib.pyplot")
    yield pyplot
    pyplot.close("all")


@pytest.fixture
def python_sigint():
    """Python's SIGINT handler (KeyboardInterrupt) for one test; the old handler restored.

    Python keeps SIGINT ignored when the process starts with it ignored (a
    background job, nohup, some CI runners); tests of Ctrl-C install it.
    """
    old = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old)


@pytest.fixture
def blas_threads():
    """A setter of numpy's and scipy's BLAS threads for one test; every library's count restored.

    Whichever thread set a limit before (threadpoolctl 3.8 ignores every
    thread but the first to set one), this one may: the limit is taken the
    way ``lpvid._threads`` takes it.
    """
    from threadpoolctl import threadpool_info, threadpool_limits

    from lpvid._threads import _release_control

    if not threadpool_info():
        pytest.skip("no BLAS library that threadpoolctl controls")
    before = threadpool_info()

    def set_to(limit: int) -> None:
        _release_control()
        threadpool_limits(limits=limit, user_api="blas")

    try:
        yield set_to
    finally:
        _release_control()
        for lib in before:
            threadpool_limits(limits={lib["filepath"]: lib["num_threads"]})
        _release_control()
