"""Duration percept trees: one shared pulse across tuples, with metrical levels as children
(thesis: "exotic duration models", the coherent pulse)."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from creatures.behaviour import Action, ActionTuple, DoUntil, WhateverPercept
from creatures.temporal.durations import LowIntegerRatioModel, SimpleDurationModel
from creatures.temporal.tree import PulsePercept, Subdivision


def play(tuple_: ActionTuple, start: float, seconds: float, rng: np.random.Generator) -> float:
    tuple_.start(start, rng)
    planned = tuple_.do_until.planned
    tuple_.stop(start + seconds)
    return planned


def test_tuples_sharing_a_pulse_keep_one_time(rng):
    root = WhateverPercept()
    beat = PulsePercept("beat", LowIntegerRatioModel(prior_pulse=0.5), parent=root)
    half = beat.subdivide(2)
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


def test_a_subdivision_teaches_its_parent():
    beat = PulsePercept("beat", SimpleDurationModel(0.5, 0.05, size=8, prior_weight=0.1))
    half = beat.subdivide(2)
    for _ in range(8):
        half.model.update(0.35)  # half-beats of 0.35 s: the beat is 0.7 s
    assert beat.pulse == pytest.approx(0.9 * 0.7 + 0.1 * 0.5)
    assert half.pulse == pytest.approx(beat.pulse / 2)
    bar = beat.group(4)
    assert isinstance(bar.model, Subdivision) and bar.model.ratio == 4
    assert bar.pulse == pytest.approx(4 * beat.pulse)


def test_levels_share_one_grid():
    beat = PulsePercept("beat", SimpleDurationModel(0.6, 1e-3, prior_weight=1.0))
    quarter_beat = beat.subdivide(2).subdivide(2)
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
    beat.subdivide(2)
    beat.level(Fraction(3), "three beats")
    assert root.find("beat/2").pulse == pytest.approx(beat.pulse / 2)
    assert [c.name for c in beat.children] == ["beat/2", "three beats"]
    assert "  beat/2 (PulsePercept)" in root.describe()
    saved = beat.to_dict()
    assert saved["model"]["kind"] == "low_integer_ratio_model"
    assert saved["children"][1]["ratio"] == [3, 1]
    assert saved["children"][1]["own"]["kind"] == "low_integer_ratio_model"  # each level's own model
    with pytest.raises(ValueError, match="positive ratio"):
        beat.level(Fraction(0))


def test_a_subdivision_learns_its_own_swing_and_keeps_the_parents_time():
    rng = np.random.default_rng(3)
    beat = PulsePercept("beat", LowIntegerRatioModel(prior_pulse=0.5))
    half = beat.subdivide(2)
    for d in 0.6 * rng.uniform(0.97, 1.03, 40):  # a drum teaches the beat
        beat.model.update(d)
    for _ in range(64):  # swung half-beats: long-short, 2:1 within each 0.6 s beat
        half.model.update(0.4 * rng.uniform(0.97, 1.03))
        half.model.update(0.2 * rng.uniform(0.97, 1.03))
    # The swung half-beats taught the beat (0.4 + 0.2 s per beat), not 0.8 or 0.4 s...
    assert beat.pulse == pytest.approx(0.6, rel=0.02) and beat.model.reanchors == 1
    assert half.pulse == pytest.approx(0.3, rel=0.02)  # ...and the level's grid is still half the beat,

    def played(n: int = 2000) -> tuple[np.ndarray, np.ndarray]:
        """Shares of long and short notes (within 5 %) among the level's sampled durations."""
        steps = np.array([half.model.sample(rng) for _ in range(n)]) / half.pulse
        return np.abs(steps / (4 / 3) - 1) < 0.05, np.abs(steps / (2 / 3) - 1) < 0.05

    long, short = played()  # ...but what the level plays is its own swing
    assert (long | short).mean() > 0.95 and abs(long.mean() - short.mean()) < 0.1
    # Tied to the parent: the drum speeds up to 130 BPM (quarters and eighths); the level
    # swings at the new tempo without having heard a single new half-beat.
    for d in 60.0 / 130.0 * rng.choice([1.0, 0.5], 60) * rng.uniform(0.97, 1.03, 60):
        beat.model.update(d)
    assert half.pulse == pytest.approx(30.0 / 130.0, rel=0.02)
    long, short = played()
    assert (long | short).mean() > 0.95 and abs(long.mean() - short.mean()) < 0.1


def test_an_untaught_level_plays_its_grid_and_an_even_one_stays_even(rng):
    beat = PulsePercept("beat", LowIntegerRatioModel(prior_pulse=0.6))
    triplet = beat.subdivide(3)
    assert np.allclose([triplet.model.sample(rng) for _ in range(50)], 0.2)  # the prior grid step
    for d in 0.2 * np.random.default_rng(2).uniform(0.97, 1.03, 60):
        triplet.model.update(d)
    steps = np.array([triplet.model.sample(rng) for _ in range(500)]) / triplet.pulse
    assert np.mean(np.abs(steps - 1.0) < 0.05) > 0.95
    assert beat.pulse == pytest.approx(0.6, rel=0.02)
