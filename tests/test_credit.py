"""Credit assignment on a 3-tuple group, checked against numbers worked out by hand
(thesis: "credit assignment" — discount β, proximity, Tr modulation)."""

from __future__ import annotations

import numpy as np
import pytest

from creatures.behaviour.action_group import ActionGroup, group_tuple, leaf_of
from creatures.behaviour.action_tuple import Action, ActionTuple, DoUntil
from creatures.behaviour.percept import FunctionPercept, WhateverPercept


class TableAction(Action):
    """An action whose proximity to others comes from a table (default: same name → 1)."""

    def __init__(self, name: str, near: dict[str, float] | None = None) -> None:
        super().__init__(name)
        self.near = near or {}

    def proximity_to(self, other: Action) -> float:
        return 1.0 if other.name == self.name else self.near.get(other.name, 0.0)


def three_tuple_group(rng, events):
    # "sound" is heard at saliency 0.5 until t = 1; food (saliency 2, > 1 on purpose)
    # appears at t = 1 and is gone at t = 2.
    sound = FunctionPercept("sound", lambda t: 0.5 if t < 1.0 else 0.0)
    food = FunctionPercept("food", lambda t: 2.0 if 1.0 <= t < 2.0 else 0.0)
    a = ActionTuple("sound|sit", sound, TableAction("sit", {"sit-ish": 0.5}), DoUntil(5.0), 10.0)
    b = ActionTuple("whatever|sit-ish", WhateverPercept(), TableAction("sit-ish"), DoUntil(5.0), 0.0)
    c = ActionTuple("food|eat", food, TableAction("eat"), DoUntil(1.0), 100.0)
    group = ActionGroup("dog", [a, b, c], rng=rng, alpha=0.2, discount=0.8, on_event=events.append,
                        grounded_by="the credit arithmetic under test")
    return group, a, b, c


def test_credit_by_hand(rng):
    events: list[dict] = []
    group, a, b, c = three_tuple_group(rng, events)

    group.tick(0.0)  # only A has a positive expected value (B's V is 0, no food)
    assert group.active == [a]

    group.tick(1.0)  # food: C's expected value 200 jumps above everything; A's Tr is now 0
    assert group.active == [c]
    # Target β·V_C = 0.8·100 = 80. Tr at A's start: A 0.5, B 1, C 0.
    # a_A = 0.2·prox(A,A)=1·0.5 = 0.1 → V_A = 0.9·10 + 0.1·80 = 17
    # a_B = 0.2·prox(A,B)=0.5·1 = 0.1 → V_B = 0.9·0 + 0.1·80 = 8
    # a_C = 0.2·prox(A,C)=0·0   = 0   → V_C = 100
    assert a.value.to_float() == pytest.approx(17.0)
    assert b.value.to_float() == pytest.approx(8.0)
    assert c.value.to_float() == pytest.approx(100.0)

    group.tick(2.0)  # C is done (1 s); food gone, A's Tr 0: only B (V=8) can be chosen
    assert group.active == [b]
    # Target β·V_B = 6.4; Tr at C's start: C 2 (the salient food), so a_C = 0.2·1·2 = 0.4:
    # V_C = 0.6·100 + 0.4·6.4 = 62.56. A and B have proximity 0 to "eat": unchanged.
    assert c.value.to_float() == pytest.approx(62.56)
    assert a.value.to_float() == pytest.approx(17.0)
    assert b.value.to_float() == pytest.approx(8.0)

    credit = [e for e in events if e["event"] == "credit"]
    assert [(e["last"], e["new"]) for e in credit] == [("sound|sit", "food|eat"), ("food|eat", "whatever|sit-ish")]
    assert credit[0]["blended"] == pytest.approx({"sound|sit": 0.1, "whatever|sit-ish": 0.1})


