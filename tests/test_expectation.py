"""Expectations (thesis: "expectations about value", "expectations about the consequences of
actions"): an action-tuple's Du end and its value are expectations; violating them is a
surprise scaled by a confidence that falls when the model was recently wrong and while it
goes untested, slows credit assignment, and a confident violation splits a percept."""

from __future__ import annotations

import textwrap

import numpy as np
import pytest

from creatures.behaviour.action_group import ActionGroup
from creatures.behaviour.action_tuple import Action, ActionTuple, DoUntil
from creatures.behaviour.confidence import Confidence
from creatures.behaviour.expectation import Expectations
from creatures.behaviour.learning import PerceptLearning
from creatures.behaviour.models.gaussian import GaussianModel, GaussianPercept
from creatures.behaviour.percept import FunctionPercept
from creatures.behaviour.state_object import StateObject
from creatures.behaviour.value import GaussianValue, ScalarValue
from creatures.kinds import KINDS
from creatures.runtime.schema import load_installation
from midi.notes import NoteEvent
from tests.test_authored import _world_with

DT = 0.01

RHYTHM = """
title = "rhythm"
duration = 60.0

[[creature]]
name = "r"
kind = "authored"

[creature.percepts.onset]
type = "onset"
window = 0.05

[creature.percepts.surprised]
type = "surprise"
tuple = "expect"

[creature.percepts.sure]
type = "confidence"
tuple = "expect"

[creature.tuples.expect]
trigger = "onset"
action = "rest"
until = { gaussian = [0.5, 0.05], percept = "onset", fresh = true, graded = true }

[creature.groups.beat]
tuples = ["expect"]
alpha = 0.0

[creature.expectations]
groups = ["beat"]
memory = 30.0
"""


def authored(tmp_path, text: str, sensors: dict | None = None, seed: int = 3):
    """(clock, world, creature) for the first creature of installation ``text``, in a world
    on a simulated clock with ``sensors``."""
    path = tmp_path / "creature.toml"
    maps = "".join(f'\n[[input]]\nosc = "/{name}"\nto = "sensor"\nname = "{name}"\n' for name in sensors or {})
    path.write_text(textwrap.dedent(text) + maps)  # the maps that write the sensors its percepts read
    spec = load_installation(path).specs[0]
    clock, world = _world_with(sensors or {})
    creature = KINDS["authored"](spec, world, np.random.default_rng(seed))
    world.add(creature)
    return clock, world, creature


def rhythm_creature(tmp_path):
    return authored(tmp_path, RHYTHM)


def play(clock, world, creature, intervals: list[float]) -> list[float]:
    """Play notes at the given inter-onset intervals, ticking every DT; returns, per note,
    the largest surprise percept reading in the interval that note ends (0: not surprised)."""
    surprised = creature.percept("surprised")
    t, per_note, best = clock.now(), [], 0.0
    due = t
    notes = iter(intervals)
    nxt = due + next(notes)
    while True:
        clock.advance(DT)
        t = clock.now()
        if t >= nxt - 1e-9:
            world.inject(NoteEvent(t, 60, 90, 0, 0.1))
            per_note.append(best)
            best = 0.0
            step = next(notes, None)
            if step is None:
                return per_note
            nxt += step
        world.deliver(t)
        creature.tick(t)
        best = max(best, surprised.evaluate(t))


def jittered(rng, ioi: float, n: int) -> list[float]:
    return list(ioi * (1.0 + 0.03 * rng.standard_normal(n)))


@pytest.mark.parametrize("new_ioi", [0.33, 0.75], ids=["faster", "slower"])
def test_surprise_fires_within_four_notes_of_a_rhythm_change_and_rarely_on_a_steady_one(tmp_path, new_ioi):
    rng = np.random.default_rng(7)
    clock, world, creature = rhythm_creature(tmp_path)
    steady = play(clock, world, creature, jittered(rng, 0.5, 200))
    fired = [s > 0.1 for s in steady[20:]]  # after the first notes have made it confident
    assert sum(fired) <= 0.05 * len(fired), f"surprised on {sum(fired)} of {len(fired)} steady notes"
    confident = creature.percept("sure").evaluate(clock.now())
    assert confident > 0.8
    changed = play(clock, world, creature, jittered(rng, new_ioi, 12))
    first = next(k for k, s in enumerate(changed) if s > 0.1)
    assert first < 4, changed
    # Recently wrong: the confidence fell, so being wrong again is less surprising.
    assert creature.percept("sure").evaluate(clock.now()) < 0.5 * confident


