"""A body from files (issue 16): graph build from 10 minutes of 120 fps BVH, cached reload, A*.

The take is generated (30 joints, every joint turning on its own slow incommensurate cycle, so
the poses never repeat exactly) and written as BVH; the build is timed from the BVH file to a
cached graph (parse, topology, low-energy labels, cache write), on one core. Reload is a second
load of the same sources (the cache hit). A* is timed over random node pairs after the landmark
tables exist (they are built once per graph, before the first tick).
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from bench import Row
from bench.motor import chain_skeleton
from creatures.motor.body_build import Sources, load_or_build
from creatures.motor.bvh import save_bvh
from creatures.motor.material import Animation
from creatures.motor.pose import PoseSet
from creatures.motor.search import PathFinder


def take(frames: int, joints: int, rng: np.random.Generator) -> PoseSet:
    """``frames`` at 120 fps of a ``joints``-joint body, each joint on its own slow cycle."""
    skeleton = chain_skeleton(joints)
    t = np.arange(frames) / 120.0
    rate = rng.uniform(0.05, 0.6, (joints, 3))
    phase = rng.uniform(0.0, 2 * np.pi, (joints, 3))
    vectors = 0.6 * np.sin(2 * np.pi * t[:, None, None] * rate + phase)
    xyzw = Rotation.from_rotvec(vectors.reshape(-1, 3)).as_quat().reshape(frames, joints, 4)
    return PoseSet.animation(skeleton, xyzw[..., [3, 0, 1, 2]], np.zeros((frames, 3)), t, "take")


def run(quick: bool) -> list[Row]:
    frames = 7_200 if quick else 72_000
    rng = np.random.default_rng(0)
    with tempfile.TemporaryDirectory() as folder:
        bvh = Path(folder) / "take.bvh"
        save_bvh(bvh, take(frames, 30, rng), frame_time=1.0 / 120.0)
        sources = Sources((Animation(bvh, {"rest": ((0, 0),)}),), rest_labels=("rest",))
        cache = Path(folder) / "cache" / "body.npz"
        t0 = time.process_time()
        graph = load_or_build(sources, cache)
        built = time.process_time() - t0
        t0 = time.perf_counter()
        again = load_or_build(sources, cache)
        reload = time.perf_counter() - t0
        assert len(again) == len(graph)
        finder = PathFinder(again)
        finder.prepare()
        pairs = rng.integers(len(again), size=(200, 2))
        t0 = time.perf_counter()
        for a, b in pairs:
            finder.path(int(a), [int(b)])
        per_query = (time.perf_counter() - t0) / len(pairs)
    size = f"{frames} frames × 30 joints"
    return [
        Row(f"body graph build from BVH, {size} (CPU)", built, "s", 15.0 if not quick else None, higher_is_better=False),
        Row(f"body graph cached reload, {size}", reload, "s", 0.5 if not quick else None, higher_is_better=False),
        Row(f"A* mean per query, body graph of {size}", per_query * 1e3, "ms", 2.0, higher_is_better=False),
    ]