def test_tr_modulation_blocks_credit_without_trigger(rng):
    """'any sound | sit' is only affected by credit if there was in fact a sound."""
    quiet = FunctionPercept("any sound", lambda t: 0.0)
    food = FunctionPercept("food", lambda t: 1.0 if t >= 1.0 else 0.0)
    sit = ActionTuple("whatever|sit", WhateverPercept(), TableAction("sit"), DoUntil(5.0), 10.0)
    sound_sit = ActionTuple("any sound|sit", quiet, TableAction("sit"), DoUntil(5.0), 10.0)
    eat = ActionTuple("food|eat", food, TableAction("eat"), DoUntil(1.0), 100.0)
    group = ActionGroup("dog", [sit, sound_sit, eat], rng=rng, alpha=0.5, discount=0.5,
                        grounded_by="the credit arithmetic under test")
    group.tick(0.0)
    group.tick(1.0)
    assert group.active == [eat]
    assert sit.value.to_float() == pytest.approx(0.5 * 10 + 0.5 * 50)  # blended halfway to 50
    assert sound_sit.value.to_float() == pytest.approx(10.0)  # no sound: no credit


def test_low_plasticity_value_moves_less(rng):
    """A value's plasticity scales the blend parameter (the lion's innate value)."""
    from creatures.behaviour.value import ScalarValue

    food = FunctionPercept("food", lambda t: 1.0 if t >= 1.0 else 0.0)
    sit = ActionTuple("whatever|sit", WhateverPercept(), TableAction("sit"), DoUntil(5.0), ScalarValue(10.0, plasticity=0.1))
    eat = ActionTuple("food|eat", food, TableAction("eat"), DoUntil(1.0), 100.0)
    group = ActionGroup("dog", [sit, eat], rng=rng, alpha=0.5, discount=1.0)
    group.tick(0.0)
    group.tick(1.0)
    assert sit.value.to_float() == pytest.approx(10.0 + 0.05 * 90.0)


def test_an_authored_plasticity_scales_what_credit_assignment_moves(rng):
    """``plasticity`` in a tuple's value table (thesis "what is value?": an innate value "with
    a far lower plasticity") reaches the value: the same credit moves it a tenth as far."""
    from creatures.authored.creature import make_value
    from creatures.authored.spec import ValueSpec
    from creatures.clock import SimulatedClock

    moved = {}
    for share in (None, 0.1):
        food = FunctionPercept("food", lambda t: 1.0 if t >= 1.0 else 0.0)
        value = make_value(ValueSpec(value=10.0, plasticity=share), None, SimulatedClock())
        sit = ActionTuple("whatever|sit", WhateverPercept(), TableAction("sit"), DoUntil(5.0), value)
        eat = ActionTuple("food|eat", food, TableAction("eat"), DoUntil(1.0), 100.0)
        group = ActionGroup("dog", [sit, eat], rng=np.random.default_rng(0), alpha=0.5, discount=1.0)
        group.tick(0.0)
        group.tick(1.0)
        moved[share] = sit.value.to_float() - 10.0
    assert moved[None] == pytest.approx(45.0) and moved[0.1] == pytest.approx(4.5)


def test_hierarchical_credit_reaches_leaves_only(rng):
    """A group dressed as a tuple runs selection inside; credit skips the group tuple and
    flows from and to the leaves (thesis: "hierarchical action-groups")."""
    food = FunctionPercept("food", lambda t: 1.0 if t >= 1.0 else 0.0)
    play = ActionTuple("whatever|fetch", WhateverPercept(), TableAction("fetch"), DoUntil(5.0), 10.0)
    inner = ActionGroup("play", [play], rng=rng, grounded_by="the outer group's credit under test")
    play_group = group_tuple(inner, WhateverPercept(), 20.0)
    eat = ActionTuple("food|eat", food, TableAction("eat"), DoUntil(1.0), 100.0)
    # An outer leaf doing the same action as the inner leaf: proximity 1 lets credit reach it.
    twin = ActionTuple("outer|fetch", WhateverPercept(), TableAction("fetch"), DoUntil(5.0), 0.0)
    outer = ActionGroup("dog", [play_group, eat, twin], rng=rng, alpha=0.5, discount=0.5, temperature=1.0,
                        grounded_by="the credit arithmetic under test")

    outer.tick(0.0)
    assert outer.active == [play_group] and inner.active == [play]
    assert leaf_of(play_group) is play
    outer.tick(0.5)
    assert inner.active == [play]  # the child keeps running while the group is active
    outer.tick(1.0)
    assert outer.active == [eat] and inner.active == []  # stopping the group stops its child
    assert play_group.value.to_float() == pytest.approx(20.0)  # not a leaf: no credit
    # Credit is computed from the last active *leaf* (inner "fetch") to the new leaf "eat":
    # target 0.5·100 = 50; the outer twin (proximity 1, Tr 1) gets a = 0.5 → 0.5·0 + 0.5·50.
    assert twin.value.to_float() == pytest.approx(25.0)
    assert eat.value.to_float() == pytest.approx(100.0)  # proximity("fetch", "eat") = 0
    assert play.value.to_float() == pytest.approx(10.0)  # inside another group: shielded


