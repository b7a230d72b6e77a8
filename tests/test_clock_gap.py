"""A clock gap is not a duration (thesis, "percept updating – model building"): an activation
the clock jumped across (a suspended machine, a fast-forwarded offline run) teaches its Du
model nothing, while durations lived tick by tick are still learnt, however they drift."""

from __future__ import annotations

import numpy as np
import pytest

from creatures.behaviour.action_group import ActionGroup
from creatures.clock import CLOCK_GAP
from creatures.behaviour.action_tuple import Action, ActionTuple, DoUntil
from creatures.behaviour.models.gaussian import GaussianModel
from creatures.behaviour.percept import FunctionPercept
from creatures.behaviour.value import ScalarValue

DT = 0.04
NIGHT = 86400.0


def mirror_group(rng: np.random.Generator, events: list[dict]) -> tuple[ActionGroup, GaussianModel]:
    """curve's mirror: a Gaussian Du of 4 ± 1 s, the only thing to do."""
    model = GaussianModel(4.0, 1.0)
    always = FunctionPercept("always", lambda t: 1.0)
    mirror = ActionTuple("mirror", always, Action("mirror"), DoUntil(model), ScalarValue(3.0, plasticity=0.0))
    return ActionGroup("g", [mirror], rng=rng, alpha=0.0, on_event=events.append), model


def live(group: ActionGroup, start: float, seconds: float) -> float:
    t = start
    for k in range(1, int(round(seconds / DT)) + 1):
        t = round(start + k * DT, 6)
        group.tick(t)
    return t


def test_a_gaussian_du_stays_near_four_seconds_across_overnight_gaps(rng):
    events: list[dict] = []
    group, model = mirror_group(rng, events)
    group.tick(0.0)
    for day in range(30):  # a minute lived each day, the machine suspended in between
        live(group, day * NIGHT, 60.0)
    assert model.mean == pytest.approx(4.0, abs=0.5)
    assert model.buffer.max() < 4.0 + 5 * 1.0  # not one night in the buffer
    gaps = [e for e in events if e["event"] == "gap"]
    assert len(gaps) == 29 and all(e["spanned"] == ["mirror"] and e["seconds"] > NIGHT - 61 for e in gaps)
    stops = [e for e in events if e["event"] == "stop"]
    assert max(e["duration"] for e in stops) > NIGHT / 2  # the activation did span the night …
    assert len(stops) > 29 * 10  # … and the mirror still ends every few seconds on each day


def test_without_the_rule_the_night_would_be_learnt(rng):
    """The control: the same activation closed by hand teaches the model its night."""
    model = GaussianModel(4.0, 1.0)
    du = DoUntil(model)
    du.begin(0.0, rng)
    du.end(NIGHT)
    assert model.mean > 1000.0


def test_a_step_within_the_bound_is_lived_time(rng):
    events: list[dict] = []
    group, model = mirror_group(rng, events)
    group.tick(0.0)
    t = 0.0
    for _ in range(200):
        t += 0.9 * CLOCK_GAP  # a slow machine: every step late, none a gap
        group.tick(t)
    assert not [e for e in events if e["event"] == "gap"]
    assert model.buffer.max() > 4.0 + 0.9 * CLOCK_GAP - 3 * 1.0  # learnt what it lived, late stops too


def test_a_genuine_gradual_lengthening_is_still_learnt(rng):
    """Eating until the food is gone, each meal a little longer (3 s to 8 s over 40 meals), a
    night between days of meals: the Du model follows the meals, not the nights. (Lived tick
    by tick, an activation can only outlast its planned duration by one step: a prior well
    above the meals keeps the plan longer than each meal, so the food's end is what stops it.)"""
    model = GaussianModel(30.0, 2.0, size=8, prior_weight=0.1)
    gone_at = [0.0]
    food = FunctionPercept("food", lambda t: 1.0 if t < gone_at[0] else 0.0)
    eat = ActionTuple("eat", food, Action("eat"),
                      DoUntil(model, until=FunctionPercept("gone", lambda t: 1.0 if t >= gone_at[0] else 0.0)),
                      ScalarValue(1.0, plasticity=0.0))
    group = ActionGroup("g", [eat], rng=rng, alpha=0.0)
    t, means = 0.0, []
    for meal, length in enumerate(np.linspace(3.0, 8.0, 40)):
        if meal % 10 == 0:
            t += NIGHT  # the machine sleeps between days of meals, with nothing active
        gone_at[0] = t + DT + length
        t = live(group, t, length + 1.0)
        means.append(model.mean)
    assert means[-1] - means[9] > 3.0  # learnt the lengthening, 3 → 8 s
    assert model.buffer.max() < 8.0 + 2 * DT  # and no night


