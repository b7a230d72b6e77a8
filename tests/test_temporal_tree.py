"""Duration percept trees: one shared pulse across tuples, with metrical levels as children
(thesis: "exotic duration models", the coherent pulse)."""

from __future__ import annotations

import json
from fractions import Fraction

import numpy as np
import pytest

from creatures.behaviour import Action, ActionTuple, DoUntil, WhateverPercept
from creatures.temporal.durations import LowIntegerRatioModel, SimpleDurationModel
from creatures.temporal.readings import METRES
from creatures.temporal.tree import PulsePercept, Subdivision

HALF, THIRD = Fraction(1, 2), Fraction(1, 3)


def play(tuple_: ActionTuple, start: float, seconds: float, rng: np.random.Generator) -> float:
    tuple_.start(start, rng)
    planned = tuple_.do_until.planned
    tuple_.stop(start + seconds)
    return planned


def test_tuples_sharing_a_pulse_keep_one_time(rng):
    root = WhateverPercept()
    beat = PulsePercept("beat", LowIntegerRatioModel(prior_pulse=0.5), parent=root)
    half = beat.level(HALF)
    drum = ActionTuple("drum", root, Action("drum"), DoUntil(beat.model), 1.0)
    bell = ActionTuple("bell", root, Action("bell"), DoUntil(beat.model), 1.0)
    shaker = ActionTuple("shaker", root, Action("shaker"), DoUntil(half.model), 1.0)
    t = 0.0
    for d in np.random.default_rng(5).uniform(0.58, 0.62, 40):  # only the drum plays, at 0.6 s
        play(drum, t, d, rng)
        t += d
    assert beat.pulse == pytest.approx(0.6, rel=0.02)
    # The bell and the shaker were never taught, yet keep the drum's time.
    bell_plans = np.array([play(bell, t + k, 0.6, rng) for k in range(200)]) / beat.pulse
    lattice = [float(r) for r in beat.model.ratios]
    assert np.all(np.min(np.abs(np.log(bell_plans[:, None] / lattice)), axis=1) <= beat.model.tolerance)
    assert np.mean(np.abs(np.log(bell_plans)) <= beat.model.tolerance) > 0.9  # mostly one beat
    shaker_plans = np.array([shaker.do_until.model.sample(rng) for _ in range(200)])
    assert np.allclose(shaker_plans, 0.3, rtol=0.1)


def test_levels_share_one_grid():
    beat = PulsePercept("beat", SimpleDurationModel(0.6, 1e-3, prior_weight=1.0))
    quarter_beat = beat.level(HALF).level(HALF)
    quarter_beat.entrain(10.0)  # any level can be entrained: the anchor is the root's
    assert beat.anchor == quarter_beat.anchor == 10.0
    for k in range(4):
        on_beat = 10.0 + 0.6 * k
        assert beat.evaluate(on_beat) == pytest.approx(1.0)
        assert beat.evaluate(on_beat + 0.3) < 1e-6  # the off-beat is not the beat...
        assert beat.children[0].evaluate(on_beat + 0.3) == pytest.approx(1.0)  # ...but a half-beat
        assert quarter_beat.evaluate(on_beat + 0.15) == pytest.approx(1.0)
    assert 0.0 < beat.evaluate(10.05) < 1.0


def test_pulse_levels_sit_in_a_percept_tree():
    root = WhateverPercept()
    beat = PulsePercept("beat", LowIntegerRatioModel(), parent=root)
    beat.level(HALF, "half")
    bar = beat.level(4, "bar")
    assert root.find("half").pulse == pytest.approx(beat.pulse / 2)
    assert isinstance(bar.model, Subdivision) and bar.pulse == pytest.approx(4 * beat.pulse)
    assert [c.name for c in beat.children] == ["half", "bar"]
    assert "  half (PulsePercept)" in root.describe()
    with pytest.raises(ValueError, match="positive ratio"):
        beat.level(Fraction(0))


def hear(beat: PulsePercept, level: PulsePercept, intervals: np.ndarray) -> None:
    """What a reading does with each heard interval: the beat learns it, the level hears it."""
    assert isinstance(level.model, Subdivision)
    for d in intervals:
        beat.model.update(d)
        level.model.hear(d)


