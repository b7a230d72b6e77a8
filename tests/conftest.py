"""Shared fixtures: seeded RNGs and simulated clocks make every test deterministic."""

from __future__ import annotations

import os

import numpy as np
import pytest

os.environ.setdefault("NUMBA_CACHE_DIR", os.path.join(os.path.dirname(__file__), "..", ".numba_cache"))

from creatures.clock import SimulatedClock  # noqa: E402


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20011)


@pytest.fixture
def clock() -> SimulatedClock:
    return SimulatedClock()
