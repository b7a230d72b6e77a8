"""Adverb blending in neutral time (thesis "blend based motor systems", figures 20–21)."""

from __future__ import annotations

import numpy as np
import pytest

from creatures.motor import quaternion as quat
from creatures.motor.adverbs import AdverbBlend, Example
from creatures.motor.animations import creature_skeleton, sway
from creatures.motor.graph import MotorGraph
from creatures.motor.search import PathFinder


@pytest.fixture(scope="module")
def skeleton():
    return creature_skeleton()


def test_blend_goes_through_the_examples(skeleton):
    slow, fast = sway(skeleton, duration=4.0, amplitude=0.4), sway(skeleton, duration=2.0, amplitude=0.1)
    blend = AdverbBlend([Example(fast, (0.0,)), Example(slow, (1.0,))])
    for adverb, example in ((0.0, fast), (1.0, slow)):
        rotations, _ = blend.sample([adverb], example.times)
        assert quat.distance(rotations, example.rotations).max() < 1e-12


def test_half_blend_lasts_the_mean_time_and_reads_each_example_at_its_own_time(skeleton):
    # "A 50%:50% blend of a 2 s and a 4 s walk lasts 3 s; half-way through it reads 1 s into
    # one and 2 s into the other." Sways of the same shape blend to the in-between sway.
    fast, slow = sway(skeleton, duration=2.0, amplitude=0.1), sway(skeleton, duration=4.0, amplitude=0.4)
    blend = AdverbBlend([Example(fast, (0.0,)), Example(slow, (1.0,))])
    weights = blend.weights([0.5])
    assert weights == pytest.approx([0.5, 0.5])
    assert blend.duration(weights) == pytest.approx(3.0)
    middle = sway(skeleton, duration=3.0, amplitude=0.25)
    rotations, _ = blend.sample([0.5], middle.times)
    assert quat.angle_between(rotations, middle.rotations).max() < 0.01


def test_correspondence_points_line_up(skeleton):
    # Two takes whose extremes fall at different times: aligning the extremes makes the
    # blend reach its extreme where the blended warp puts it.
    a = sway(skeleton, duration=4.0, amplitude=0.3)
    b = sway(skeleton, duration=4.0, amplitude=0.3)
    b_times = b.times ** 1.5 / 4.0 ** 0.5  # the same motion, time-distorted
    b.times = b_times
    left_a = 1.0  # "sway left" at a quarter of the cycle
    left_b = float(left_a ** 1.5 / 4.0 ** 0.5)
    blend = AdverbBlend([Example(a, (0.0,), (left_a,)), Example(b, (1.0,), (left_b,))])
    knot = 0.5 * (left_a + left_b)
    rotations, _ = blend.sample([0.5], np.array([knot]))
    extreme = a.rotations[a.labelled("sway left")[0]]
    assert quat.angle_between(rotations[0], extreme).max() < 1e-6


def test_two_axis_blend_and_graph_patching(skeleton):
    examples = [
        Example(sway(skeleton, duration=2.0, amplitude=0.1), (0.0, 0.0)),
        Example(sway(skeleton, duration=4.0, amplitude=0.1), (1.0, 0.0)),
        Example(sway(skeleton, duration=2.0, amplitude=0.4), (0.0, 1.0)),
        Example(sway(skeleton, duration=4.0, amplitude=0.4), (1.0, 1.0)),
    ]
    blend = AdverbBlend(examples)
    for k, e in enumerate(examples):
        assert blend.weights(e.adverbs) == pytest.approx(np.eye(4)[k], abs=1e-9)
    assert blend.weights([0.3, 0.8]).sum() == pytest.approx(1.0)
    made = blend.animation([0.5, 0.5], fps=10.0)
    assert made.times[-1] == pytest.approx(3.0)
    # New material made on the fly becomes reachable graph nodes.
    graph = MotorGraph.build(examples[0].animation, k=3)
    new = graph.add_poses(made, k=3)
    assert PathFinder(graph).path(0, [int(new[len(new) // 2])]).goal == new[len(new) // 2]


def test_examples_must_agree(skeleton):
    a = sway(skeleton)
    with pytest.raises(ValueError, match="at least two"):
        AdverbBlend([Example(a, (0.0,))])
    with pytest.raises(ValueError, match="same number"):
        AdverbBlend([Example(a, (0.0,)), Example(a, (1.0, 2.0))])
    with pytest.raises(ValueError, match="must increase"):
        AdverbBlend([Example(a, (0.0,), (9.0,)), Example(a, (1.0,), (1.0,))])
