"""Graded, learnable proximity (issue 17; thesis "credit assignment": "we will see cases where
proximities are somewhere between 0 and 1"): a value in [0, 1] per ordered pair of actions
scales the credit one tuple's activation passes to another; with learning on it becomes how
reliably one action precedes the other's reward; it is saved with the creature's state and
written in the authored schema."""

from __future__ import annotations

import json

import pytest

from creatures.authored.describe import describe
from creatures.behaviour.action_group import ActionGroup
from creatures.behaviour.action_tuple import Action, ActionTuple, DoUntil
from creatures.behaviour.percept import WhateverPercept
from creatures.behaviour.proximity import Proximity
from creatures.behaviour.value import ScalarValue
from creatures.clock import SimulatedClock
from creatures.events import EventLog
from creatures.runtime.schema import load_installation
from creatures.runtime.session import Session
from midi.sinks import MemorySink
from tests.test_authored import HEAD, error_of, write


def _tuple(name: str, value: float | ScalarValue = 1.0) -> ActionTuple:
    return ActionTuple(name, WhateverPercept(), Action(name), DoUntil(100.0), value)


def _group(rng, proximity: Proximity, events: list) -> ActionGroup:
    tuples = [_tuple("other"), _tuple("rest"), _tuple("lure"), _tuple("sit"),
              _tuple("treat", ScalarValue(10.0, plasticity=0.0))]
    return ActionGroup("dog", tuples, rng=rng, alpha=0.5, discount=0.8, proximity=proximity, on_event=events.append)


def _round(group: ActionGroup, t: float, *, lure: bool = True) -> None:
    """other, then a rest, then (the lure and) sit, then the treat that rewards sit."""
    group.force("other", t)
    group.force("rest", t + 1.0)
    if lure:
        group.force("lure", t + 4.0)
    group.force("sit", t + 5.0)
    group.force("treat", t + 6.0)


def test_a_graded_proximity_scales_the_credit_by_hand(rng):
    events: list = []
    group = _group(rng, Proximity({("sit", "lure"): 0.25}), events)
    group.force("sit", 0.0)
    group.force("treat", 1.0)
    # target β·V_treat = 8; a_lure = α·0.25·Tr(1) = 0.125 → V = 0.875·1 + 0.125·8 = 1.875
    assert group.find("lure").value.to_float() == pytest.approx(1.875)
    assert group.find("other").value.to_float() == pytest.approx(1.0)  # proximity 0 by default
    assert group.find("sit").value.to_float() == pytest.approx(0.5 + 0.5 * 8)  # itself: 1
    with pytest.raises(ValueError, match=r"\[0, 1\]"):
        Proximity({("sit", "lure"): 1.5})


def test_proximity_is_learnt_from_what_reliably_precedes_a_reward(rng):
    events: list = []
    proximity = Proximity(rate=0.2, window=3.0)
    group = _group(rng, proximity, events)
    for k in range(15):
        _round(group, 10.0 * k)
    near = proximity.table
    assert near[("sit", "lure")] >= 0.9  # the lure came just before every rewarded sit
    assert near[("sit", "other")] <= 0.1  # 'other' ended 4 s before: outside the window
    last = [e for e in events if e["event"] == "credit" and e["last"] == "sit"][-1]
    assert last["blended"]["lure"] == pytest.approx(0.5 * near[("sit", "lure")], rel=0.3)
    assert last["blended"].get("other", 0.0) < 0.1 * last["blended"]["lure"]
    for k in range(15, 30):  # the lure stops coming first: its share of sit's reward fades
        _round(group, 10.0 * k, lure=False)
    assert proximity.table[("sit", "lure")] <= 0.1


def test_without_learning_or_when_fixed_a_proximity_stays_as_written(rng):
    off = Proximity({("sit", "lure"): 0.3})
    group = _group(rng, off, [])
    for k in range(10):
        _round(group, 10.0 * k)
    assert off.table == {("sit", "lure"): 0.3}
    fixed = Proximity(rate=0.5, fixed=[("sit", "other")])
    group = _group(rng, fixed, [])
    for k in range(10):
        _round(group, 10.0 * k)
    assert fixed.table[("sit", "other")] == 1.0 and fixed.table[("sit", "lure")] > 0.9


def test_an_action_no_tuple_performs_any_more_is_forgotten(rng):
    """The learnt table grew with every action a run ever tried (a sound class that fused
    away kept its row for the whole run), and a new action given a freed name would have
    inherited the old one's proximities. The author's pairs and fixed ones stay."""
    proximity = Proximity({("sit", "rest"): 0.3}, rate=0.2, window=3.0, fixed=[("sit", "other")])
    group = _group(rng, proximity, [])
    group.add(_tuple("lure"))  # a second tuple performing 'lure'
    for k in range(5):
        _round(group, 10.0 * k)
    learnt = set(proximity.table)
    assert ("sit", "lure") in learnt and ("sit", "rest") in learnt and ("sit", "other") in learnt
    first, second = [tp for tp in group.tuples if tp.action.name == "lure"]
    group.remove(first, 60.0)
    assert set(proximity.table) == learnt  # 'lure' is still performed
    group.remove(second, 60.0)
    assert not any("lure" in key for key in proximity.table)
    group.remove(group.find("rest"), 60.0)
    group.remove(group.find("other"), 60.0)
    assert proximity.table[("sit", "rest")] != 0.3 and ("sit", "other") in proximity.table


