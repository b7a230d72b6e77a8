"""Motor system: graph construction, A* per query, pose interpolation throughput.

Graphs are built from many variations (durations, amplitudes) of the shipped sway / reach /
strike animations until they hold the wanted number of nodes. A* is timed over random
start/goal pairs once the landmark tables exist (they are rebuilt only after edits, and
their cost is reported with construction, as is the playback speed limit, computed once
per pose set before the first course). Interpolation runs squad playback on a 30-joint
skeleton. The quaternion product is timed against scipy's ``Rotation`` on the same data, to
back the choice of plain numpy.
"""

from __future__ import annotations

import time

import numpy as np
from scipy.spatial.transform import Rotation

from bench import Row, best_of
from creatures.motor import quaternion as quat
from creatures.motor.animations import creature_skeleton, reach, strike, sway
from creatures.motor.graph import MotorGraph
from creatures.motor.playback import Playback
from creatures.motor.pose import PoseSet, estimate_velocities
from creatures.motor.search import PathFinder
from creatures.motor.skeleton import Skeleton


def material(count: int, rng: np.random.Generator) -> PoseSet:
    """At least ``count`` poses: varied takes of the three example animations."""
    skeleton = creature_skeleton()
    takes: list[PoseSet] = []
    total = 0
    while total < count:
        kind = int(rng.integers(3))
        scale = float(rng.uniform(0.7, 1.5))
        if kind == 0:
            take = sway(skeleton, duration=4.0 * scale, amplitude=float(rng.uniform(0.1, 0.4)))
        elif kind == 1:
            take = reach(skeleton, duration=12.0 * scale)
        else:
            take = strike(skeleton, duration=2.0 * scale)
        take.sources = [f"{take.sources[0]}-{len(takes)}"]
        takes.append(take)
        total += len(take)
    return PoseSet.concatenate(takes).subset(np.arange(count))


def chain_skeleton(joints: int = 30) -> Skeleton:
    """A branching 30-joint body: a spine with limbs of three joints each."""
    parents = [-1] + [0 if j % 3 == 1 else j - 1 for j in range(1, joints)]
    offsets = np.tile([0.0, 0.2, 0.05], (joints, 1))
    return Skeleton(tuple(f"j{j}" for j in range(joints)), np.array(parents), offsets, np.ones(joints))


def _astar_rows(size: int, queries: int, rng: np.random.Generator) -> list[Row]:
    poses = material(size, rng)
    t0 = time.perf_counter()
    graph = MotorGraph.build(poses, k=6)
    built = time.perf_counter() - t0
    finder = PathFinder(graph)
    t0 = time.perf_counter()
    finder.prepare()
    landmarks = time.perf_counter() - t0
    t0 = time.perf_counter()
    graph.timing  # computed lazily by the first playback
    speed_limit = time.perf_counter() - t0
    finder.path(0, [1])  # loads the compiled kernel before timing
    pairs = rng.integers(size, size=(queries, 2))
    expanded = 0
    t0 = time.perf_counter()
    for a, b in pairs.tolist():
        finder.path(a, [b])
        expanded += finder.expanded
    per_query = (time.perf_counter() - t0) / queries
    target = 2.0 if size == 10_000 else None
    return [
        Row(f"graph build, {size} nodes (k=6)", built, "s", higher_is_better=False),
        Row(f"landmark tables, {size} nodes", landmarks * 1e3, "ms", higher_is_better=False),
        Row(f"playback speed limit (first course), {size} nodes", speed_limit * 1e3, "ms", higher_is_better=False),
        Row(f"A* mean per query, {size} nodes", per_query * 1e3, "ms", target, higher_is_better=False),
        Row(f"A* nodes expanded per query, {size} nodes", expanded / queries, "nodes", higher_is_better=False),
    ]


def _interpolation_rows(rng: np.random.Generator, quick: bool) -> list[Row]:
    skeleton = chain_skeleton(30)
    frames = 200
    times = np.arange(frames) / 10.0
    vectors = np.cumsum(rng.normal(scale=0.05, size=(frames, 30, 3)), axis=0)
    rotations = quat.exp(vectors)
    poses = PoseSet(
        skeleton=skeleton,
        rotations=rotations,
        velocities=estimate_velocities(rotations, times),
        roots=np.zeros((frames, 3)),
        times=times,
        source_ids=np.zeros(frames, dtype=np.int64),
        sources=["walk"],
        labels=[frozenset()] * frames,
    )
    graph = MotorGraph.build(poses, k=4)
    path = PathFinder(graph).path(0, [frames - 1])
    playback = Playback(graph, path, 0.0)
    batch = np.linspace(0.0, playback.end_time, 2_000 if quick else 20_000)
    batch_time = best_of(lambda: playback.sample_rotations(batch))
    fk_time = best_of(lambda: skeleton.forward_kinematics(*playback.sample_rotations(batch)))
    singles = batch[:200]
    single_time = best_of(lambda: [playback.sample(t) for t in singles])
    return [
        Row("squad interpolation, 30 joints, batched", len(batch) / batch_time, "poses/s"),
        Row("squad + forward kinematics, 30 joints, batched", len(batch) / fk_time, "poses/s"),
        Row("one BodyPose per call (render loop), 30 joints", len(singles) / single_time, "poses/s", target=300.0),
    ]


def _product_row(rng: np.random.Generator) -> Row:
    a = quat.normalize(rng.normal(size=(10_000, 4)))
    b = quat.normalize(rng.normal(size=(10_000, 4)))
    ours = best_of(lambda: quat.multiply(a, b), repeat=5)
    ra, rb = Rotation.from_quat(a[:, [1, 2, 3, 0]]), Rotation.from_quat(b[:, [1, 2, 3, 0]])
    # scipy works on Rotation objects, so its time includes converting back to arrays.
    theirs = best_of(lambda: (ra * rb).as_quat(), repeat=5)
    small = quat.normalize(rng.normal(size=(30, 4)))
    ours_small = best_of(lambda: [quat.multiply(small, small) for _ in range(100)])
    theirs_small = best_of(
        lambda: [(Rotation.from_quat(small) * Rotation.from_quat(small)).as_quat() for _ in range(100)]
    )
    return [
        Row("quaternion product, 10k pairs, numpy", ours * 1e3, "ms", higher_is_better=False,
            baseline="scipy Rotation", ratio=theirs / ours),
        Row("quaternion product, 10k pairs, scipy Rotation (peer, same run)", theirs * 1e3, "ms",
            higher_is_better=False),
        Row("quaternion product, one 30-joint pose, numpy", ours_small / 100 * 1e6, "µs", higher_is_better=False,
            baseline="scipy Rotation", ratio=theirs_small / ours_small),
    ]


def run(quick: bool) -> list[Row]:
    rng = np.random.default_rng(2001)
    sizes = (1_000, 10_000) if quick else (1_000, 10_000, 100_000)
    rows: list[Row] = []
    for size in sizes:
        rows += _astar_rows(size, 50 if quick else 200, rng)
    rows += _interpolation_rows(rng, quick)
    rows += _product_row(rng)
    return rows
