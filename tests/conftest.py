"""Shared fixtures: seeded RNGs and simulated clocks make every test deterministic."""

from __future__ import annotations

import os

# One BLAS thread, as the CLI sets: tiny matrix operations only fight over the cores.
for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")

import numpy as np  # noqa: E402
import pytest  # noqa: E402

os.environ.setdefault("NUMBA_CACHE_DIR", os.path.join(os.path.dirname(__file__), "..", ".numba_cache"))
# Each xdist worker (and the runs it starts) compiles into a cache of its own. Numba caches a
# generalised ufunc as two entries, its kernel and its wrapper; two processes compiling one at
# once can leave a wrapper beside the other's kernel, and every process that loads the pair
# crashes (SIGSEGV in librosa's yin and in our own gufunc: two fresh-clone CI runs, 6 and 14
# tests). Numba is imported below this line, after which the variable is read.
if os.environ.get("PYTEST_XDIST_WORKER"):
    os.environ["NUMBA_CACHE_DIR"] = os.path.join(os.environ["NUMBA_CACHE_DIR"], os.environ["PYTEST_XDIST_WORKER"])

from hypothesis import settings  # noqa: E402

from creatures.clock import SimulatedClock  # noqa: E402

# Property tests draw the same examples on every run (CI included), so a pass or a failure can
# be reproduced; HYPOTHESIS_PROFILE=explore searches afresh each time, as hypothesis does by default.
# No deadline: a 200 ms limit per example measured the other test worker's load, not the code.
settings.register_profile("deterministic", derandomize=True, database=None, deadline=None)
settings.register_profile("explore")
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "deterministic"))


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20011)


@pytest.fixture
def clock() -> SimulatedClock:
    return SimulatedClock()


@pytest.fixture
def own_registry(monkeypatch):
    """Parts and kinds a test's plugin registers leave with it, so a later test in the same
    worker (the generated reference in docs/authoring.md among them) sees the built-ins only.
    The built-ins are loaded first, so they are kept."""
    from creatures import kinds
    from creatures.authored import registry

    kinds.load_all()
    registry.load_parts()
    saved = dict(kinds.KINDS)
    for parts in (registry.ACTIONS, registry.PERCEPTS, registry.MODELS):
        monkeypatch.setattr(parts, "_parts", dict(parts._parts))
    monkeypatch.setattr(registry, "_loaded", set(registry._loaded))
    yield
    kinds.KINDS.clear()
    kinds.KINDS.update(saved)


@pytest.fixture(params=["none found", "IMAGEIO_FFMPEG_EXE names none"])
def no_video_encoder(request, monkeypatch):
    """No ffmpeg for imageio: none installed (imageio-ffmpeg finds none), or the environment
    naming one that is not there."""
    import imageio_ffmpeg._utils

    monkeypatch.setattr(imageio_ffmpeg._utils, "_get_ffmpeg_exe", lambda: None)
    if request.param == "none found":
        monkeypatch.delenv("IMAGEIO_FFMPEG_EXE", raising=False)
    else:
        monkeypatch.setenv("IMAGEIO_FFMPEG_EXE", "/nonexistent/ffmpeg")