def test_a_group_tuple_starting_again_credits_the_child_it_ran_and_ends_it_as_done(rng):
    """A group tuple ends when its child does and, still triggered, starts again choosing a
    new child as it starts. The outer group credits the transition from the leaf that ran
    (thesis "hierarchical action-groups": credit between the leaves), not from the child just
    chosen; and the child whose Du ended the group stopped as done, not interrupted."""
    events: list[dict] = []
    low = ActionTuple("low", FunctionPercept("early", lambda t: 1.0 if t < 0.5 else 0.0), TableAction("low"),
                      DoUntil(1.0), 10.0)
    high = ActionTuple("high", FunctionPercept("late", lambda t: 1.0 if t >= 0.5 else 0.0), TableAction("high"),
                       DoUntil(1.0), 10.0)
    inner = ActionGroup("songs", [low, high], rng=rng, alpha=0.0, on_event=events.append)
    songs = group_tuple(inner, WhateverPercept(), 3.0)
    # An outer leaf doing what "low" does (proximity 1) but worth nothing: never chosen itself.
    twin = ActionTuple("twin", WhateverPercept(), TableAction("low"), DoUntil(5.0), 0.0)
    outer = ActionGroup("main", [songs, twin], rng=rng, alpha=0.5, discount=0.5, on_event=events.append,
                        grounded_by="the credit arithmetic under test")
    outer.tick(0.0)
    assert inner.active == [low]
    outer.tick(1.0)  # low is done, so the group tuple is; it starts again and its group chooses high
    assert outer.active == [songs] and inner.active == [high]
    credit = [e for e in events if e["event"] == "credit" and e["group"] == "main"][-1]
    assert (credit["last"], credit["new"]) == ("low", "high")
    # low → high reaches low's twin: a = 0.5 · 1 · Tr 1, toward β·V_high = 5.
    assert twin.value.to_float() == pytest.approx(2.5)
    stop = next(e for e in events if e["event"] == "stop" and e["tuple"] == "low")
    assert stop["interrupted"] is False


def test_group_du_percolates_from_active_child(rng):
    short = ActionTuple("whatever|bark", WhateverPercept(), TableAction("bark"), DoUntil(0.5), 10.0)
    inner = ActionGroup("noise", [short], rng=rng, alpha=0.0)
    outer = ActionGroup("dog", [group_tuple(inner, WhateverPercept(), 5.0)], rng=rng, alpha=0.0)
    outer.tick(0.0)
    g = outer.tuples[0]
    assert g.do_until.evaluate(0.25) == 0.0
    assert g.do_until.evaluate(0.5) == 1.0  # the child's Du says done, so the group is done


def test_a_tuple_dropped_twice_in_one_tick_is_dropped_once(rng):
    """Two fusions in one tick may each ask to drop the same tuple (issue 18: utterance trees
    re-clustered by two reviewed tuples): removals wait for the tick's end, and the second
    finds it gone."""
    group, a, b, c = three_tuple_group(rng, [])
    group.on_event = lambda event: [group.remove(c, 0.0) for _ in range(2)]  # asked twice while ticking
    group.tick(0.0)
    assert group.tuples == [a, b]
    group.remove(c, 1.0)  # and once more outside a tick
    assert group.tuples == [a, b]