def test_surprise_at_interruption_follows_the_graded_du_and_is_scaled_by_confidence():
    """p = 1 − Du.evaluate(end): interrupted 2 s into a 10 s graded tuple is p = 0.8."""
    ex = Expectations(tolerance=0.25)
    rng = np.random.default_rng(0)
    rival = [0.0]
    a = ActionTuple("a", FunctionPercept("always", lambda t: 1.0), Action("a"), DoUntil(10.0, graded=True), 1.0)
    b = ActionTuple("b", FunctionPercept("rival", lambda t: rival[0]), Action("b"), DoUntil(0.5), 5.0)
    g = ActionGroup("g", [a, b], rng=rng, alpha=0.0, multiple=1.2, expectations=ex)
    t = 0.0
    for _ in range(3):  # three full activations of a: tested and right
        for _ in range(int(10.0 / 0.1) + 1):
            g.tick(t)
            t = round(t + 0.1, 6)
    state = ex.of(a)
    assert state.violations == 0 and state.tests >= 2
    confidence = state.confidence.at(t)
    assert confidence > 0.3
    start = a.started_at
    while t < start + 2.0:
        g.tick(t)
        t = round(t + 0.1, 6)
    rival[0] = 1.0
    now = state.confidence.at(t)  # a little less than before: untested for 2 s
    g.tick(t)
    assert g.active == [b]
    assert state.violations == 1
    assert state.surprise == pytest.approx(now * (1.0 - (t - start) / 10.0), rel=1e-9)
    assert state.surprise == pytest.approx(0.8 * confidence, rel=0.01)


def test_confidence_falls_when_recently_wrong_and_when_long_untested():
    c = Confidence(reliance=0.2, memory=100.0)
    for k in range(20):
        c.record(True, float(k))
    right = c.at(19.0)
    assert right > 0.95
    c.record(False, 20.0)
    c.record(False, 21.0)
    assert c.at(21.0) < 0.7 * right  # recently wrong
    c2 = Confidence(reliance=0.2, memory=100.0)
    for k in range(20):
        c2.record(True, float(k))
    assert c2.at(19.0 + 100.0) == pytest.approx(right / np.e)  # untested for 100 s
    assert Confidence().at(0.0) == 0.0  # a new tuple has no confidence yet


def _valued_pair(ex: Expectations | None, spread: float = 0.1):
    """A tuple with a Gaussian value always followed by a fixed reward worth 1.0 (β = 1)."""
    rng = np.random.default_rng(1)
    first = ActionTuple("first", FunctionPercept("p", lambda t: 1.0), Action("first"), DoUntil(1.0),
                        GaussianValue(1.0, spread=spread))
    reward = ActionTuple("reward", FunctionPercept("q", lambda t: 1.0), Action("reward"), DoUntil(1.0),
                         ScalarValue(1.0, plasticity=0.0))
    g = ActionGroup("v", [first, reward], rng=rng, alpha=0.5, discount=1.0, expectations=ex)
    g.tick(0.0)  # a first selection: both triggers (1) are recorded for credit
    first.value.value = 1.0
    return g, first, reward


def test_an_unexpected_value_surprises_and_confidence_slows_credit_assignment():
    ex = Expectations(rigidity=0.8)
    g, first, reward = _valued_pair(ex)
    for k in range(30):  # first → reward, reward as expected (1.0): confidence grows
        g.assign_credit(float(k + 1), first, reward)
    state = ex.of(first)
    assert state.violations == 0 and state.confidence.at(30.0) > 0.9
    reward.value.value = 5.0  # the world changed: the reward is worth five times as much
    before = first.value.value
    g.assign_credit(31.0, first, reward)
    assert state.violations == 1 and state.surprise > 0.8
    moved_confident = first.value.value - before
    # The same step without expectations (no confidence) moves the value further.
    g2, first2, reward2 = _valued_pair(None)
    reward2.value.value = 5.0
    g2.assign_credit(0.0, first2, reward2)
    moved = first2.value.value - 1.0
    assert moved_confident == pytest.approx(moved * (1.0 - 0.8 * state.confidence.at(31.0)))
    assert moved_confident < 0.5 * moved


