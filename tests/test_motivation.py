"""Motivational drives as linear synthetic chemistry, integrated exactly from clock time."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from creatures import bounds
from creatures.behaviour.motivation import Motivation
from creatures.behaviour.value import ChainValue


def test_single_drive_by_hand(clock):
    hunger = Motivation({"hunger": 0.0}, growth={"hunger": 0.2}, decay={"hunger": 0.1})
    clock.advance(7.0)
    hunger.advance(clock.now())
    # x' = r − d(x − x_eq): x* = x_eq + r/d = 2, x(t) = x* + (x0 − x*)·e^(−dt)
    assert hunger.level("hunger") == pytest.approx(2.0 + (0.0 - 2.0) * math.exp(-0.7))


def test_pure_growth_is_linear_in_time():
    boredom = Motivation({"boredom": 1.0}, growth={"boredom": 0.5})
    assert boredom.level("boredom", t=4.0) == pytest.approx(3.0)
    assert boredom.level("boredom") == 1.0  # asking about the future does not move the state


def test_elapsed_time_not_tick_count():
    def make() -> Motivation:
        return Motivation(
            {"sing": 0.1, "breath": 1.0},
            growth={"sing": 0.3},
            decay={"sing": 0.05, "breath": 0.2},
            coupling={("breath", "sing"): -0.4, ("sing", "breath"): 0.1},
            floor=None,
        )

    once, ticked = make(), make()
    once.advance(10.0)
    for t in np.linspace(0.0, 10.0, 1001)[1:]:
        ticked.advance(float(t))
    np.testing.assert_allclose(ticked.levels, once.levels, rtol=1e-9)


def test_coupled_drives_match_a_numerical_integration():
    m = Motivation(
        {"sing": 0.1, "breath": 1.0},
        growth={"sing": 0.3},
        decay={"sing": 0.05, "breath": 0.2},
        equilibrium={"breath": 1.0},
        coupling={("breath", "sing"): -0.4},
        floor=None,
    )
    m.set_input(0.0, "sing", 0.2)  # someone stands at the centre of the sand

    def rate(_t, x):
        sing, breath = x
        return [0.3 + 0.2 - 0.05 * (sing - 0.1), -0.2 * (breath - 1.0) - 0.4 * sing]

    ref = solve_ivp(rate, (0.0, 6.0), [0.1, 1.0], rtol=1e-10, atol=1e-12).y[:, -1]
    m.advance(6.0)
    np.testing.assert_allclose(m.levels, ref, rtol=1e-7)
    assert m.level("breath") < 1.0  # singing used breath


def test_behaviour_closes_the_loop_with_impulses():
    m = Motivation({"hunger": 0.5}, growth={"hunger": 0.1})
    m.perturb(2.0, "hunger", -0.5)  # eat at t = 2
    assert m.level("hunger") == pytest.approx(0.2)
    m.perturb(3.0, "hunger", -5.0)
    assert m.level("hunger") == 0.0  # the floor: concentrations do not go negative
    with pytest.raises(ValueError, match="time went backwards"):
        m.advance(1.0)


def test_hungry_versus_not_hungry_reweights_whole_chains():
    m = Motivation({"hunger": 1.0, "thirst": 1.0})
    importance = m.importance({"eat": "hunger", "drink": "thirst"})
    eat, drink = ChainValue(100.0, source="eat"), ChainValue(100.0, source="drink")
    chase = ChainValue(0.0, importance=importance)
    follow_river = ChainValue(0.0, importance=importance)
    for _ in range(30):
        chase.blend_to(eat, 0.3)
        follow_river.blend_to(drink, 0.3)
    assert chase.to_float() == pytest.approx(follow_river.to_float())
    m.perturb(0.0, "hunger", -1.0)  # fed: no drive for food
    assert chase.to_float() < 0.01 * follow_river.to_float()
    assert dict(importance) == {"eat": 0.0, "drink": 1.0}


def test_round_trip_is_exact():
    m = Motivation(
        {"a": 0.3, "b": 0.7},
        growth={"a": 0.1},
        decay={"b": 0.4},
        equilibrium={"b": 0.2},
        coupling={("a", "b"): 0.25},
        ceiling=5.0,
    )
    m.set_input(1.5, "b", 0.05)
    again = Motivation.from_dict(json.loads(json.dumps(m.to_dict())))
    assert again.to_dict() == m.to_dict()
    m.advance(9.0)
    again.advance(9.0)
    np.testing.assert_array_equal(again.levels, m.levels)


def test_bad_input_is_refused_by_name():
    with pytest.raises(KeyError, match="growth: no drive named 'thirst'"):
        Motivation({"hunger": 0.0}, growth={"thirst": 1.0})
    with pytest.raises(ValueError, match="at least one drive"):
        Motivation({})
    m = Motivation({"hunger": 0.0})
    data = m.to_dict()
    del data["decay"]
    with pytest.raises(ValueError, match="missing key 'decay'"):
        Motivation.from_dict(data)
    data = m.to_dict()
    data["inputs"] = {"ghost": 1.0}
    with pytest.raises(ValueError, match="inputs: no drive named 'ghost'"):
        Motivation.from_dict(data)
    with pytest.raises(KeyError, match="'ghost'"):
        m.importance({"eat": "ghost"})


def test_an_impulse_between_live_ticks_lands_on_the_last_tick_without_a_new_step(monkeypatch):
    """Between a live run's ticks (``between_ticks``) an impulse lands at the drives' last tick
    and the next tick carries it with the step it knows: no matrix exponential for a step off
    the grid; outside, the impulse is integrated to its own time as before."""
    import creatures.behaviour.motivation as motivation_module

    def drives() -> Motivation:
        m = Motivation({"boredom": 1.0, "hunger": 0.5}, growth={"boredom": 0.3}, decay={"boredom": 0.5, "hunger": 0.2},
                       coupling={("hunger", "boredom"): 0.1})
        m.advance(0.04)
        return m

    live, offline, reference = drives(), drives(), drives()
    reference.perturb(0.04, "boredom", -0.4)  # the impulse at the last tick, integrated offline
    reference.advance(0.08)
    computed: list[float] = []
    real = Motivation._compute_propagator
    monkeypatch.setattr(Motivation, "_compute_propagator", lambda self, dt: computed.append(dt) or real(self, dt))
    with motivation_module.between_ticks():
        live.perturb(0.0537, "boredom", -0.4)
    live.advance(0.08)
    assert computed == []  # the 0.04 s step was already known
    np.testing.assert_array_equal(live.levels, reference.levels)
    offline.perturb(0.0537, "boredom", -0.4)  # outside: at its own time, two new steps
    offline.advance(0.08)
    assert len(computed) == 2
    assert not np.array_equal(offline.levels, live.levels)
    assert offline.levels == pytest.approx(live.levels, abs=0.01)  # less than a tick's decay apart


def test_drives_advanced_together_are_each_as_advanced_alone():
    """Motivation.advance_all: the stacked products give every creature's drives bit for bit
    what its own advance gives, with coupling, inputs, bounds and steps of several sizes."""
    rng = np.random.default_rng(2)
    for drives in (1, 2, 3, 5):
        names = [f"d{i}" for i in range(drives)]
        made = []
        for k in range(40):
            m = Motivation({n: rng.uniform(0, 1) for n in names}, growth={n: rng.normal(0, 0.2) for n in names},
                           decay={n: rng.uniform(0, 0.3) for n in names},
                           coupling={(a, b): rng.normal(0, 0.1) for a in names for b in names if a != b},
                           floor=None if k % 3 == 0 else 0.0, ceiling=1.0 if k % 2 else None,
                           start=float(rng.choice([0.0, 0.013])))
            m.inputs[:] = rng.normal(0, 0.1, drives)
            made.append((m, Motivation.from_dict(m.to_dict())))
        for t in (0.04, 0.08, 0.5, 0.5, 3.0):
            Motivation.advance_all([a for a, _ in made], t)
            for _, b in made:
                b.advance(t)
            for a, b in made:
                assert a.levels.tobytes() == b.levels.tobytes() and a.time == b.time


def test_a_drive_without_a_ceiling_stays_finite_and_loads_back_after_a_long_run():
    """A coupling loop that feeds itself faster than it decays (eigenvalue +0.05/s) overflowed
    to inf within four hours of 1 s ticks, and a drive that only grows (1/s, no decay) left the
    range its saved level loads in after twelve days: both stop at the open bound."""
    loop = Motivation({"a": 1.0, "b": 0.0}, decay={"a": 0.05, "b": 0.05}, equilibrium={"a": 0.0, "b": 0.0},
                      coupling={("a", "b"): 0.1, ("b", "a"): 0.1})
    for k in range(1, 6 * 3600, 60):
        loop.advance(float(k))
    assert np.isfinite(loop.levels).all() and loop.levels.max() == bounds.LARGEST_RATE
    bored = Motivation({"boredom": 0.0}, growth={"boredom": 1.0})
    bored.advance(30 * 86400.0)
    assert bored.level("boredom") == bounds.LARGEST_RATE
    for drives in (loop, bored):
        fresh = Motivation({name: 0.0 for name in drives.names})
        fresh.restore(json.loads(json.dumps(drives.to_dict())), now=0.0)
        assert np.array_equal(fresh.levels, drives.levels)


def test_a_night_long_step_of_a_drive_that_feeds_itself_reaches_its_bound_not_nan():
    """A clock gap of ten hours (the machine suspended) over drives growing at +0.05/s: one
    exact step overflowed (e^1800) and left both drives NaN for good, alone and in a crowd."""
    def loop() -> Motivation:
        return Motivation({"a": 1.0, "b": -0.5}, decay={"a": 0.05, "b": 0.05}, equilibrium={"a": 0.0, "b": 0.0},
                          coupling={("a", "b"): 0.1, ("b", "a"): 0.1}, floor=None)
    alone, crowd = loop(), [loop(), Motivation({"a": 1.0, "b": 0.0}, floor=None)]
    with np.errstate(over="ignore", invalid="ignore"):  # the first, exact, try overflows
        alone.advance(36000.0)
        Motivation.advance_all(crowd, 36000.0)
    assert alone.levels.tolist() == [bounds.LARGEST_RATE] * 2
    assert np.array_equal(crowd[0].levels, alone.levels) and crowd[1].levels.tolist() == [1.0, 0.0]
    alone.advance(36001.0)
    assert alone.levels.tolist() == [bounds.LARGEST_RATE] * 2



def test_a_clock_gap_over_the_largest_accepted_coupling_saturates_in_a_few_steps(monkeypatch):
    """Coupling at 1e6/s (the largest a config takes) over a ten-hour gap needs 2^26 clipped
    steps to stay finite: they ran for minutes, and the creature's tick with them. Levels held
    at their bounds stop the stepping (counted here as clips, stopped at 10 000)."""
    drives = Motivation({"a": 1.0, "b": -0.5}, decay={"a": 0.05, "b": 0.05}, floor=None,
                        coupling={("a", "b"): bounds.LARGEST_RATE, ("b", "a"): bounds.LARGEST_RATE})
    clip, clips = drives._clip, []

    def counted(x: np.ndarray) -> np.ndarray:
        clips.append(1)
        assert len(clips) < 10_000, "still stepping"
        return clip(x)

    monkeypatch.setattr(drives, "_clip", counted)
    with np.errstate(over="ignore", invalid="ignore"):
        drives.advance(36000.0)
    assert drives.levels.tolist() == [bounds.LARGEST_RATE] * 2


def test_a_clock_gap_over_a_feeding_loop_beside_drives_that_never_settle_ends_within_the_cap(monkeypatch):
    """A loop at the largest coupling needs 2^26 clipped steps over ten hours, and two drives
    that circle one another (coupled each way with opposite signs, no decay) never settle, so
    nothing stopped the stepping early: minutes on the creature's thread. At most
    MOST_SUBSTEPS sub-steps run: the levels come back finite and within their bounds."""
    from creatures.behaviour.motivation import MOST_SUBSTEPS

    drives = Motivation({"a": 1.0, "b": -0.5, "x": 1.0, "y": 0.0},
                        decay={"a": 0.05, "b": 0.05, "x": 0.0, "y": 0.0}, floor=None,
                        coupling={("a", "b"): bounds.LARGEST_RATE, ("b", "a"): bounds.LARGEST_RATE,
                                  ("x", "y"): 0.01, ("y", "x"): -0.01})
    clip, clips = drives._clip, []

    def counted(x: np.ndarray) -> np.ndarray:
        clips.append(1)
        assert len(clips) <= 4 * MOST_SUBSTEPS, "still stepping"
        return clip(x)

    monkeypatch.setattr(drives, "_clip", counted)
    with np.errstate(over="ignore", invalid="ignore"):
        drives.advance(36000.0)
    assert np.isfinite(drives.levels).all()
    assert np.all(np.abs(drives.levels) <= bounds.LARGEST_RATE)


def test_an_input_is_held_within_the_bound_its_saved_state_loads_in():
    """A rate past ±1e6 was held as given and saved, and the next run refused the state; a
    NaN from a broken sensor keeps the rate before it."""
    m = Motivation({"presence": 0.0})
    m.set_input(1.0, "presence", 3e10)
    assert m.inputs[0] == bounds.LARGEST_RATE
    m.set_input(2.0, "presence", float("nan"))
    assert m.inputs[0] == bounds.LARGEST_RATE
    fresh = Motivation({"presence": 0.0})
    fresh.restore(json.loads(json.dumps(m.to_dict())), now=0.0)
    assert fresh.inputs[0] == bounds.LARGEST_RATE
