"""The compiled motor kernels agree with the numpy formulas they replace (to rounding).

Each reference below is the numpy code the kernel took over, written out with the public
numpy functions of :mod:`creatures.motor.quaternion`; inputs are seeded random key
sequences plus the awkward cases: a key and its antipode (the same rotation, opposite
sign) and keys a hair apart (slerp's near-zero-angle branch).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from creatures.kinds.moves import head_for
from creatures.kinds.parts import BODY_BLOCK, BODY_RATE, Body
from creatures.motor import quaternion as quat
from creatures.motor import playback as playback_module
from creatures.motor.animations import creature_skeleton, example_animations, strike
from creatures.motor.graph import MotorGraph
from creatures.motor.playback import Playback, transit_times
from creatures.motor.pose import PoseSet
from creatures.motor.search import GraphPosition, PathFinder

TOLERANCE = 1e-9


def key_sequences(seed: int, count: int = 9, joints: int = 7) -> dict[str, np.ndarray]:
    """Random unit keys ``(count, joints, 4)``, and the same with antipodal or near-equal neighbours."""
    rng = np.random.default_rng(seed)
    keys = quat.normalize(rng.normal(size=(count, joints, 4)))
    antipodal = keys.copy()
    antipodal[1::2] = -antipodal[:-1:2] + 1e-9 * rng.normal(size=antipodal[1::2].shape)
    near = keys.copy()
    near[1:] = keys[:1] + 1e-8 * rng.normal(size=(count - 1, joints, 4))
    return {"random": keys, "antipodal": quat.normalize(antipodal), "near": quat.normalize(near)}


def reference_controls(keys: np.ndarray) -> np.ndarray:
    q = quat.hemisphere_align(keys)
    return quat.squad_control(np.concatenate((q[:1], q[:-1])), q, np.concatenate((q[1:], q[-1:])))


def reference_rate(q1, q2, s1, s2, samples: int = 16) -> np.ndarray:
    alphas = np.linspace(0.0, 1.0, samples + 1)[1:].reshape((-1,) + (1,) * (q1.ndim - 1))
    points = quat.squad(q1, q2, s1, s2, alphas)
    return quat.angle_between(points, np.concatenate((q1[None], points[:-1]))).max(axis=0) * samples


@pytest.mark.parametrize("seed", range(5))
def test_squad_controls_match_numpy(seed):
    for name, keys in key_sequences(seed).items():
        assert np.abs(quat.squad_controls(keys) - reference_controls(keys)).max() < TOLERANCE, name
        q = quat.hemisphere_align(keys)
        n = np.arange(len(q))
        at = quat.squad_control_at(q, np.maximum(n - 1, 0), np.minimum(n + 1, len(q) - 1))
        assert np.abs(at - reference_controls(keys)).max() < TOLERANCE, name


@pytest.mark.parametrize("seed", range(5))
def test_squad_keys_match_numpy_squad(seed):
    rng = np.random.default_rng(100 + seed)
    for name, keys in key_sequences(seed).items():
        keys = quat.hemisphere_align(keys)
        controls = quat.squad_controls(keys)
        segments = rng.integers(0, len(keys) - 1, 40)
        alpha = np.concatenate(([0.0, 1.0, 1e-12, 0.5], rng.uniform(0.0, 1.0, 36)))
        expected = quat.squad(keys[segments], keys[segments + 1], controls[segments], controls[segments + 1], alpha[:, None])
        assert np.abs(quat.squad_keys(keys, controls, segments, alpha) - expected).max() < TOLERANCE, name


def test_squad_keys_refuses_segments_past_the_last_key():
    keys = key_sequences(0)["random"]
    with pytest.raises(IndexError):
        quat.squad_keys(keys, keys, np.array([len(keys) - 1]), np.array([0.5]))


@pytest.mark.parametrize("seed", range(5))
def test_squad_rate_matches_numpy(seed):
    for name, keys in key_sequences(seed).items():
        keys = quat.hemisphere_align(keys)
        controls = quat.squad_controls(keys)
        args = (keys[:-1], keys[1:], controls[:-1], controls[1:])
        for samples in (4, 16, 64):
            got, expected = quat.squad_rate(*args, samples=samples), reference_rate(*args, samples=samples)
            # Points a hair apart are an acos near 1 apart, where a rounding step or two in
            # their dot product moves the angle by up to 2·acos(1 − 2ε) ≈ 6e-8 (per sample).
            tolerance = samples * 2.0 * np.arccos(1.0 - 2.0 * np.finfo(float).eps) if name == "near" else TOLERANCE
            assert np.abs(got - expected).max() < tolerance, (name, samples)


def test_squad_rate_broadcasts_its_inputs():
    keys = key_sequences(1)["random"]
    rate = quat.squad_rate(keys[:-1], keys[1:], keys[0], keys[1])
    assert rate.shape == (len(keys) - 1, keys.shape[1])
    s1, s2 = np.broadcast_to(keys[0], keys[1:].shape), np.broadcast_to(keys[1], keys[1:].shape)
    assert np.abs(rate - reference_rate(keys[:-1], keys[1:], s1, s2)).max() < TOLERANCE


def reference_forward_kinematics(skeleton, rotations: np.ndarray, root: np.ndarray) -> np.ndarray:
    world = np.empty_like(rotations)
    positions = np.empty((*rotations.shape[:-1], 3))
    for j, p in enumerate(skeleton.parents):
        if p < 0:
            world[..., j, :] = rotations[..., j, :]
            positions[..., j, :] = skeleton.offsets[j] + root
        else:
            world[..., j, :] = quat.multiply(world[..., p, :], rotations[..., j, :])
            positions[..., j, :] = positions[..., p, :] + quat.rotate(world[..., p, :], skeleton.offsets[j])
    return positions


def test_forward_kinematics_matches_numpy():
    skeleton = creature_skeleton()
    rng = np.random.default_rng(7)
    rotations = quat.normalize(rng.normal(size=(25, skeleton.joint_count, 4)))
    roots = rng.normal(size=(25, 3))
    expected = reference_forward_kinematics(skeleton, rotations, roots)
    assert np.abs(skeleton.forward_kinematics(rotations, roots) - expected).max() < TOLERANCE
    assert np.abs(skeleton.forward_kinematics(rotations[3], roots[3]) - expected[3]).max() < TOLERANCE
    shared_root = skeleton.forward_kinematics(rotations, roots[0])
    assert np.abs(shared_root - reference_forward_kinematics(skeleton, rotations, roots[0])).max() < TOLERANCE


@pytest.fixture(scope="module")
def graph() -> MotorGraph:
    return MotorGraph.build(PoseSet.concatenate(example_animations(creature_skeleton())), k=5)


def test_playback_times_match_sampling_every_joint(graph):
    """Skipping the joints whose bound keeps them under the limit lays out the same times
    as sampling every joint of every segment."""
    rng = np.random.default_rng(11)
    finder = PathFinder(graph)
    edges = list(graph.edges())
    slowed = 0
    for i in range(60):
        a, b = edges[int(rng.integers(len(edges)))]
        start = GraphPosition(a, b, float(rng.uniform(0.05, 0.95))) if i % 2 else GraphPosition(a)
        playback = Playback(graph, finder.path(start, [int(rng.integers(len(graph)))]), 0.0)
        keys, controls = playback.keys, playback.controls
        turns = quat.squad_rate(keys[:-1], keys[1:], controls[:-1], controls[1:]).max(axis=-1)
        # Every segment after the first (which starts from the body's own pose) joins two nodes.
        durations = transit_times(graph, playback.key_nodes[:-1], playback.key_nodes[1:])
        expected = np.maximum(durations, turns[1:] / graph.timing.max_speed)
        assert np.diff(playback.key_times)[1:] == pytest.approx(expected, rel=1e-12, abs=1e-12)
        slowed += int(np.sum(expected > durations))
    assert slowed > 0  # some segments are slowed by the limit, so skipping could have mattered


def test_transit_times_are_remembered_until_the_graph_changes():
    skeleton = creature_skeleton()
    graph = MotorGraph.build(PoseSet.concatenate(example_animations(skeleton)), k=5)
    pairs = np.array(list(graph.edges()))
    before = transit_times(graph, pairs[:, 0], pairs[:, 1])
    assert np.array_equal(before, graph.transit_times(pairs[:, 0], pairs[:, 1]))
    version, known = playback_module._TRANSITS[graph]
    assert version == graph.version and len(known) == len(pairs)
    # A strike four times faster raises the speed limit, which shortens the estimated
    # transits of the old edges: a memo that outlived the edit would keep the old times.
    graph.add_poses(dataclasses.replace(strike(skeleton, duration=0.5), sources=["fast strike"]))
    after = transit_times(graph, pairs[:, 0], pairs[:, 1])
    assert np.array_equal(after, graph.transit_times(pairs[:, 0], pairs[:, 1]))
    assert np.any(after < before)


@pytest.mark.parametrize("seed", range(3))
def test_squad_rate_samples_only_segments_whose_bound_passes_above(seed):
    keys = quat.hemisphere_align(key_sequences(seed)["random"])
    # Controls near the keys on even joints (finite bounds), anywhere on odd ones (often infinite).
    controls = quat.normalize(keys + 0.3 * np.random.default_rng(seed + 100).normal(size=keys.shape))
    controls[:, 1::2] = key_sequences(seed + 10)["random"][:, 1::2]
    args = (keys[:-1], keys[1:], controls[:-1], controls[1:])
    rate, bound = quat.squad_rate(*args), quat.squad_rate_bound(*args)
    finite = np.isfinite(bound)
    assert finite.any() and (~finite).any()
    # Just under its bound every segment is sampled; just over, only unbounded ones are
    # (the compiled bound agrees with squad_rate_bound to rounding).
    assert np.array_equal(quat.squad_rate(*args, above=np.where(finite, bound - 1e-9, 0.0)), rate)
    assert np.array_equal(quat.squad_rate(*args, above=np.where(finite, bound + 1e-9, 0.0)), np.where(finite, 0.0, rate))


def test_a_body_looked_up_in_any_order_follows_its_course_on_the_grid():
    """Body poses come from blocks computed where a tick first looks; whichever order the
    ticks come in, each is the course's squad sample on the BODY_RATE grid, moving at the
    turn to the next grid sample."""
    body = Body(np.random.default_rng(3), ratios=True)
    graph = body.graph
    head_for(body, 2.0, [int(np.argmax(quat.angle_between(graph.poses.rotations, body.pose.rotations).sum(axis=1)))])
    playback = body.motor.playback
    grid = 2.0 + np.arange(int((playback.end_time - 2.0) * BODY_RATE)) / BODY_RATE
    assert len(grid) > 3 * BODY_BLOCK
    rotations, roots = playback.sample_rotations(np.concatenate((grid, [grid[-1] + 1.0 / BODY_RATE])))
    turns = quat.log(quat.multiply(rotations[1:], quat.conjugate(rotations[:-1]))) * BODY_RATE
    for i in np.random.default_rng(4).permutation(len(grid)):
        pose = body.update(float(grid[i]))
        assert np.abs(pose.rotations - rotations[i]).max() < TOLERANCE
        assert np.abs(pose.velocities - turns[i]).max() < 1e-6
        assert np.abs(pose.positions - graph.skeleton.forward_kinematics(rotations[i], roots[i])).max() < TOLERANCE


def test_nearest_costs_keep_each_rows_k_cheapest_exactly():
    """The pruned costing (metric.nearest_costs) gives the full metric's k cheapest candidates
    of every row, bit for bit, and skips others (which is what makes it worth having)."""
    from creatures.kinds.parts import shared_material
    from creatures.motor import metric

    poses, weights = shared_material(), metric.MetricWeights()
    following = metric.successors(poses)
    rows = np.arange(len(poses))
    candidates = np.random.default_rng(0).integers(len(poses), size=(len(poses), 19))
    candidates[:, 0] = rows
    full = metric.edge_costs(poses, rows[:, None], candidates, weights, following)
    pruned = metric.nearest_costs(poses, rows, candidates, weights, following, 6)
    for r in rows:
        others = candidates[r] != r
        assert np.array_equal(np.sort(full[r][others])[:6], np.sort(pruned[r][others])[:6])
    evaluated = np.isfinite(pruned)
    assert np.array_equal(pruned[evaluated], full[evaluated]) and evaluated.mean() < 0.8
