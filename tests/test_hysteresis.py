"""Hysteresis of the baseline selection mechanism (thesis: "don't dither vs appearing
aware") and the selection distribution (probabilities ∝ S, Boltzmann exp(S/T))."""

from __future__ import annotations

import numpy as np
import pytest

from creatures.behaviour.action_group import ActionGroup, selection_probabilities
from creatures.behaviour.action_tuple import Action, ActionTuple, DoUntil
from creatures.behaviour.percept import FunctionPercept
from creatures.clock import SimulatedClock

DT = 0.05


def noisy(name: str, seed: int, level: float = 1.0, spread: float = 0.05) -> FunctionPercept:
    """A trigger of saliency ``level`` ± ``spread`` noise, fresh every tick of DT seconds."""
    noise = np.random.default_rng(seed).uniform(-spread, spread, 100_000)
    return FunctionPercept(name, lambda t: level + noise[int(round(t / DT))])


def run(group: ActionGroup, clock: SimulatedClock, seconds: float) -> None:
    end = clock.now() + seconds
    while clock.now() < end - 1e-9:
        group.tick(clock.now())
        clock.advance(DT)


def two_near_equal(rng, events, multiple):
    a = ActionTuple("a", noisy("tr-a", 1), Action("a"), DoUntil(10.0), 10.0)
    b = ActionTuple("b", noisy("tr-b", 2), Action("b"), DoUntil(10.0), 10.2)
    return ActionGroup("g", [a, b], rng=rng, alpha=0.0, multiple=multiple, on_event=events.append)


def count(events, kind):
    return sum(e["event"] == kind for e in events)


def test_noise_does_not_interrupt_with_hysteresis(rng, clock):
    events: list[dict] = []
    run(two_near_equal(rng, events, multiple=1.5), clock, 100.0)
    assert count(events, "interruption") == 0
    # Every stop is a tuple running its full 10 s: ~10 selections in 100 s, no dithering.
    stops = [e for e in events if e["event"] == "stop"]
    assert all(not e["interrupted"] and e["duration"] == pytest.approx(10.0, abs=DT + 1e-9) for e in stops)
    assert count(events, "selection") == 10


def test_without_hysteresis_noise_makes_it_dither(rng, clock):
    """The same world with multiple = 1 (the pseudocode taken literally): noise alone
    interrupts the active tuple again and again. This is what the multiple prevents."""
    events: list[dict] = []
    run(two_near_equal(rng, events, multiple=1.0), clock, 100.0)
    assert count(events, "interruption") > 50


def test_a_jump_above_both_thresholds_interrupts(rng, clock):
    events: list[dict] = []
    level = {"c": 0.1}
    c_trigger = FunctionPercept("tr-c", lambda t: level["c"])
    group = two_near_equal(rng, events, multiple=1.5)
    c = group.add(ActionTuple("c", c_trigger, Action("c"), DoUntil(3.0), 10.0))
    group.temperature = 1.0  # exp(S/T): the startled choice is all but certain
    run(group, clock, 2.0)
    before = group.active[0]
    assert before is not c  # base of c is 0.1·10 = 1

    level["c"] = 0.5  # 5 ≥ 1.5 × 1 but below the active tuple's 10: above one threshold only
    run(group, clock, 2.0)
    assert group.active == [before] and count(events, "interruption") == 0

    level["c"] = 8.0  # 80: above 1.5 × its base and above the active tuple's expected value
    t_jump = clock.now()
    run(group, clock, DT)
    interruptions = [e for e in events if e["event"] == "interruption"]
    assert interruptions == [{"event": "interruption", "t": t_jump, "group": "g", "tuple": before.name, "by": "c"}]
    assert group.active == [c]


def test_selection_probabilities_proportional_and_boltzmann():
    s = np.array([3.0, 1.0, 0.0, -5.0])
    assert selection_probabilities(s) == pytest.approx([0.75, 0.25, 0.0, 0.0])
    p = selection_probabilities(s, temperature=2.0)
    assert p == pytest.approx(np.array([np.exp(1.5), np.exp(0.5), 0, 0]) / (np.exp(1.5) + np.exp(0.5)))
    assert selection_probabilities(np.array([0.0, -1.0])) is None


def test_empirical_choice_frequencies(rng):
    """Many selections from a fresh group match S / ΣS; a negative S is never chosen."""
    tr = FunctionPercept("on", lambda t: 1.0)
    tuples = [ActionTuple(n, tr, Action(n), DoUntil(1.0), v) for n, v in [("x", 6.0), ("y", 2.0), ("z", -4.0)]]
    group = ActionGroup("g", tuples, rng=rng, alpha=0.0)
    chosen = []
    for k in range(4000):
        group.tick(float(k))  # each tuple lasts 1 s, so every tick is a fresh selection
        chosen.append(group.active[0].name)
    assert chosen.count("z") == 0
    assert chosen.count("x") / len(chosen) == pytest.approx(0.75, abs=0.03)


def test_several_active_at_once(rng):
    tr = FunctionPercept("on", lambda t: 1.0)
    tuples = [ActionTuple(n, tr, Action(n), DoUntil(5.0), 1.0) for n in "pqrs"]
    group = ActionGroup("perception", tuples, rng=rng, max_active=3, alpha=0.0)
    group.tick(0.0)
    assert len(group.active) == 3 and len({tp.name for tp in group.active}) == 3
    with pytest.raises(ValueError, match="max_active"):
        ActionGroup("bad", tuples, rng=rng, max_active=0)


def test_expected_values_are_each_tuples_expected_value(rng):
    """The group's vector S (what selection compares) is Tr·V for waiting tuples and
    (1 − Du)·V for the active one, tuple by tuple."""
    level = {"t": 0.3}
    tuples = [
        ActionTuple("a", FunctionPercept("a", lambda t: level["t"]), Action("a"), DoUntil(4.0), 2.0),
        ActionTuple("b", FunctionPercept("b", lambda t: 0.5), Action("b"), DoUntil(4.0), 1.0),
    ]
    group = ActionGroup("g", tuples, rng=rng, max_active=1, alpha=0.0)
    group.tick(0.0)
    (active,) = group.active
    for t in (1.0, 3.0):
        np.testing.assert_allclose(group.expected_values(t), [tu.expected_value(t) for tu in tuples])
    assert active.expected_value(1.0) == pytest.approx((1 - active.do_until.evaluate(1.0)) * active.value.to_float())
