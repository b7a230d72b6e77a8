"""Creature save/load (DESIGN.md "State that lasts"): save → load → continue is exactly
never saving; bad files raise StateFileError naming the file; a failed save leaves the
previous state intact and no temporary files."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

import creatures.persist as persist
from creatures.behaviour.action_group import ActionGroup
from creatures.behaviour.action_tuple import Action, ActionTuple, DoUntil
from creatures.behaviour.creature import Creature
from creatures.behaviour.learning import ParametrisedAction, PerceptLearning
from creatures.behaviour.models.gaussian import GaussianModel, GaussianPercept
from creatures.behaviour.motivation import Motivation
from creatures.behaviour.percept import FunctionPercept, WhateverPercept
from creatures.behaviour.state_object import Habituation, StateObject
from creatures.behaviour.value import ScalarValue
from creatures.clock import SimulatedClock
from creatures.persist import StateFileError

DT = 0.1
SEED = 77
# The world outside the creature is a pure function of time: two kinds of pitch, and food
# for one second in every three.
WORLD = np.where(np.random.default_rng(3).random(20_000) < 0.5, -4.0, 4.0) + np.random.default_rng(4).normal(0, 0.4, 20_000)


def food_at(t: float) -> float:
    return 5.0 if (t % 3.0) < 1.0 else 0.0


class Eat(Action):
    """Eating takes hunger down (behaviour closing the motivational loop)."""

    def __init__(self, motivation: Motivation) -> None:
        super().__init__("eat")
        self.motivation = motivation

    def start(self, t: float, tuple_: ActionTuple) -> None:
        self.motivation.perturb(t, "hunger", -0.5)


def build(events: list | None = None):
    """The author's code: the same function makes the creature first and on every load."""

    def make() -> Creature:
        clock = SimulatedClock()
        rng = np.random.default_rng(SEED)
        hunger = Motivation({"hunger": 0.2}, growth={"hunger": 0.05}, ceiling=1.0)
        pitch = StateObject("pitch", history=256, habituation=Habituation(rate=0.5, recovery=5.0))
        whatever = WhateverPercept()
        heard = GaussianPercept("pitch", pitch, GaussianModel(0.0, 3.0, size=24), parent=whatever)
        food = FunctionPercept("food", food_at, parent=whatever)
        hungry = FunctionPercept("hungry", lambda t: hunger.level("hunger", t), parent=whatever)
        sing_length = GaussianModel(1.5, 0.3, size=8)
        tuples = [
            ActionTuple("pitch|sing", heard, Action("sing"), DoUntil(sing_length), 40.0),
            ActionTuple("whatever|call", whatever, ParametrisedAction("call", GaussianModel(60.0, 5.0), rng), DoUntil(0.7), 8.0),
            ActionTuple("hungry|forage", hungry, Action("forage"), DoUntil(1.2), 15.0),
            ActionTuple("food|eat", food, Eat(hunger), DoUntil(0.8), ScalarValue(100.0, plasticity=0.0)),
            ActionTuple("whatever|rest", whatever, Action("rest"), DoUntil(2.0), ScalarValue(6.0, plasticity=0.0)),
        ]
        sink = None if events is None else events.append
        group = ActionGroup("main", tuples, rng=rng, alpha=0.2, temperature=20.0, learning=PerceptLearning(statistics=0.5, innovation=0.75), on_event=sink)
        return Creature("singer", clock=clock, rng=rng, groups=[group], percepts=[whatever], state_objects=[pitch], motivation=hunger)

    return make


def live(creature: Creature, seconds: float) -> None:
    end = creature.clock.now() + seconds - 1e-9
    while creature.clock.now() < end:
        t = creature.clock.now()
        creature.state_objects["pitch"].push(t, WORLD[int(round(t / DT))])
        creature.tick()
        creature.clock.advance(DT)


def selections(events: list) -> list[tuple[float, str]]:
    return [(round(e["t"], 6), e["tuple"]) for e in events if e["event"] == "selection"]


def test_save_load_continue_equals_never_saving(tmp_path):
    events_a: list = []
    a = build(events_a)()
    live(a, 100.0)

    events_b: list = []
    b = build(events_b)()
    live(b, 50.0)
    b.save(tmp_path / "singer.json")
    del b
    events_c: list = []
    c = Creature.load(tmp_path / "singer.json", build(events_c))
    assert c.clock.now() == pytest.approx(50.0)
    live(c, 50.0)

    assert len(selections(events_a)) > 40
    assert selections(events_b) + selections(events_c) == selections(events_a)
    # What was learnt is identical too, including what grew after the save.
    assert [tp.name for tp in c.group("main").tuples] == [tp.name for tp in a.group("main").tuples]
    assert [tp.value.to_float() for tp in c.group("main").tuples] == [tp.value.to_float() for tp in a.group("main").tuples]
    assert c.rng.bit_generator.state == a.rng.bit_generator.state


