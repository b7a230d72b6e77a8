"""The colony's pulse keeps competing metrical readings (creatures/temporal/readings.py):
each reading hears every interval and is scored; the best one is the pulse the colony plays by."""

from __future__ import annotations

import json
from typing import get_args

import numpy as np
import pytest

from creatures.behaviour.models.gaussian import GaussianModel
from creatures.config import ConfigError
from creatures.runtime.pulse import LONGEST_INTERVAL, HeardPulse, PulseDuration
from creatures.runtime.schema import load_installation
from creatures.temporal.readings import LEVELS, METRES, Level, PulseReadings

DUPLE = [0.5, 0.5, 1.0, 1.0, 2.0]  # eighths, quarters, halves (in beats)
TRIPLE = [1 / 3, 1 / 3, 2 / 3, 1.0, 2.0]  # triplet eighths and quarters, quarters, halves


def performance(style: list[float], n: int, seed: int, beat: float = 0.6, jitter: float = 0.03) -> list[float]:
    """``n`` intervals drawn from ``style`` (beats) at ``beat`` seconds, played with ±3 % jitter."""
    rng = np.random.default_rng(seed)
    return [b * beat * (1.0 + rng.normal(0.0, jitter)) for b in rng.choice(style, n)]


@pytest.mark.parametrize("seed", range(5))
def test_each_metre_wins_on_its_own_rhythm_and_the_other_stays_scored(seed):
    for style, metre, other in ((DUPLE, "duple", "triple"), (TRIPLE, "triple", "duple")):
        readings = PulseReadings(["duple", "triple"], 0.5)
        for d in performance(style, 120, seed):
            readings.hear(d)
        scores = readings.scores()
        assert readings.best.metre == metre, (style, scores)
        assert scores[metre] > scores[other] + 0.2  # a clear lead, not a tie broken by order
        assert np.isfinite(scores[other])  # the losing hypothesis is still kept, and scored


@pytest.mark.parametrize("seed", range(5))
def test_the_best_reading_changes_when_the_metre_does(seed):
    readings = PulseReadings(["duple", "triple"], 0.5)
    for d in performance(DUPLE, 100, seed):
        readings.hear(d)
    assert readings.best.metre == "duple"
    switched = None
    for i, d in enumerate(performance(TRIPLE, 100, seed + 100)):
        readings.hear(d)
        if readings.best.metre == "triple":
            switched = i
            break
    assert switched is not None and switched < 40


def test_an_ambiguous_rhythm_does_not_flip_the_metre_back_and_forth():
    """Quarters alone fit both metres: the first reading keeps the colony's metre."""
    readings = PulseReadings(["duple", "triple"], 0.5)
    bests = []
    for d in performance([1.0], 200, 3):
        readings.hear(d)
        bests.append(readings.best.metre)
    assert set(bests) == {"duple"}


def heard(style: list[float], n: int, seed: int) -> HeardPulse:
    """A colony pulse of duple and triple readings that has heard ``n`` intervals of ``style``."""
    pulse = HeardPulse(0.5, ("duple", "triple"))
    for onset in np.cumsum([0.0, *performance(style, n, seed)]):
        pulse.hear(float(onset))
    pulse.settle()
    return pulse


def test_the_heard_pulse_plays_by_its_best_reading():
    """A Du resting on the colony's pulse samples the triple reading's lattice once triplets
    are heard: durations at 1/3 and 2/3 of the beat, never the duple 1/2."""
    pulse = heard(TRIPLE, 120, 1)
    assert pulse.model is pulse.readings.best.model and pulse.readings.best.metre == "triple"
    draws = np.array([PulseDuration(pulse, GaussianModel(2.0, 0.5), beats=1).sample(np.random.default_rng(i))
                      for i in range(300)]) / pulse.model.pulse
    ratios = np.array([float(r) for r in METRES["triple"]])
    nearest = ratios[np.abs(np.log(draws[:, None] / ratios)).argmin(axis=1)]
    assert (np.abs(np.log(draws / nearest)) < 0.08).all()
    assert (np.abs(draws - 0.5) > 0.05).all()


