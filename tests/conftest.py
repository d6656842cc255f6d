"""Fixtures of the lpvid test suite (helpers live in lpvid.testing)."""

from __future__ import annotations

import numpy as np
import pytest


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)