def test_grown_percepts_and_hypotheses_survive(tmp_path):
    a = build()()
    live(a, 100.0)
    grown = [p.name for p in a.percepts[0].find("pitch").children]
    assert len(grown) == 2  # the two kinds of pitch split the percept
    a.save(tmp_path / "singer.json")
    b = Creature.load(tmp_path / "singer.json", build())
    assert [p.name for p in b.percepts[0].find("pitch").children] == grown
    hypotheses = [tp for tp in b.group("main").tuples if tp.trigger.name in grown]
    assert [tp.name for tp in hypotheses] == [tp.name for tp in a.group("main").tuples if tp.trigger.name in grown]
    assert len(hypotheses) >= 2
    # A grown hypothesis has no code of its own: its Ac is re-bound to the built sibling's.
    built = {tp.action.name: tp.action for tp in b.group("main").tuples if tp.trigger.name not in grown}
    assert all(tp.action is built[tp.action.name] for tp in hypotheses)
    assert b.describe() == a.describe()


def test_missing_file_names_it(tmp_path):
    with pytest.raises(StateFileError, match="nothing-here.json"):
        Creature.load(tmp_path / "nothing-here.json", build())


def saved(tmp_path) -> Path:
    creature = build()()
    live(creature, 5.0)
    path = tmp_path / "singer.json"
    creature.save(path)
    return path


def test_truncated_json_names_the_file(tmp_path):
    path = saved(tmp_path)
    text = path.read_text()
    path.write_text(text[: len(text) // 2])
    with pytest.raises(StateFileError, match=r"singer\.json:\d+: malformed JSON"):
        Creature.load(path, build())


def test_truncated_arrays_name_the_file(tmp_path):
    path = saved(tmp_path)
    npz = tmp_path / json.loads(path.read_text())["arrays"]
    npz.write_bytes(npz.read_bytes()[:100])
    with pytest.raises(StateFileError, match=npz.name):
        Creature.load(path, build())


def test_missing_key_and_mismatched_code_name_the_file(tmp_path):
    path = saved(tmp_path)
    document = json.loads(path.read_text())
    del document["rng"]
    path.write_text(json.dumps(document))
    with pytest.raises(StateFileError, match=r"singer\.json: missing key 'rng'"):
        Creature.load(path, build())

    path = saved(tmp_path)
    document = json.loads(path.read_text())
    document["groups"][0]["tuples"][1]["action"] = "fly"  # code that this build does not have
    path.write_text(json.dumps(document))
    with pytest.raises(StateFileError, match=r"singer\.json: .*'fly'"):
        Creature.load(path, build())


def test_failed_save_keeps_previous_state_and_leaves_no_temp_files(tmp_path, monkeypatch):
    path = saved(tmp_path)
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    creature = Creature.load(path, build())
    live(creature, 5.0)

    real_replace = os.replace
    calls = []

    def replace_fails_on_json(src, dst):
        calls.append(dst)
        if str(dst).endswith(".json"):
            raise OSError("disk full")
        return real_replace(src, dst)

    monkeypatch.setattr(persist.os, "replace", replace_fails_on_json)
    with pytest.raises(OSError, match="disk full"):
        creature.save(path)
    monkeypatch.undo()
    assert len(calls) == 2  # the NPZ went through, the JSON did not
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before
    Creature.load(path, build())  # and the previous pair still loads


def test_unsaveable_state_writes_nothing(tmp_path):
    creature = build()()
    words = StateObject("words", saliency_fn=len)
    words.push(0.0, "sit")  # text is fine to perceive but has no array form to save
    creature.state_objects["words"] = words
    with pytest.raises(TypeError, match="words"):
        creature.save(tmp_path / "singer.json")
    assert list(tmp_path.iterdir()) == []


def test_any_corrupted_field_gives_state_file_error_or_loads(tmp_path):
    """Replace every field of a saved file (first items of lists) by a wrong type: loading
    either succeeds or raises StateFileError naming the file — never another exception."""
    path = saved(tmp_path)
    document = json.loads(path.read_text())

    def paths(node, prefix=()):
        if prefix:
            yield prefix
        items = node.items() if isinstance(node, dict) else enumerate(node[:2]) if isinstance(node, list) else ()
        for key, child in items:
            yield from paths(child, prefix + (key,))

    broken = tmp_path / "broken.json"
    checked = 0
    for where in paths(document):
        if where == ("arrays",):
            continue  # which NPZ to read: covered by the truncated-arrays test
        for wrong in (None, "x"):
            corrupt = json.loads(json.dumps(document))
            node = corrupt
            for key in where[:-1]:
                node = node[key]
            node[where[-1]] = wrong
            broken.write_text(json.dumps(corrupt))
            try:
                Creature.load(broken, build())
            except StateFileError as exc:
                assert "broken.json" in str(exc)
            checked += 1
    assert checked > 200
