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