LEARNS = HEAD + """
[[creature]]
name = "p"
kind = "authored"

[creature.tuples.lure]
action = "rest"
until = { seconds = 1.0 }
value = 1.0

[creature.tuples.sit]
action = "rest"
until = { seconds = 1.0 }
value = 1.0

[creature.tuples.treat]
action = "rest"
until = { seconds = 0.5 }
value = { value = 5.0, plastic = false }

[creature.groups.main]
tuples = ["lure", "sit", "treat"]
alpha = 0.3
proximity = { sit = { lure = 0.4 } }
proximity_learning = { rate = 0.2, window = 2.0 }
"""


def _session(path) -> tuple[Session, SimulatedClock]:
    clock = SimulatedClock()
    return Session(load_installation(path), clock, EventLog(), MemorySink()), clock


def test_an_authored_proximity_table_learns_and_is_saved_with_the_state(tmp_path):
    session, clock = _session(write(tmp_path, LEARNS))
    group = session.creatures[0].groups["main"]
    assert group.proximities.table == {("sit", "lure"): 0.4} and group.proximities.rate == 0.2
    for step in range(1, 601):
        clock.advance_to(step * 0.05)
        session.step(step * 0.05, 0, None, audio=False)
    learnt = dict(group.proximities.table)
    assert learnt != {("sit", "lure"): 0.4} and all(0.0 <= p <= 1.0 for p in learnt.values())
    session.save_state(tmp_path / "state")
    assert json.loads((tmp_path / "state" / "p.json").read_text())["state"]["proximity"]["main"]["table"]
    fresh, _ = _session(tmp_path / "inst.toml")
    fresh.load_state(tmp_path / "state")
    assert fresh.creatures[0].groups["main"].proximities.table == pytest.approx(learnt)


@pytest.mark.parametrize("edit, message", [
    ("proximity = { sit = { lure = 0.4 } }", "proximity = { sit = { lura = 0.4 } }"),
    ("proximity = { sit = { lure = 0.4 } }", "proximity = { sat = { lure = 0.4 } }"),
])
def test_a_proximity_naming_a_tuple_outside_its_group_is_refused(tmp_path, edit, message):
    error = error_of(write(tmp_path, LEARNS.replace(edit, message)))
    assert "is not a tuple of group 'main'" in error.message and "did you mean" in error.message


def test_a_proximity_outside_zero_to_one_is_refused(tmp_path):
    error = error_of(write(tmp_path, LEARNS.replace("lure = 0.4", "lure = 1.4")))
    assert "groups.main.proximity.sit.lure" in str(error) and "less than or equal to 1" in error.message


def test_a_shaping_guide_outside_the_group_is_refused(tmp_path):
    text = LEARNS.replace('[creature.groups.main]', '''[creature.tuples.chase]
action = { type = "shape_gesture", guide = "stray" }
until = { done = true }

[creature.tuples.stray]
action = "rest"
until = { seconds = 1.0 }

[creature.groups.other]
tuples = ["stray"]
alpha = 0.0

[creature.groups.main]''').replace('tuples = ["lure", "sit", "treat"]', 'tuples = ["lure", "sit", "treat", "chase"]')
    text = text.replace('name = "p"\nkind = "authored"', 'name = "p"\nkind = "authored"\nbody = true')
    error = error_of(write(tmp_path, text))
    assert "the guide 'stray' is not a tuple of 'chase''s group 'main'" in error.message


def test_a_learnt_gesture_named_like_a_tuple_is_refused(tmp_path):
    text = LEARNS.replace('[creature.groups.main]', '''[creature.tuples.chase]
action = { type = "shape_gesture", guide = "lure", gesture = "sit" }
until = { done = true }

[creature.groups.main]''').replace('tuples = ["lure", "sit", "treat"]', 'tuples = ["lure", "sit", "treat", "chase"]')
    text = text.replace('name = "p"\nkind = "authored"', 'name = "p"\nkind = "authored"\nbody = true')
    error = error_of(write(tmp_path, text))
    assert "would be named 'sit'" in error.message and str(error).split(":")[1].strip().isdigit()


def test_describe_shows_a_group_proximity_table(tmp_path):
    text = describe(load_installation(write(tmp_path, LEARNS)))
    assert "proximity learnt at 0.2 over 2 s" in text and "proximity sit → lure: 0.4" in text


@pytest.mark.parametrize("gestures, message", [
    (("reach",), "'reach' is already material of the body"),
    (("spin", "spin"), "'s learnt gesture too"),
])
def test_a_learnt_gesture_named_like_the_bodys_material_or_another_gesture_is_refused(tmp_path, gestures, message):
    """Accepted, the gesture could never be dispatched: after ``dispatch_after`` lessons (hours
    into a run) :func:`dispatch` raised "the graph already has material by that name" on the
    creature's thread ('reach' is a take of the shipped figure; two tuples share one name)."""
    tables = "".join(f'''[creature.tuples.chase{k or ""}]
action = {{ type = "shape_gesture", guide = "lure", gesture = "{g}" }}
until = {{ done = true }}

''' for k, g in enumerate(gestures))
    members = ", ".join(f'"chase{k or ""}"' for k in range(len(gestures)))
    text = LEARNS.replace('[creature.groups.main]', tables + '[creature.groups.main]').replace(
        'tuples = ["lure", "sit", "treat"]', f'tuples = ["lure", "sit", "treat", {members}]')
    text = text.replace('name = "p"\nkind = "authored"', 'name = "p"\nkind = "authored"\nbody = true')
    error = error_of(write(tmp_path, text))
    assert message in error.message and str(error).split(":")[1].strip().isdigit()