# -- ears that count samples keep to the clock -------------------------------------------------
SR = 22050
BLOCK = 0.02


def _tone_then_silence() -> np.ndarray:
    """Two seconds: a 0.3 s tone at 0.5 s, silence around it (one utterance, one note)."""
    from creatures.runtime.inputs import render_notes
    from midi.notes import NoteEvent

    return render_notes([NoteEvent(0.5, 69, 100, 0, 0.3)], SR, 2.0)


def _listen(ear, start: float, sound: np.ndarray) -> list:
    n = int(round(BLOCK * SR))
    heard = []
    for k in range(len(sound) // n):
        heard += ear.listen(round(start + (k + 1) * BLOCK, 6), sound[k * n:(k + 1) * n], SR)
    return heard


def test_an_ear_dates_what_it_hears_after_a_night_on_the_clock():
    """soundcreatures were deaf from the second day of the thirty-day run: the ear counted
    time in samples, so each sound after a fast-forwarded night was dated a night early and
    was never within the utterance percept's memory (0.25 s) of the clock."""
    from audio.utterance import UtterancePercept
    from creatures.kinds.hearing_parts import Ear, HearingSpec

    ear, tree = Ear(HearingSpec()), UtterancePercept("any sound")
    sound = _tone_then_silence()
    first = _listen(ear, 0.0, sound)
    night = _listen(ear, NIGHT, sound)
    assert len(first) == len(night) == 1
    assert night[0].time == pytest.approx(NIGHT + first[0].time, abs=0.02)
    tree.hear(night[0])
    assert tree.evaluate(night[0].time + 0.1) > 0.0  # perceived now, not a night ago
    stalled = _listen(ear, NIGHT + 2.0 + 0.9 * CLOCK_GAP, sound)  # a late block is not a gap
    assert stalled[0].time == pytest.approx(night[0].time + 2.0, abs=0.02)


def test_the_colony_transcribes_notes_after_a_night_at_their_time():
    """The same for the colony's transcription of the input audio (audio-only runs)."""
    import installations
    from creatures.clock import SimulatedClock
    from creatures.events import EventLog
    from creatures.runtime.schema import load_installation
    from creatures.runtime.session import Session
    from midi.sinks import MemorySink

    inst = load_installation(installations.path("tutorial/heron-1"))
    inst.settings.audio.sample_rate = SR
    clock, log = SimulatedClock(), EventLog()
    session = Session(inst, clock, log, MemorySink(), transcribe=True)
    sound, n = _tone_then_silence(), int(round(BLOCK * SR))
    for day in (0.0, NIGHT):
        for k in range(len(sound) // n):
            t = round(day + (k + 1) * BLOCK, 6)
            clock.advance_to(t)
            session.step(t, n, sound[k * n:(k + 1) * n])
    heard = [e["time"] for e in log.records if e["kind"] == "heard" and e["source"] == "audio"]
    assert len(heard) == 2 and heard[0] == pytest.approx(0.5, abs=0.1)
    assert heard[1] == pytest.approx(NIGHT + heard[0], abs=0.02)


def test_a_crowd_stands_through_a_night_instead_of_living_its_sub_steps():
    """flock's room integrated every 0.01 s of a night before: 8.6 million sub-steps, so a
    machine waking from suspend (or the thirty-day run of flock) spent hours catching up."""
    import installations
    from creatures.clock import SimulatedClock
    from creatures.events import EventLog
    from creatures.runtime.schema import load_installation
    from creatures.runtime.session import Session
    from midi.sinks import MemorySink

    inst = load_installation(installations.path("flock"))
    clock = SimulatedClock()
    session = Session(inst, clock, EventLog(), MemorySink())
    crowd = session.stage.crowd

    def tick(t: float) -> int:
        """Sub-steps lived by the tick (the compiled crowd counts them as the numpy one did;
        a skipped gap moves ``steps`` on without living them, so count the time lived)."""
        before = crowd.steered
        clock.advance_to(t)
        session.step(t, 0, None, audio=False)
        return (crowd.steered - before) // len(crowd.v)

    assert [tick(round(0.04 * k, 6)) for k in range(1, 26)] == [4] * 25  # a second lived: 100 sub-steps
    where = crowd.v.pos.copy()
    assert tick(1.0 + NIGHT) == 0 and np.array_equal(crowd.v.pos, where)  # the night is skipped, not lived
    assert tick(1.04 + NIGHT) == 4 and crowd.t == pytest.approx(1.04 + NIGHT)  # then it moves on
    assert not np.array_equal(crowd.v.pos, where)
    assert tick(1.04 + NIGHT + 0.9 * CLOCK_GAP) == 90  # a late tick is lived time
