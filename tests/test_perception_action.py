"""Perception as action (thesis: "perception as action"): a non-exclusive group of
perception actions, a percept sub-tree that models their activity, and perception values
(the value of perceiving something) that ground those percepts' saliency."""

from __future__ import annotations

import numpy as np
import pytest

from creatures.behaviour.action_tuple import Action, ActionTuple, DoUntil
from creatures.behaviour.perception import PerceivingPercept
from creatures.behaviour.percept import FunctionPercept
from creatures.behaviour.state_object import StateObject
from tests.test_expectation import authored

LOOKING = """
title = "looking"
duration = 60.0

[[creature]]
name = "dog"
kind = "authored"

[creature.percepts.bowl]
type = "sensor"
sensor = "bowl"

[creature.percepts.food]
type = "sensor"
sensor = "food"

[creature.percepts.no_bowl]
type = "not"
of = "bowl"

[creature.percepts.no_food]
type = "not"
of = "food"

[creature.percepts.seeing]
type = "perceiving"
group = "look"

[creature.percepts.seeing_bowl]
type = "perceiving"
tuple = "see_bowl"
parent = "seeing"

[creature.percepts.seeing_food]
type = "perceiving"
tuple = "see_food"
parent = "seeing"

[creature.tuples.see_bowl]
trigger = "bowl"
action = "rest"
until = { percept = "no_bowl" }
value = 0.1

[creature.tuples.see_food]
trigger = "food"
action = "rest"
until = { percept = "no_food" }
value = { value = 5.0, plastic = false }

[creature.tuples.approach]
trigger = "seeing_bowl"
action = "rest"
until = { seconds = 0.5 }

[creature.tuples.idle]
action = "rest"
until = { seconds = 0.5 }
value = 0.3

[creature.groups.look]
tuples = ["see_bowl", "see_food"]
perception = true
alpha = 0.3
discount = 0.9

[creature.groups.act]
tuples = ["approach", "idle"]
alpha = 0.0
"""


def test_perception_actions_run_together_and_their_values_ground_the_percepts_saliency(tmp_path):
    bowl, food = StateObject("bowl"), StateObject("food")
    clock, world, dog = authored(tmp_path, LOOKING, {"bowl": bowl, "food": food}, seed=0)
    look = dog.groups["look"]
    assert look.max_active == 2  # non-exclusive: every perception may be active at once
    seeing_bowl, seeing = dog.percept("seeing_bowl"), dog.percept("seeing")
    assert seeing_bowl.parent is seeing  # the sub-tree of perceiving
    together, bowl_alone, approach_share = 0, [], []
    for k in range(1, 1201):  # 60 s: a bowl for 2 s every 3 s, food in its second half
        t = round(k * 0.05, 2)
        clock.advance(0.05)
        phase = t % 3.0
        bowl.push(t, 1.0 if phase < 2.0 else 0.0)
        food.push(t, 1.0 if 1.0 <= phase < 2.0 else 0.0)
        dog.tick(t)
        together += len(look.active) == 2
        if abs(phase - 1.5) < 1e-6:
            strongest = seeing.evaluate(t)
        if 0.5 <= phase < 0.9:
            bowl_alone.append(seeing_bowl.evaluate(t))
            approach_share.append(dog.tuple("approach").active)
    assert together > 100  # seeing the bowl and the food at once
    # The bowl precedes food: perceiving it has become valuable, and so salient.
    early, late = np.mean(bowl_alone[:8]), np.mean(bowl_alone[-8:])  # the first and last bowls
    assert early == pytest.approx(0.1) and late > 4.0, (early, late)
    assert np.mean(approach_share[-40:]) > np.mean(approach_share[:40])
    # The sub-tree's root reads its strongest perception: the bowl alone now, food when seen.
    assert seeing.evaluate(clock.now()) == seeing_bowl.evaluate(clock.now()) > 4.0
    assert strongest == 5.0


def test_the_credit_of_what_follows_a_perception_grounds_its_value():
    """Perceiving a lion is followed by fleeing, worth −4: the lion's perception value goes
    negative, and the percept with it (a large, negatively salient perception)."""
    lion = ActionTuple("see_lion", FunctionPercept("lion", lambda t: 1.0), Action("see"), DoUntil(1.0), 0.0)
    seeing = PerceivingPercept("seeing_lion", lambda: [lion], trace=2.0, ground=0.5)
    assert seeing.evaluate(0.0) == 0.0
    lion.start(0.0, np.random.default_rng(0))
    for _ in range(6):
        seeing.update(0.5, -4.0)
    assert lion.value.to_float() == pytest.approx(-4.0 * (1 - 0.5 ** 6))
    assert seeing.evaluate(0.5) == pytest.approx(lion.value.to_float())
    lion.stop(1.0)
    assert seeing.evaluate(3.0) == pytest.approx(lion.value.to_float() * np.exp(-1.0))  # the trace fades


LION = """
title = "lion"
duration = 60.0

[[creature]]
name = "zebra"
kind = "authored"

[creature.percepts.lion]
type = "sensor"
sensor = "lion"

[creature.percepts.no_lion]
type = "not"
of = "lion"

[creature.percepts.seeing_lion]
type = "perceiving"
tuple = "see_lion"
ground = GROUND

[creature.tuples.see_lion]
trigger = "lion"
action = "rest"
until = { percept = "no_lion" }
value = 0.5

[creature.tuples.flee]
trigger = "seeing_lion"
action = "rest"
until = { seconds = 0.5 }

[creature.tuples.safe]
action = "rest"
until = { seconds = 0.5 }
value = { value = 3.0, plastic = false }

[creature.groups.look]
tuples = ["see_lion"]
perception = true
alpha = 0.0

[creature.groups.act]
tuples = ["flee", "safe"]
alpha = 0.5
discount = 1.0

[creature.learning]
groups = ["act"]
statistics = 0.0
innovation = 100.0
"""


@pytest.mark.parametrize("ground", [0.0, 0.5])
def test_an_authored_perception_value_is_grounded_by_what_perceiving_leads_to(tmp_path, ground):
    """Fleeing, triggered by perceiving the lion, is followed by safety (worth 3): with
    ``ground`` the value of perceiving the lion (0.5) is drawn toward it, and so is its
    saliency; without, it stays as authored."""
    lion = StateObject("lion")
    clock, world, zebra = authored(tmp_path, LION.replace("GROUND", str(ground)), {"lion": lion}, seed=4)
    seeing = zebra.percept("seeing_lion")
    for k in range(1, 1201):
        t = round(k * 0.05, 2)
        clock.advance(0.05)
        lion.push(t, 1.0)
        zebra.tick(t)
    value = zebra.tuple("see_lion").value.to_float()
    if ground:
        assert value > 2.0
    else:
        assert value == 0.5
    assert seeing.evaluate(clock.now()) == pytest.approx(value)  # perceiving it, as salient as it is worth
