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
