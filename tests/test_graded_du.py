"""A graded Du (thesis, "computing expected values"): while active, a tuple's expected value
``(1 − Du)·V`` declines over its planned duration, so an interruption competes against what
is left of it. With a step Du the same rival waits for the tuple to finish."""

from __future__ import annotations

import numpy as np
import pytest

from creatures.behaviour.action_group import ActionGroup
from creatures.behaviour.action_tuple import Action, ActionTuple, DoUntil
from creatures.behaviour.percept import FunctionPercept
from creatures.clock import SimulatedClock

DT = 0.05


def test_graded_du_ramps_to_one_at_the_planned_duration(rng):
    step, graded = DoUntil(8.0), DoUntil(8.0, graded=True)
    for du in (step, graded):
        du.begin(2.0, rng)
    assert [step.evaluate(t) for t in (2.0, 6.0, 9.9, 10.0)] == [0.0, 0.0, 0.0, 1.0]
    assert [graded.evaluate(t) for t in (2.0, 6.0, 10.0, 11.0)] == pytest.approx([0.0, 0.5, 1.0, 1.0])
    until = DoUntil(None, until=FunctionPercept("never", lambda t: 0.0), graded=True)
    until.begin(0.0, rng)
    assert until.evaluate(100.0) == 0.0  # no planned duration: nothing to ramp over


def interrupted_at(graded: bool, rng: np.random.Generator) -> float | None:
    """A 10 s tuple worth 1.0 against a rival of value 1.0 whose trigger is absent at the
    selection and 0.6 from 1 s on (an absent trigger's threshold is only to beat the active
    tuple): when the rival first interrupts (a re-choice that may also confirm the active
    tuple: ``interruption`` or ``reselection``), or None if it never does."""
    rival = FunctionPercept("rival", lambda t: 0.0 if t < 1.0 else 0.6)
    events: list[dict] = []
    a = ActionTuple("a", FunctionPercept("always", lambda t: 1.0), Action("a"), DoUntil(10.0, graded=graded), 1.0)
    b = ActionTuple("b", rival, Action("b"), DoUntil(1.0), 1.0)
    group = ActionGroup("g", [a, b], rng=rng, alpha=0.0, multiple=1.25, on_event=events.append)
    clock = SimulatedClock()
    group.tick(0.0)
    assert group.active == [a]
    while clock.now() < 9.5:
        clock.advance(DT)
        group.tick(clock.now())
        if any(e["event"] in ("interruption", "reselection") for e in events):
            return clock.now()
    return None


def test_interruption_competes_against_a_declining_expected_value(rng):
    """With the graded Du the rival (0.6) interrupts once (1 − t/10)·1.0 falls to it, at 4 s;
    with the step Du it never does, the active tuple is worth its full 1.0 to the end."""
    assert interrupted_at(False, rng) is None
    assert interrupted_at(True, rng) == pytest.approx(4.0, abs=DT + 1e-9)


def test_a_graded_tuple_left_near_its_end_does_not_take_its_place_back(rng):
    """A tuple interrupted near the end of a graded Du was worth little as it ran; as a
    candidate again it is worth Tr·V. Its base value for the next interruption is the larger,
    so it must grow past that to come back, not merely back to its own value: without it the
    two tuples would take turns tick after tick (every tick an interruption)."""
    always = FunctionPercept("always", lambda t: 1.0)
    events: list[dict] = []
    a = ActionTuple("a", always, Action("a"), DoUntil(2.0, graded=True), 1.0)
    b = ActionTuple("b", FunctionPercept("later", lambda t: 0.0 if t < 1.5 else 1.0), Action("b"),
                    DoUntil(10.0, graded=True), 0.9)
    group = ActionGroup("g", [a, b], rng=rng, alpha=0.0, multiple=1.5, on_event=events.append)
    clock = SimulatedClock()
    group.tick(0.0)
    while clock.now() < 1.5:
        clock.advance(DT)
        group.tick(clock.now())
    # At 1.5 s a is worth (1 − 0.75)·1.0 = 0.25 and b, triggered, 0.9: b interrupts (or the
    # re-choice confirms a; the seed decides). Then nothing more for the rest of b's run.
    taken = [e for e in events if e["event"] == "interruption"]
    assert [(e["tuple"], e["by"]) for e in taken] == [("a", "b")]
    while clock.now() < 5.0:
        clock.advance(DT)
        group.tick(clock.now())
    assert [e for e in events if e["event"] == "interruption"] == taken
    assert group.active == [b]
