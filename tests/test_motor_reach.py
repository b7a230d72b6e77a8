"""'Get my hand to that note': end-effector goals and note placement (thesis *exchange*)."""

from __future__ import annotations

import numpy as np
import pytest

from creatures.motor.animations import creature_skeleton, example_animations, reach
from creatures.motor.graph import MotorGraph
from creatures.motor.note_space import NotePlacement, nearest_note
from creatures.motor.playback import Playback
from creatures.motor.pose import PoseSet
from creatures.motor.search import GraphPosition, PathFinder

HAND = "hand_r"
TOLERANCE = 0.15  # metres: the graph holds key-frames at 10 fps, not the continuous motion


@pytest.fixture(scope="module")
def setting():
    skeleton = creature_skeleton()
    graph = MotorGraph.build(PoseSet.concatenate(example_animations(skeleton)), k=5)
    # Where the hand really goes: the reach animation sampled six times finer than the graph.
    continuous = reach(skeleton, fps=60.0).positions[:, skeleton.index(HAND)]
    placement = NotePlacement.around(continuous)
    return graph, PathFinder(graph), continuous, placement


def notes_in_reach(placement: NotePlacement, continuous: np.ndarray) -> list[tuple[int, int, np.ndarray]]:
    """Notes whose place lies within 5 cm of the hand's continuous source motion."""
    found = []
    for pitch in range(48, 85, 3):
        for velocity in range(20, 128, 15):
            where = placement.place(pitch, velocity)
            if np.linalg.norm(continuous - where, axis=1).min() < 0.05:
                found.append((pitch, velocity, where))
    return found


def test_hand_reaches_every_note_in_reach(setting, clock):
    graph, finder, continuous, placement = setting
    notes = notes_in_reach(placement, continuous)
    assert len(notes) >= 15, "the fitted note space should put many notes within reach"
    starts = [GraphPosition(0), GraphPosition(50, 51, 0.3), GraphPosition(len(graph) - 1)]
    for k, (_, _, where) in enumerate(notes):
        start = starts[k % len(starts)]
        path = finder.to_effector(start, HAND, where)
        playback = Playback(graph, path, clock.now())
        clock.advance(playback.end_time - clock.now() + 0.01)
        hand = playback.sample(clock.now()).end_effector(HAND)
        assert np.linalg.norm(hand - where) < TOLERANCE


def test_tolerance_turns_many_poses_into_goals_and_takes_the_nearest(setting):
    graph, finder, continuous, placement = setting
    where = placement.place(66, 90)
    goals = finder.effector_goals(HAND, where, tolerance=0.2)
    hands = graph.poses.positions[goals, graph.skeleton.index(HAND)]
    assert np.all(np.linalg.norm(hands - where, axis=1) <= 0.2)
    exact = finder.to_effector(0, HAND, where)
    loose = finder.to_effector(0, HAND, where, tolerance=0.2)
    assert loose.cost <= exact.cost + 1e-12


def test_placement_maps_pitch_to_height_and_back(setting):
    _, _, _, placement = setting
    low, high = placement.place(50, 64), placement.place(80, 64)
    assert high[1] > low[1]
    for pitch in (50, 61, 77):
        for velocity in (30, 90):
            heard_pitch, heard_velocity = placement.note_at(placement.place(pitch, velocity))
            assert heard_pitch == pitch
            assert abs(heard_velocity - velocity) <= 1  # velocity is rounded to an integer
    loud, soft = placement.place(64, 120), placement.place(64, 20)
    centre = np.array(placement.centre)
    assert np.hypot(*(loud - centre)[[0, 2]]) > np.hypot(*(soft - centre)[[0, 2]])


class Note:
    def __init__(self, pitch: int, position: np.ndarray) -> None:
        self.pitch = pitch
        self.position = position


def test_strike_the_nearest_note(setting):
    graph, finder, continuous, placement = setting
    reachable = notes_in_reach(placement, continuous)
    notes = [Note(p, where) for p, _, where in reachable[::4]]
    note, path = nearest_note(finder, 0, HAND, notes, tolerance=TOLERANCE)
    # The chosen note is the one with the cheapest path among all of them.
    costs = [finder.to_effector(0, HAND, n.position, tolerance=TOLERANCE).cost for n in notes]
    assert path.cost == pytest.approx(min(costs))
    hand = graph.poses.positions[path.goal, graph.skeleton.index(HAND)]
    assert np.linalg.norm(hand - note.position) <= TOLERANCE