def _bimodal_learning():
    """'sing' (a 4 s graded Du) on a Gaussian percept whose buffer has become bimodal, worth
    less than the innovation threshold (so value alone never reviews it), and a rival that
    interrupts it once ``rival[0]`` is set; the group has a learner and expectations."""
    state = StateObject("pitch")
    state.push(0.0, 55.0)
    model = GaussianModel(60.0, 3.0, size=32)
    for k in range(32):
        model.update(55.0 + (k % 2) * 10.0 + 0.3 * np.sin(k))  # two clusters, 55 and 65
    percept = GaussianPercept("pitch", state, model)
    events: list[dict] = []
    learner = PerceptLearning(statistics=1.0, innovation=10.0, on_event=events.append)
    ex = Expectations(confident=0.5, on_event=events.append)
    rival = [0.0]
    sing = ActionTuple("sing", percept, Action("sing"), DoUntil(4.0, graded=True), 1.0)
    other = ActionTuple("shout", FunctionPercept("rival", lambda t: rival[0]), Action("shout"), DoUntil(1.0), 10.0)
    g = ActionGroup("g", [sing, other], rng=np.random.default_rng(2), alpha=0.0, learning=learner, expectations=ex)
    return g, sing, ex, percept, events, rival


def _run(group: ActionGroup, start: float, seconds: float) -> float:
    t = start
    while t < start + seconds - 1e-9:
        group.tick(t)
        t = round(t + 0.1, 6)
    return t


def test_a_confident_expectation_violated_fissions_the_percept_and_a_kept_one_does_not():
    g, sing, ex, percept, events, rival = _bimodal_learning()
    t = _run(g, 0.0, 41.0)  # ten full songs: each ends as its Du expected
    assert ex.of(sing).tests >= 9 and ex.of(sing).violations == 0
    assert percept.children == []  # confident, and never wrong: the tree stays as it is
    assert ex.of(sing).confidence.at(t) > 0.5
    t = _run(g, t, 1.0)  # 1 s into a song (the last one ended at 40 s)
    rival[0] = 1.0
    t = _run(g, t, 0.2)  # interrupted: p = 1 − Du.evaluate(end) ≈ 0.75, from a confident tuple
    assert ex.of(sing).violations == 1
    assert len(percept.children) == 2
    assert [e["event"] for e in events].count("fission") == 1
    assert len(g.tuples) == 4  # a hypothesis on each child


def test_an_unconfident_expectation_violated_does_not_fission_the_percept():
    g, sing, ex, percept, events, rival = _bimodal_learning()
    t = _run(g, 0.0, 1.0)  # the first song: nothing is trusted yet
    rival[0] = 1.0
    _run(g, t, 0.2)
    assert ex.of(sing).violations == 1 and ex.of(sing).surprise == 0.0
    assert percept.children == [] and not any(e["event"] == "fission" for e in events)


def test_surprise_and_confidence_are_percepts_other_tuples_act_on(tmp_path):
    """A 'startle' tuple triggered by the surprise percept runs after the rhythm changes,
    never while it is steady."""
    text = RHYTHM + """
[creature.groups.react]
tuples = ["startle"]
alpha = 0.0

[creature.tuples.startle]
trigger = "surprised"
action = "rest"
until = { seconds = 0.2 }
"""
    clock, world, creature = authored(tmp_path, text)
    startle = creature.tuple("startle")
    rng = np.random.default_rng(5)
    play(clock, world, creature, jittered(rng, 0.5, 60))
    assert startle.started_at is None
    play(clock, world, creature, jittered(rng, 0.3, 6))
    assert startle.started_at is not None


KEEP_TIME = """
title = "keep time"
duration = 60.0

[[creature]]
name = "r"
kind = "authored"

[creature.percepts.visitor]
type = "onset"
window = 0.01
outside = true

[creature.percepts."in time"]
type = "in_time"
level = "division"

[creature.percepts.surprised]
type = "surprise"
tuple = "keep time"
low = 0.2
high = 0.4

[creature.tuples."keep time"]
trigger = "visitor"
action = "rest"
until = { seconds = 0.01, percept = "in time" }

[creature.groups.time]
tuples = ["keep time"]
alpha = 0.0

[creature.expectations]
groups = ["time"]
tolerance = 0.5
grace = 0.0

[[creature]]
name = "s"
kind = "authored"

[creature.tuples.idle]
action = "rest"
until = { seconds = 1.0 }

[creature.groups.main]
tuples = ["idle"]
alpha = 0.0
"""