@pytest.mark.parametrize("style, metre, division", [(DUPLE, "duple", 1 / 2), (TRIPLE, "triple", 1 / 3)])
def test_each_reading_is_a_pulse_tree_and_a_note_is_placed_on_the_heard_metre(style, metre, division):
    """Every reading is a tree of levels on its own model (beat, division, bar); the heard
    metre's division is two halves or three thirds, so a note a third of a beat after the last
    is in time (phase 0) only in triple, and one a half after only in duple."""
    pulse = heard(style, 120, 4)
    assert pulse.readings.best.metre == metre
    assert all(set(levels) == set(get_args(Level)) for levels in LEVELS.values())  # every metre names each level
    beat = pulse.model.pulse
    for reading in pulse.readings.readings:
        levels = reading.levels
        assert levels["beat"].model is reading.model  # the root is the reading's own model
        assert levels["division"].parent is levels["beat"] is levels["bar"].parent
        assert levels["bar"].pulse == pytest.approx(float(LEVELS[reading.metre]["bar"]) * reading.model.pulse)
    assert pulse.readings.level("division").pulse == pytest.approx(division * beat)
    last = pulse.readings.level("beat").anchor  # entrained on the last onset heard
    assert last == pytest.approx(float(np.cumsum(performance(style, 120, 4))[-1]))
    for step, wanted in ((division, 0.0), (2 * division, 0.0), (1.0, 0.0), (0.5 if metre == "triple" else 1 / 3, None)):
        phase = pulse.phase(last + step * beat, "division")
        if wanted is None:  # the other metre's division: well off this one's grid
            assert 0.2 < phase < 0.8, (step, phase)
        else:
            assert min(phase, 1.0 - phase) < 1e-6, (step, phase)
    assert pulse.phase(last + LONGEST_INTERVAL + 0.1, "division") is None  # after a pause: no expectation
    assert HeardPulse(0.5).phase(1.0, "beat") is None  # nothing trusted yet
    saved = HeardPulse(0.5, ("duple", "triple"))
    saved.restore(json.loads(json.dumps(pulse.to_dict())))
    assert saved.readings.level("division").pulse == pytest.approx(pulse.readings.level("division").pulse)  # the trees regrow


@pytest.mark.parametrize("style, bar, division", [(DUPLE, 4.0, 1 / 2), (TRIPLE, 3.0, 1 / 3)])
def test_a_du_samples_a_level_of_the_heard_metre(style, bar, division):
    """``until = { model = { type = "pulse", level = "bar" } }`` rests a bar of the best
    reading: four beats of duple, three of triple; a division is a half or a third."""
    pulse = heard(style, 120, 6)
    rng = np.random.default_rng(0)
    fallback = GaussianModel(2.0, 0.5)
    for level, steps in (("bar", bar), ("beat", 1.0)):
        draws = np.array([PulseDuration(pulse, fallback, beats=2, level=level).sample(rng) for _ in range(200)])
        assert np.allclose(draws / pulse.model.pulse, 2 * steps, rtol=0.1), (level, draws.min(), draws.max())  # ± the heard jitter
    # The division plays steps of its grid as the beat was heard filled: duple's in two even
    # halves; triple's in three thirds, or two and one (the style's triplet quarter and eighth).
    grid = pulse.readings.level("division").pulse
    assert grid == pytest.approx(division * pulse.model.pulse)
    steps = np.array([PulseDuration(pulse, fallback, beats=1, level="division").sample(rng) for _ in range(400)]) / grid
    one, two = (np.abs(steps - k) < 0.1 * k for k in (1, 2))
    if division == 1 / 2:
        assert one.mean() > 0.9, steps
    else:
        assert one.mean() > 0.3 and two.mean() > 0.3 and (one | two).mean() > 0.9, steps
    # Without a level the Du draws the reading's ratios instead: not one length.
    ratios = np.array([PulseDuration(pulse, fallback, beats=1).sample(rng) for _ in range(200)]) / pulse.model.pulse
    assert ratios.max() / ratios.min() > 2.5


