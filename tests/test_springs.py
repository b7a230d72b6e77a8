"""Bodies as spring systems (issue 22, curve as the thesis's platform; creatures/body/springs.py):
the realised body follows its pose with the dynamics of damped springs, keeps its bones and the
floor, does not depend on the tick, and in curve pushes its strings on after the pose is still."""

from __future__ import annotations

import numpy as np
import pytest

from creatures.body.springs import SpringBody, SpringSpec
from creatures.kinds.moves import head_for
from creatures.kinds.parts import shared_graph
from test_kind_curve import SR, TICK, advance, colony

PARENTS = np.array([-1, 0, 1, 2])
UPRIGHT = np.array([[0, 1, 0], [0, 1.5, 0], [0, 2, 0], [0, 2.5, 0]], float)
LEVEL = np.array([[0, 1, 0], [0.5, 1, 0], [1.0, 1, 0], [1.5, 1, 0]], float)


def swing(spec: SpringSpec, target: np.ndarray, seconds: float, tick: float = 0.01) -> np.ndarray:
    """Positions (steps, J, 3) of a chain let go toward ``target`` from upright."""
    body = SpringBody(spec, PARENTS, UPRIGHT)
    return np.array([body.follow(k * tick, target).copy() for k in range(1, int(round(seconds / tick)) + 1)])


def bone_lengths(positions: np.ndarray) -> np.ndarray:
    return np.linalg.norm(np.diff(positions, axis=-2), axis=-1)


def test_a_swung_limb_overshoots_rings_and_settles_on_its_pose_with_its_bones_kept():
    path = swing(SpringSpec(stiffness=400.0, damping=8.0), LEVEL, 4.0)
    tip = path[:, -1]
    assert tip[:, 1].min() < LEVEL[-1, 1] - 0.3  # it swings past the level line …
    assert np.abs(tip[-1] - LEVEL[-1]).max() < 1e-3  # … and settles on it
    assert np.abs(bone_lengths(path) - 0.5).max() < 0.005  # bones within 1 % throughout
    critical = swing(SpringSpec(stiffness=400.0, damping=40.0), LEVEL, 4.0)[:, -1]
    assert critical[:, 1].min() > tip[:, 1].min() + 0.2  # damping takes the swing away


def test_the_floor_holds_a_limb_the_pose_puts_below_it():
    below = LEVEL - [0.0, 1.5, 0.0]  # a pose half under the floor
    below[0] = [0.0, 0.2, 0.0]  # its root stands on it
    path = swing(SpringSpec(floor=0.0), below, 2.0)
    assert path[:, :, 1].min() >= 0.0
    assert path[-1, -1, 1] == pytest.approx(0.0, abs=1e-9)  # pressed onto it, not through


def test_the_realised_body_does_not_depend_on_the_tick():
    spec = SpringSpec(stiffness=300.0, damping=6.0)
    fine = swing(spec, LEVEL, 2.0, tick=0.02)[1::2]  # at 0.04, 0.08, …
    coarse = swing(spec, LEVEL, 2.0, tick=0.04)
    assert np.abs(fine - coarse).max() < 1e-9


def hand_sweep(springs: dict | None) -> tuple[np.ndarray, list[float], object, object]:
    """A curve creature holding a note sweeps its hand down through its string: the string's
    sound, and the largest force its limbs put on the string each tick, from the moment the
    motor system has arrived, for one second."""
    world = colony(0.0, **({"springs": springs} if springs else {}))
    c = world.creatures[0]
    c.group.stop_all(0.0)
    c.group.tick = lambda t: None
    c.sound(np.zeros(1), SR)
    hands = shared_graph().poses.positions[:, c.body.effector_index, 1]
    head_for(c.body, 0.0, [int(np.argmax(hands))])
    advance(world, 8.0)
    c.sound_hand(8.0)
    world.scheduler.pump()
    head_for(c.body, 8.0, [int(np.argmin(hands))])
    t = 8.0
    while not c.body.motor.arrived(t):
        advance(world, t + TICK)
        t += TICK
    pushes: list[float] = []
    forces = c.voice.coupling.forces
    c.voice.coupling.forces = lambda pose: pushes.append(float(np.abs(f := forces(pose)).max())) or f
    return advance(world, t + 1.0, sound=True), pushes, world, c


def test_a_spring_body_goes_on_pushing_its_string_after_its_pose_is_still():
    plain, still, _, _ = hand_sweep(None)
    sprung, pushes, world, c = hand_sweep({"stiffness": 150.0, "damping": 3.0})
    assert max(still) == 0.0  # a pose at rest pushes nothing
    assert np.mean(np.array(pushes) > 0.01) > 0.9  # the realised body rings on and pushes
    assert np.sqrt(np.mean((sprung - plain) ** 2)) > 0.1 * np.sqrt(np.mean(plain ** 2))  # audibly
    assert np.abs(c.positions() - c.body.pose.positions).max() > 0.005  # still moving a second on
    advance(world, world.clock.now() + 8.0)
    assert np.abs(c.positions() - c.body.pose.positions).max() < 1e-4  # then settled onto its pose
    assert np.allclose(c.figure()[0][:, 1:], c.positions()[:, 1:])  # what is drawn is the realised body