def long_over_short(level: PulsePercept, rng: np.random.Generator, n: int = 2000) -> float:
    """The level's sampled durations split at their median: the mean of the longer half over
    the mean of the shorter (2 for a swung 2:1 level, 1 for an even one)."""
    steps = np.sort([level.model.sample(rng) for _ in range(n)])
    return float(steps[n // 2:].mean() / steps[:n // 2].mean())


def swung(rng: np.random.Generator, beats: int, beat: float = 0.6) -> np.ndarray:
    """Quarters and swung eighth pairs (2/3 + 1/3 of a beat) with ±1.5 % jitter."""
    cells = [[1.0] if rng.random() < 0.3 else [2 / 3, 1 / 3] for _ in range(beats)]
    return beat * np.concatenate(cells) * rng.uniform(0.985, 1.015, sum(map(len, cells)))


def test_a_level_learns_its_own_swing_from_what_is_heard_and_keeps_the_parents_time():
    rng = np.random.default_rng(3)
    # The beat hears a swung pair as two and one thirds of it (the triple reading's ratios:
    # with every ratio of one to four a beat of 0.4 s explains 0.6, 0.4, 0.2 s as simply).
    beat = PulsePercept("beat", LowIntegerRatioModel(prior_pulse=0.5, ratios=METRES["triple"]))
    half = beat.level(HALF)
    assert isinstance(half.model, Subdivision)
    hear(beat, half, swung(rng, 80))
    assert beat.pulse == pytest.approx(0.6, rel=0.02)  # the beat learns from the heard intervals
    assert half.pulse == pytest.approx(0.3, rel=0.02)  # ...and the level's grid is half of it,
    # ...but what the level plays is the swing: long and short, 2:1, about equally often.
    assert long_over_short(half, rng) == pytest.approx(2.0, rel=0.05)
    steps = np.array([half.model.sample(rng) for _ in range(2000)]) / half.pulse
    long, short = np.abs(steps / (4 / 3) - 1) < 0.05, np.abs(steps / (2 / 3) - 1) < 0.05
    assert (long | short).mean() > 0.95 and abs(long.mean() - short.mean()) < 0.1
    # Quarters are not the level's notes: only the pairs that fill a beat were learnt.
    assert half.model.heard % 2 == 0
    # Tied to the parent: the drum speeds up to 130 BPM (quarters and triplets); the level
    # swings at the new tempo without having heard a single new half-beat.
    for d in 60.0 / 130.0 * rng.choice([1.0, 1 / 3, 2 / 3], 60) * rng.uniform(0.97, 1.03, 60):
        beat.model.update(d)
    assert half.pulse == pytest.approx(30.0 / 130.0, rel=0.02)
    assert long_over_short(half, rng) == pytest.approx(2.0, rel=0.05)


def test_an_untaught_level_plays_its_grid_and_an_even_one_stays_even(rng):
    """The control: the same hearing, straight, leaves the level even."""
    beat = PulsePercept("beat", LowIntegerRatioModel(prior_pulse=0.6))
    triplet, half = beat.level(THIRD), beat.level(HALF)
    assert np.allclose([triplet.model.sample(rng) for _ in range(50)], 0.2)  # the prior grid step
    for d in 0.2 * np.random.default_rng(2).uniform(0.985, 1.015, 60):  # only the level hears them
        triplet.model.hear(d)
    assert long_over_short(triplet, rng) < 1.05
    steps = np.array([triplet.model.sample(rng) for _ in range(500)]) / triplet.pulse
    assert np.mean(np.abs(steps - 1.0) < 0.05) > 0.95
    # A level never teaches its parent (the beat learns from what it hears itself); and a
    # note as long as the beat breaks a run: eighths either side of a quarter fill no beat.
    assert beat.pulse == pytest.approx(0.6) and triplet.model.heard == 60
    for d in (0.3, 0.6, 0.3):
        half.model.hear(d)
    assert half.model.heard == 0


def test_a_level_saves_what_it_learnt():
    rng = np.random.default_rng(4)
    beat = PulsePercept("beat", LowIntegerRatioModel(prior_pulse=0.6))
    half = beat.level(HALF)
    hear(beat, half, swung(rng, 40))
    assert isinstance(half.model, Subdivision)
    fresh = Subdivision(beat.model, HALF)
    fresh.restore(json.loads(json.dumps(half.model.to_dict())))
    assert fresh.heard == half.model.heard and fresh.own.to_dict() == half.model.own.to_dict()
    assert long_over_short(beat.level(HALF), rng) < 1.05  # the control: a new level is even
    with pytest.raises(ValueError):
        fresh.restore({"own": fresh.own.to_dict(), "heard": -1})
    assert fresh.heard == half.model.heard  # a damaged state changes nothing


def test_a_du_on_a_level_ends_a_long_activation_without_teaching_it():
    """A Du on the half-beat of a 0.5 s beat (a 0.25 s grid) whose tuple lasted 20 minutes:
    the level's own model refused 4800 grid steps with a ValueError in the group's tick."""
    level = PulsePercept("beat", LowIntegerRatioModel(0.5)).level(Fraction(1, 2)).model
    du = DoUntil(level)
    du.begin(0.0, np.random.default_rng(0))
    assert du.end(1200.0) == 1200.0 and level.heard == 0
    du.begin(1200.0, np.random.default_rng(0))
    du.end(1200.5)  # a note of the level is still learnt
    assert level.heard == 1
