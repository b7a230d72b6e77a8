"""Emotional tags (thesis: "emotional tags"): a stance value carries a tag that credit
assignment blends like the value, and each start of its tuple pulls the creature's mood (a
drive) toward it — a startle that comes to precede food stops being frightening."""

from __future__ import annotations

import pytest

from creatures.behaviour.value import StanceValue
from creatures.config import ConfigError
from tests.test_expectation import authored

DT = 0.05

STARTLE = """
title = "t"
duration = 90.0

[[creature]]
name = "dog"
kind = "authored"
drive_floor = -1.0

[creature.drives.mood]
decay = 0.05

[creature.mood]
drive = "mood"
strength = 0.5

[creature.percepts.click]
type = "schedule"
times = [5, 15, 25, 35, 45, 55, 65, 75]
width = 0.1

[creature.percepts.clicked]
type = "active"
tuple = "startle"

[creature.tuples.startle]
trigger = "click"
action = "rest"
until = { seconds = 0.5 }
value = { kind = "stance", value = 5.0, stance = -1.0 }

[creature.tuples.eat]
trigger = "clicked"
action = "rest"
until = { seconds = 1.0 }
value = { kind = "stance", value = 100.0, plastic = false, stance = FOOD }

[creature.tuples.wander]
action = "rest"
until = { seconds = 1.0 }
value = { value = 0.5, plastic = false }

[creature.groups.main]
tuples = ["startle", "eat", "wander"]
alpha = 0.3
"""


def run(tmp_path, food: str) -> tuple[StanceValue, list[tuple[str, float]]]:
    """90 s of a click every 10 s that food follows; returns startle's value and, per start of
    a stance tuple, (tuple, the mood it left)."""
    clock, world, dog = authored(tmp_path, STARTLE.replace("FOOD", food))
    felt: list[tuple[str, float]] = []
    emit = world.log.emit
    world.log.emit = lambda t, kind, **f: felt.append((f["tuple"], f["after"])) if kind == "mood" else emit(t, kind, **f)
    for k in range(1, int(90 / DT)):
        clock.advance(DT)
        dog.tick(k * DT)
    return dog.tuple("startle").value, felt


def test_a_startle_that_precedes_food_takes_its_stance_and_gladdens_the_mood(tmp_path):
    startle, felt = run(tmp_path, "1.0")
    assert isinstance(startle, StanceValue)
    assert startle.stance > 0.5  # credit carried food's tag back: from "run away" toward glad
    startled = [mood for tuple_, mood in felt if tuple_ == "startle"]
    assert len(startled) >= 8
    assert startled[0] == pytest.approx(-0.5)  # the first click frightens: halfway from 0 to −1
    assert startled[-1] > 0.25  # the last one brings gladness, before any food


def test_with_food_untagged_the_startle_stays_frightening(tmp_path):
    startle, felt = run(tmp_path, "0.0")
    assert -1.0 < startle.stance < 0.0  # food's neutral tag only dilutes the fear
    assert all(mood < 0.0 for tuple_, mood in felt if tuple_ == "startle")


@pytest.mark.parametrize("old, new, key, message", [
    ('[creature.mood]\ndrive = "mood"', "[creature.other]", "tuples.startle.value.kind", "[creature.mood] drive"),
    ('drive = "mood"', 'drive = "mod"', "mood.drive", "no drive named 'mod'"),
    ("drive_floor = -1.0", "drive_floor = 0.0", "tuples.startle.value.stance", "below drive_floor = 0"),
    ('value = { value = 0.5, plastic = false }', 'value = { value = 0.5, plastic = false, stance = 0.5 }',
     "tuples.wander.value.stance", 'set kind = "stance"'),
])
def test_stance_values_need_a_mood_that_can_reach_them(tmp_path, old, new, key, message):
    text = STARTLE.replace("FOOD", "1.0").replace("[creature.other]\n", "")
    assert old in text
    text = text.replace(old, new)
    if "[creature.other]" in text:  # the mood table gone, and its drive key with it
        text = text.replace("[creature.other]\nstrength = 0.5\n", "")
    with pytest.raises(ConfigError) as error:
        authored(tmp_path, text)
    assert error.value.key.endswith(key) and message in error.value.message, error.value