def test_a_note_off_the_heard_metre_is_a_surprise_and_a_colony_note_is_not_judged(tmp_path):
    """Perception as action with an expectation: hearing a visitor's note ends with its fit to
    the division of the heard metre (``in_time``, on the best reading's pulse tree). Eighths
    and quarters in duple fit; the first swung eighth (2/3 + 1/3 of a beat) does not, and
    surprises; a colony creature's note, however far off, is not the visitor's to judge."""
    from creatures.runtime.pulse import HeardPulse

    path = tmp_path / "keep.toml"
    path.write_text(KEEP_TIME)
    clock, world = _world_with({})
    world.pulse = HeardPulse(0.5, ("duple", "triple"))
    rng = np.random.default_rng(8)
    r, s = (KINDS["authored"](spec, world, rng) for spec in load_installation(path).specs)
    world.add(r)
    world.add(s)
    state = r.expectations.of(r.tuple("keep time"))
    surprised = r.percept("surprised")

    played = [0.0]  # when the last note was played

    def play(beats: list[float], source: str = "input") -> list[float]:
        """The visitor (or ``source``) plays notes ``beats`` apart at 100 bpm (±1 % jitter);
        per note, the most surprised ``r`` was before the next."""
        per_note = []  # the most surprised r was on the way to each note: that judges the last
        for k, beat in enumerate([*beats, 0.2]):  # and a moment after the last, while it is judged
            due = played[0] = played[0] + beat * 0.6 * (1.0 + 0.01 * rng.standard_normal())
            if k < len(beats):
                world.inject(NoteEvent(due, 60, 90, 0, 0.1), source)
            most = 0.0
            while clock.now() < due:
                clock.advance(DT)
                world.deliver(clock.now())
                r.tick(clock.now())
                most = max(most, surprised.evaluate(clock.now()))
            per_note.append(most)
        return per_note[1:]

    steady = play(list(rng.choice([0.5, 0.5, 1.0, 2.0], 80)))
    # The first notes, before the pulse is trusted, are out of time and untrusted (no surprise).
    assert max(steady) == 0.0 and state.confidence.at(clock.now()) > 0.8
    violations = state.violations
    tests = state.tests
    play([0.5, 1.0 / 3.0, 0.5], source="s")  # the colony's own notes, off the division
    assert state.tests == tests
    assert max(play([1.0, 0.5, 0.5, 1.0])) == 0.0  # the visitor again, in time
    swung = play([2 / 3, 1 / 3] * 4)
    assert max(swung[:2]) == 1.0, swung  # the first swung eighth startles at once
    assert state.violations >= violations + 3


@pytest.mark.parametrize("old, new, key, message", [
    ('groups = ["beat"]\nmemory', 'groups = ["bea"]\nmemory', "expectations.groups", "did you mean 'beat'"),
    ('tuple = "expect"\n\n[creature.percepts.sure]', 'tuple = "expec"\n\n[creature.percepts.sure]',
     "percepts.surprised.tuple", "did you mean 'expect'"),
    ('[creature.expectations]\ngroups = ["beat"]', '[creature.expectations]\ngroups = []', "percepts.surprised.type",
     "[creature.expectations] groups"),
    ('percept = "onset", fresh = true', 'fresh = true', "tuples.expect.until.fresh", "give the Du a 'percept'"),
    ('tuple = "expect"\n\n[creature.percepts.sure]', 'tuple = "expect"\nlow = 0.2\n\n[creature.percepts.sure]',
     "percepts.surprised", "give both 'low' and 'high'"),
    ('groups = ["beat"]\nmemory', 'groups = ["beat"]\ntransitions = true\nmemory', "expectations.transitions",
     "tuples with until.follow"),
])
def test_bad_expectation_keys_are_errors_at_their_line(tmp_path, old, new, key, message):
    from tests.test_authored import error_of

    assert old in RHYTHM
    path = tmp_path / "bad.toml"
    path.write_text(textwrap.dedent(RHYTHM.replace(old, new)))
    err = error_of(path)
    assert key in str(err) and message in str(err), str(err)
    assert err.line is not None


