"""Gesture models over motor node identities (thesis figure 32, "learning to chase your tail")."""

from __future__ import annotations

import numpy as np
import pytest

from creatures.motor.animations import creature_skeleton, example_animations
from creatures.motor.gesture import BodyMemory, GestureModel, Observation
from creatures.motor.graph import MotorGraph
from creatures.motor.pose import PoseSet
from creatures.motor.programs import MotorSystem, ProgramStack, Status, run
from creatures.persist import load_json, save_json


def noisy(sequence: str, rng: np.random.Generator, nodes: list[int], noise: list[int]) -> list[int]:
    """A BodyMemory-like sequence: the gesture, maybe with one stray node inside it and
    unrelated movement before and after."""
    core = [nodes[int(c)] for c in sequence]
    if rng.random() < 0.3:
        core.insert(int(rng.integers(1, len(core))), int(rng.choice(noise)))
    before = rng.choice(noise, size=int(rng.integers(0, 3))).tolist()
    after = rng.choice(noise, size=int(rng.integers(0, 3))).tolist()
    return [*before, *core, *after]


@pytest.fixture(scope="module")
def graph() -> MotorGraph:
    return MotorGraph.build(PoseSet.concatenate(example_animations(creature_skeleton())), k=5)


@pytest.mark.parametrize("seed", range(5))
def test_core_is_the_true_gesture(seed, graph):
    rng = np.random.default_rng(seed)
    picks = rng.permutation(len(graph))
    nodes = picks[:7].tolist()  # nodes[1..6] play "1".."6"
    noise = picks[7:].tolist()
    model = GestureModel()
    for k in range(10):
        model.learn(noisy("12345" if k % 2 == 0 else "23456", rng, nodes, noise))
    assert model.core_nodes() == nodes[1:7]
    # The model is a percept model too: it prefers the gesture to its reverse.
    assert model.log_likelihood(nodes[1:7]) > model.log_likelihood(nodes[6:0:-1])


def test_learning_extends_the_matched_chain():
    model = GestureModel()
    first = model.learn([1, 2, 3, 4, 5])
    second = model.learn([2, 3, 4, 5, 6])
    assert second[:4] == first[1:]  # "2345" explained by the existing chain
    assert len(model.states) == 6  # only "6" was added
    looped = model.learn([1, 2, 1, 2])  # a repeated pose gets a fresh state: no tangle
    assert len(set(looped)) == 4


def test_executing_the_core_reproduces_it(graph, clock):
    rng = np.random.default_rng(7)
    picks = rng.permutation(len(graph))
    nodes, noise = picks[:7].tolist(), picks[7:].tolist()
    model = GestureModel()
    for k in range(10):
        model.learn(noisy("12345" if k % 2 == 0 else "23456", rng, nodes, noise))
    program = model.to_program("new_gesture_1")
    motor = MotorSystem(graph, start=int(noise[0]))
    stack = ProgramStack(motor, program)
    stack.start(clock.now())
    assert run(stack, clock, until=60.0) is Status.DONE
    assert [node for _, node in motor.arrivals] == nodes[1:7]
    # And what the body did, read back through a BodyMemory, is explained by the model.
    memory = BodyMemory()
    for t, node in motor.arrivals:
        memory.record(node, t)
    relearnt = GestureModel()
    relearnt.learn(memory)
    assert relearnt.core_nodes() == nodes[1:7]


def test_sampling_follows_learnt_transitions(rng):
    model = GestureModel()
    for _ in range(5):
        model.learn([10, 11, 12, 13])
    walk = model.sample(rng)
    assert [model.states[s].node for s in walk] == [10, 11, 12, 13]


def test_states_carry_notes_and_timing(tmp_path):
    model = GestureModel()
    model.learn([Observation(1, 0.0, note=60), Observation(2, 0.5, note=64), Observation(3, 1.5, note=67)])
    assert [g.notes for g in model.states] == [[60], [64], [67]]
    assert [g.dwell for g in model.states[:2]] == pytest.approx([0.5, 1.0])
    save_json(tmp_path / "gesture.json", model.to_dict(), kind="gesture-model")
    restored = GestureModel.from_dict(load_json(tmp_path / "gesture.json", kind="gesture-model"))
    assert restored.core_nodes() == model.core_nodes()
    assert [g.out for g in restored.states] == [g.out for g in model.states]


def test_body_memory_ignores_staying_put_and_is_bounded():
    memory = BodyMemory(capacity=3)
    for t, node in enumerate([5, 5, 6, 7, 8]):
        memory.record(node, float(t))
    assert [o.node for o in memory] == [6, 7, 8]
    assert [o.node for o in memory.since(3.0)] == [7, 8]


def derived(model: GestureModel, probe: list[int]) -> tuple:
    """Everything a model caches, as a listening creature reads it."""
    return (model.core(), model.core_nodes(), [model.confidence(s) for s in range(len(model.states))],
            model.log_likelihood(probe))


def test_learning_invalidates_what_the_model_derived(rng):
    """Cores, confidences and matches are cached between lessons: after ``learn`` they must
    be those of a model that learnt the same sequences and was never asked before."""
    lessons = [[1, 2, 3, 4]] * 3 + [[7, 8, 9, 7, 8, 9, 7, 8, 9]] * 4 + [[1, 2, 3, 9, 5]] * 2 + [[5, 6, 7, 8]] * 3
    probe = [7, 8, 9, 1, 2, 3]
    asked = GestureModel()
    cores = []
    for k, lesson in enumerate(lessons):
        version = asked.version
        asked.learn(lesson)
        assert asked.version > version
        fresh = GestureModel()
        for earlier in lessons[:k + 1]:
            fresh.learn(earlier)
        assert derived(asked, probe) == derived(fresh, probe)
        cores.append(asked.core_nodes())
    assert sum(a != b for a, b in zip(cores, cores[1:])) >= 3  # the core really moved as the model learnt


def test_a_restored_model_derives_and_learns_like_the_original(tmp_path):
    model = GestureModel(entropy_weight=0.5, threshold=0.3)
    for lesson in [[1, 2, 3, 4]] * 3 + [[2, 3, 5, 6]]:
        model.learn(lesson)
    probe = [1, 2, 3, 5, 6]
    before = derived(model, probe)  # cached on the original before it is saved
    save_json(tmp_path / "gesture.json", model.to_dict(), kind="gesture-model")
    restored = GestureModel.from_dict(load_json(tmp_path / "gesture.json", kind="gesture-model"))
    assert derived(restored, probe) == before
    assert [restored.states_of(n) for n in range(8)] == [model.states_of(n) for n in range(8)]
    for lesson in [[5, 6, 7]] * 4:
        model.learn(lesson)
        restored.learn(lesson)
    assert derived(restored, probe) == derived(model, probe) != before


def test_a_gap_of_hours_learns_a_timing_the_saved_model_reloads():
    """Music that stops overnight: the note heard next morning follows the last one by hours.
    Learnt raw, the state's dwell was 5,395 s and the saved model was refused on reload
    (``dwell`` must be in [0, 3600]): everything the population had learnt was lost."""
    model = GestureModel()
    model.learn([Observation(1, 0.0), Observation(2, 1.0), Observation(3, 2.0)])
    model.learn([Observation(1, 10.0), Observation(2, 11.0), Observation(3, 3 * 3600.0)])
    assert max(s.dwell for s in model.states) <= 3600.0
    restored = GestureModel.from_dict(model.to_dict())
    assert [s.dwell for s in restored.states] == [s.dwell for s in model.states]
