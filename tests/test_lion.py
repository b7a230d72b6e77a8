"""The lion problem (thesis: "phase four – extensions", "what is value?", figure 13).

A zebra that sees a lion whenever it approaches one. With the classical chain (seeing a lion
is valuable, the lion percept positive) credit assignment teaches the zebra to approach
lions. With the thesis's fix (a negative, barely plastic value for the perception action
"see lion" and a negative saliency for the lion percept) the expected value of seeing the
lion is still positive, so the perception action still wins when a lion appears, but the
value propagated back is negative: the actions that precede it are suppressed.
"""

from __future__ import annotations

import numpy as np

from creatures.behaviour.action_group import ActionGroup
from creatures.behaviour.action_tuple import Action, ActionTuple, DoUntil
from creatures.behaviour.percept import FunctionPercept, WhateverPercept
from creatures.behaviour.value import ScalarValue
from creatures.clock import SimulatedClock

DT = 0.1


class Savannah:
    """A lion shows itself one second into any approach, for one second."""

    def __init__(self) -> None:
        self.lion_until = -np.inf


class Approach(Action):
    def __init__(self, world: Savannah) -> None:
        super().__init__("approach")
        self.world = world
        self.since = 0.0

    def start(self, t: float, tuple_: ActionTuple) -> None:
        self.since = t

    def update(self, t: float) -> None:
        if t - self.since >= 1.0:
            self.world.lion_until = t + 1.0


def zebra(rng, *, fixed: bool):
    world = Savannah()
    sign = -1.0 if fixed else 1.0
    lion = FunctionPercept("lion", lambda t: sign * 1.0 if t < world.lion_until else 0.0)
    see_lion = ActionTuple(
        "lion|see lion", lion, Action("see lion"), DoUntil(0.5), ScalarValue(sign * 100.0, plasticity=0.05)
    )
    approach = ActionTuple("whatever|approach", WhateverPercept(), Approach(world), DoUntil(2.0), 10.0)
    graze = ActionTuple("whatever|graze", WhateverPercept(), Action("graze"), DoUntil(2.0), 10.0)
    flee = ActionTuple("whatever|flee", WhateverPercept(), Action("flee"), DoUntil(1.0), ScalarValue(5.0, plasticity=0.0))
    events: list[dict] = []
    group = ActionGroup("zebra", [see_lion, approach, graze, flee], rng=rng, alpha=0.2, discount=0.8, on_event=events.append)
    return group, events


def live(group: ActionGroup, seconds: float) -> None:
    clock = SimulatedClock()
    while clock.now() < seconds:
        group.tick(clock.now())
        clock.advance(DT)


def selections(events, name, since=0.0):
    return sum(e["event"] == "selection" and e.get("tuple") == name and e["t"] >= since for e in events)


def test_classical_chain_teaches_the_zebra_to_approach_lions(rng):
    group, events = zebra(rng, fixed=False)
    live(group, 300.0)
    approach, graze = group.find("whatever|approach"), group.find("whatever|graze")
    assert approach.value.to_float() > 40.0  # fed by "see lion" (β·100 = 80)
    assert approach.value.to_float() > graze.value.to_float() > 10.0  # graze precedes approach
    assert selections(events, "whatever|approach", since=150.0) > selections(events, "whatever|graze", since=150.0)


def test_negative_perception_action_suppresses_what_precedes_it(rng):
    group, events = zebra(rng, fixed=True)
    see_lion, approach = group.find("lion|see lion"), group.find("whatever|approach")
    live(group, 300.0)
    # Seeing the lion still happens whenever a lion appears: (−1)·(−100) = +100 > 0 ...
    seen = selections(events, "lion|see lion")
    assert seen >= 1
    preceding = {e["last"] for e in events if e["event"] == "credit" and e["new"] == "lion|see lion"}
    assert "whatever|approach" in preceding
    # ... its value hardly moves (plasticity 0.05) ...
    assert see_lion.value.to_float() < -90.0
    # ... and the action that precedes it is driven negative, so it is never chosen again.
    assert approach.value.to_float() < 0.0
    last_approach = max(e["t"] for e in events if e["event"] == "selection" and e["tuple"] == "whatever|approach")
    assert selections(events, "whatever|graze", since=last_approach) > 20
    assert last_approach < 100.0


def test_negative_expected_values_are_never_selected(rng):
    """A negative value meeting a positive trigger gives S < 0: never chosen, even as the
    only candidate, and even at a high Boltzmann temperature."""
    doom = ActionTuple("whatever|walk into lion", WhateverPercept(), Action("walk"), DoUntil(1.0), -5.0)
    group = ActionGroup("zebra", [doom], rng=rng, temperature=1e6, alpha=0.0)
    for k in range(50):
        group.tick(k * DT)
    assert group.active == []