SUCCESSION = """
title = "t"
duration = 30.0

[[creature]]
name = "c"
kind = "authored"

[creature.percepts.a_cue]
type = "schedule"
times = [0, 2, 4, 6, 8, 10, 12, 14, 16, 18, 20]
width = 0.5

[creature.percepts.b_cue]
type = "schedule"
times = [1, 3, 5, 7, 9, 11, 13, 15, 17, 19]
width = 0.5

[creature.percepts.c_cue]
type = "schedule"
times = [21]
width = 0.5

[creature.percepts.surprised]
type = "surprise"
tuple = "a"

[creature.tuples.a]
trigger = "a_cue"
action = "rest"
until = { seconds = 1.0, follow = true }

[creature.tuples.b]
trigger = "b_cue"
action = "rest"
until = { seconds = 1.0, follow = true }

[creature.tuples.c]
trigger = "c_cue"
action = "rest"
until = { seconds = 1.0, follow = true }

[creature.groups.main]
tuples = ["a", "b", "c"]
alpha = 0.0

[creature.expectations]
groups = ["main"]
transitions = TRANSITIONS
decay = 5.0
"""


@pytest.mark.parametrize("transitions", [True, False])
def test_an_unexpected_successor_surprises_the_tuple_whose_forward_model_it_violates(tmp_path, transitions):
    """a is always followed by b for 20 s, then by c, which it has never been followed by
    (thesis "expectations about the consequences of actions": with forward transition
    models "surprise can be the result of a character being able to perform an unexpected
    action"). Without ``transitions`` only the Du ends are judged, and none is violated."""
    clock, world, c = authored(tmp_path, SUCCESSION.replace("TRANSITIONS", str(transitions).lower()))
    surprises: list[dict] = []
    emit = world.log.emit
    world.log.emit = lambda t, kind, **f: surprises.append({"t": t, **f}) if kind == "surprise" else emit(t, kind, **f)
    before = 0.0
    for k in range(1, 500):  # 25 s
        t = round(k * 0.05, 2)
        clock.advance(0.05)
        c.tick(t)
        if t < 21.0:
            before = max(before, c.percept("surprised").evaluate(t))
    after = c.percept("surprised").evaluate(clock.now())
    if not transitions:
        assert surprises == [] and after == 0.0
        return
    assert before == 0.0  # a → b, as a has always been followed
    (surprise,) = surprises
    assert (surprise["tuple"], surprise["why"]) == ("a", "unexpected successor") and 21.0 <= surprise["t"] < 21.5
    # N·p(a → c) = 3 · 0.1 / 1.3 over a window of ten a → b: p = 1 − 0.23, from a confident a
    assert surprise["p"] == pytest.approx(1.0 - 3 * 0.1 / 1.3)
    assert surprise["confidence"] > 0.9 and surprise["surprise"] == pytest.approx(surprise["confidence"] * surprise["p"])
    assert after > 0.3  # the surprise percept of a, fading over ``decay``


def test_a_removed_tuple_leaves_the_expectations_so_a_growing_and_fusing_tree_holds_no_more():
    """Each hypothesis a fission makes has a new name and a fusion removes it: a month of
    them left every one (its percept and models with it) in the expectations, 400 after 400
    cycles; only the tuples still in the group are kept now."""
    ex = Expectations()
    keep = ActionTuple("keep", FunctionPercept("p", lambda t: 1.0), Action("keep"), DoUntil(1.0), 1.0)
    g = ActionGroup("g", [keep], rng=np.random.default_rng(0), alpha=0.0, expectations=ex)
    t = 0.0
    for k in range(400):
        grown = g.add(ActionTuple(f"p.{k}|sing", FunctionPercept(f"p.{k}", lambda t: 1.0), Action("sing"),
                                  DoUntil(0.5), 1.0))
        g.force(grown.name, t)
        t += 1.0
        g.tick(t)  # ended on its plan: judged
        assert ex.of(grown).tests >= 1
        g.remove(grown, t)
    assert len(ex._of) == len(ex._names) == 1 and ex.confidence(t, "p.0|sing") == 0.0
