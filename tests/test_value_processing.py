"""Value signal processing (thesis: "value signal processing"): blendTo as a place for
signal processing — a leaky value forgets what is not re-earned, momentum keeps credit
assignment going the way it has been going."""

from __future__ import annotations

import math

import pytest

from creatures.behaviour.value import ProcessedValue, ScalarValue, value_from_dict
from creatures.clock import SimulatedClock
from tests.test_expectation import authored


def test_a_leaky_value_leaks_toward_its_rest_over_time_and_keeps_what_it_earns():
    clock = SimulatedClock()
    v = ProcessedValue(4.0, leak=0.1, rest=1.0, clock=clock)
    clock.advance(10.0)
    assert v.to_float() == pytest.approx(1.0 + 3.0 * math.exp(-1.0))
    v.blend_to(ScalarValue(4.0), 1.0)  # re-earned
    assert v.to_float() == pytest.approx(4.0)
    clock.advance(1e4)
    assert v.to_float() == pytest.approx(1.0)
    plain = ProcessedValue(4.0, leak=0.1, rest=1.0)  # no clock: nothing leaks
    assert plain.to_float() == 4.0


def test_momentum_carries_a_run_of_credit_further_and_one_contrary_step_only_slows_it():
    plain, heavy = ScalarValue(0.0), ProcessedValue(0.0, momentum=0.6)
    for _ in range(5):
        plain.blend_to(ScalarValue(1.0), 0.1)
        heavy.blend_to(ScalarValue(1.0), 0.1)
    assert heavy.to_float() > 1.5 * plain.to_float()
    before = heavy.to_float()
    heavy.blend_to(ScalarValue(0.0), 0.1)  # one step the other way
    assert heavy.to_float() > before  # still moving up, slower
    saved = value_from_dict(heavy.to_dict())
    assert saved.to_dict() == heavy.to_dict()  # velocity and rates survive a save


def test_authored_leak_and_momentum(tmp_path):
    text = """
    title = "t"
    duration = 10.0

    [[creature]]
    name = "c"
    kind = "authored"

    [creature.tuples.hum]
    action = "rest"
    until = { seconds = 1.0 }
    value = { value = 2.0, leak = 0.5, rest = 0.5, momentum = 0.3 }

    [creature.groups.main]
    tuples = ["hum"]
    alpha = 0.0
    """
    clock, world, c = authored(tmp_path, text)
    value = c.tuple("hum").value
    assert isinstance(value, ProcessedValue) and value.momentum == 0.3
    clock.advance(2.0)
    assert value.to_float() == pytest.approx(0.5 + 1.5 * math.exp(-1.0))
    # After a restart the loaded value still leaks on the creature's clock.
    c.restore(c.state())
    clock.advance(2.0)
    assert c.tuple("hum").value.to_float() == pytest.approx(0.5 + 1.5 * math.exp(-2.0))