def test_the_colony_grid_is_locked_to_the_heard_beats():
    pulse = HeardPulse(0.5)
    assert pulse.next_beat(0.7) == pytest.approx(1.0)  # from 0 before anything is heard
    for onset in (10.0, 10.5, 11.0, 11.5):  # not trusted yet: each onset is a grid point
        pulse.hear(onset)
    pulse.settle()
    assert pulse.next_beat(11.6) == pytest.approx(11.5 + pulse.model.pulse)
    assert pulse.next_beat(11.6, 0.5) == pytest.approx(11.5 + pulse.model.pulse / 2)
    assert pulse.next_beat(11.5) == pytest.approx(11.5)
    for k in range(1, 10):  # trusted from here on
        pulse.hear(11.5 + 0.5 * k)
    pulse.settle()
    beat, grid = pulse.model.pulse, pulse.next_beat(16.0)
    pulse.hear(grid + 0.04)  # a beat played 40 ms late pulls the grid a quarter of the way
    pulse.settle()
    assert pulse.grid == pytest.approx(grid + 0.01, abs=1e-9)
    pulse.hear(grid + 1.5 * beat)  # an off-beat note says nothing of where the beats are
    pulse.settle()
    assert pulse.grid == pytest.approx(grid + 0.01, abs=1e-9)
    assert pulse.next_beat(grid + 0.5 * beat) == pytest.approx(grid + 0.01 + pulse.model.pulse)


def test_readings_are_saved_and_taken_back():
    pulse = heard(TRIPLE, 80, 2)
    fresh = HeardPulse(0.5, ("duple", "triple"))
    fresh.restore(json.loads(json.dumps(pulse.to_dict())))
    assert fresh.readings.best.metre == "triple"
    assert fresh.readings.scores() == pulse.readings.scores()
    assert fresh.model.to_dict() == pulse.model.to_dict()
    division = pulse.readings.best.division
    assert division.heard > 0 and fresh.readings.best.division.to_dict() == division.to_dict()  # how the beat is filled
    before = fresh.readings.scores()
    for key, bad in (("score", "high"), ("division", {"own": division.own.to_dict(), "heard": -1})):
        damaged = pulse.to_dict()
        damaged["readings"]["duple"][key] = bad
        with pytest.raises(ValueError):
            fresh.restore(damaged)
        assert fresh.readings.scores() == before  # nothing taken from a damaged file
    older = pulse.to_dict()  # saved before the division learnt: it starts afresh
    for entry in older["readings"].values():
        del entry["division"]
    fresh.restore(older)
    assert fresh.readings.best.division.heard == 0


def test_an_unknown_metre_is_a_config_error_at_its_line(tmp_path):
    path = tmp_path / "a.toml"
    path.write_text('title = "x"\n[pulse]\nreadings = ["duple", "quintuple"]\n'
                    '[[creature]]\nname = "a"\nkind = "exchange"\n')
    with pytest.raises(ConfigError) as err:
        load_installation(path)
    assert err.value.line == 3 and "pulse.readings" in err.value.key
    assert "'triple'" in str(err.value)  # the valid names are listed


def swing_ratio(pulse: HeardPulse, rng: np.random.Generator, n: int = 2000) -> float:
    """The division Du's durations split at their median: the mean of the longer half over the
    mean of the shorter (2 for a division played long-short 2:1, 1 for an even one)."""
    du = PulseDuration(pulse, GaussianModel(2.0, 0.5), beats=1, level="division")
    draws = np.sort([du.sample(rng) for _ in range(n)])
    return float(draws[n // 2:].mean() / draws[:n // 2].mean())


@pytest.mark.parametrize("seed", range(3))
def test_a_heard_swing_makes_the_division_long_short_and_a_straight_rhythm_keeps_it_even(seed):
    """Quarters, halves and pairs of eighths at 100 bpm, heard straight (the control) or swung
    (each pair 2/3 + 1/3 of the beat): a Du that keeps time on the division plays as it heard."""
    rng = np.random.default_rng(seed)
    ratios = {}
    for feel, pair in (("straight", [0.5, 0.5]), ("swung", [2 / 3, 1 / 3])):
        pulse = HeardPulse(0.5, ("duple", "triple"))
        t = 0.0
        for u in rng.random(160):
            for beats in [1.0] if u < 0.6 else [2.0] if u < 0.75 else pair:
                pulse.hear(t)
                t += 0.6 * beats * (1.0 + rng.normal(0.0, 0.015))
        pulse.hear(t)
        pulse.settle()
        assert pulse.model.pulse == pytest.approx(0.6, rel=0.03)
        assert pulse.readings.best.division.heard > 0  # even because it heard even pairs, not untaught
        ratios[feel] = swing_ratio(pulse, rng)
    assert ratios["swung"] == pytest.approx(2.0, rel=0.1), ratios
    assert ratios["straight"] < 1.1, ratios
