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
    with pytest.raises(ValueError, match="positive ratio"):
        beat.level(Fraction(0))
