"""The structure installation (installations/structure.toml): musical structure that grows
out of behaviour. Its three numbers (issue 20), each beside a control that fails them:

* ≥ 95 % of the colony's inter-onset intervals lie on the heard ratio lattice (the best
  reading's ratios × its pulse); a creature playing random intervals would not;
* the phrase-level transition entropy of what the colony plays (each creature's next phrase
  given its last) falls by ≥ 30 % from before the visitor to after ten minutes of a visitor
  keeping to one order of the style's phrases; with a visitor playing them in random order
  it does not;
* the scripted complexity arc changes note density over the run: the first fifth has ≥ 2×
  the notes of the last; with the arc held flat it does not.

The colony plays alone for a minute; then the visitor, a seeded performer, plays the
installation's own four phrases (read from the config) for ten minutes at 100 bpm with a
little jitter, each beginning two or four beats after the last note of the phrase before.
Each claim is measured for three seeds (the colony's and the performer's).

And its expectations (issue 20: "surprise fires within 4 notes of a rhythm change and on
≤ 5 % of notes of a steady rhythm"): ada hears each of the visitor's notes as a tuple whose
Du expects it on the division of the heard metre, and a surprise startles her into a cry.
When the visitor starts to swing (the same phrases, each pair of eighths on a beat played
long-short, 2:1, and three-beat gaps: a triple metre), she is surprised within four notes
of the first swung one and cries out; on the steady rhythm before, and over the whole of the
steady run (the control: the same performer, who never swings), she is surprised on at
most 5 % of the notes and cries out rarely. The colony's rests, a bar of the best reading,
go from four beats to three once the triple reading wins; cy, who keeps her run of eighths in
steps of the heard division, plays them even before the swing and long-short 2:1 once the
triple reading has heard it (the steady run, over the same minutes: even)."""

from __future__ import annotations

import math
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

import installations
from creatures.events import read_events
from creatures.runtime.offline import run_offline
from creatures.runtime.pulse import CHORD_GAP, LONGEST_INTERVAL
from creatures.runtime.schema import load_installation
from creatures.temporal.onsets import inter_onset_intervals
from creatures.temporal.readings import METRES
from midi.files import write_notes
from midi.notes import NoteEvent

ALONE = 60.0
"""Seconds the colony plays before the visitor arrives (its phrase order knows no style yet)."""
SECONDS = ALONE + 600.0
BEAT = 0.6
"""The visitor's beat: 100 bpm, not the 120 the colony assumes before it hears anything."""
STYLE = {"a": "b", "b": "c", "c": "d", "d": "a"}
"""The order the consistent visitor keeps to, 85 % of the time (else another phrase)."""


def phrases(inst) -> dict[str, tuple[list[int], list[float]]]:
    """The style: each phrase tuple's pitches and beats, as the config writes them."""
    bo = next(spec for spec in inst.specs if spec.name == "bo")
    return {name: (tp.action.params()["pitches"], tp.action.params()["beats"])
            for name, tp in bo.tuples.items() if name in STYLE}


def swung(beats: list[float]) -> list[float]:
    """The phrase's rhythm in a triple metre: each pair of eighths that starts on a beat played
    long-short (2/3 + 1/3 of a beat)."""
    out: list[float] = []
    for beat in beats:
        if beat == 0.5 and out and out[-1] == 0.5 and sum(out[:-1]) % 1 == 0:
            out[-1:] = [2 / 3, 1 / 3]
        else:
            out.append(beat)
    return out


def performance(inst, *, consistent: bool, seed: int, seconds: float = SECONDS,
                swing_from: float = math.inf) -> list[NoteEvent]:
    """The visitor's notes. Phrases that begin at ``swing_from`` or later are swung, and the
    next begins two or three beats after their last note began (a triple metre); until then
    the same random draws make the same notes, so a run that swings and one that does not
    hear the same visitor up to the change."""
    rng = np.random.default_rng(seed)
    style = phrases(inst)
    names = sorted(style)
    t, current, notes = ALONE, "a", []
    while t < seconds:
        pitches, beats = style[current]
        swing = t >= swing_from
        if swing:
            beats = swung(beats)
        for pitch, beat in zip(pitches, beats):
            length = beat * BEAT * (1.0 + rng.normal(0.0, 0.02))
            notes.append(NoteEvent(round(t, 4), pitch, int(rng.integers(70, 100)), 0, round(0.9 * length, 4)))
            t += length
        # Rest so the next phrase begins two or four beats after the last note began (on the
        # half bar: the style's phrases are four beats long); two or three when swinging.
        gaps = (2.0, 3.0) if swing else (2.0, 4.0)
        t += BEAT * (float(rng.choice([g for g in gaps if g > beats[-1]])) - beats[-1])
        others = [n for n in names if n != STYLE[current]]
        if consistent:
            current = STYLE[current] if rng.random() < 0.85 else str(rng.choice(others))
        else:
            current = str(rng.choice(names))
    return notes


SEEDS = (1, 2, 3)


def run(tmp_path: Path, name: str, *, seed: int, consistent: bool = True, flat_arc: bool = False,
        seconds: float = SECONDS, swing_from: float = math.inf) -> tuple[list[dict], list[NoteEvent]]:
    """(the run's events, the visitor's notes): the installation as shipped but for its seed."""
    inst = load_installation(installations.path("structure"))
    inst.settings.seed = seed
    inst.settings.output.report = False
    inst.settings.output.wav = False
    if flat_arc:
        for spec in inst.specs:
            spec.drives["complexity"].arc = [(0.0, 0.05)]
            spec.drives["complexity"].arc_repeat = None
    midi = tmp_path / f"{name}.mid"
    notes = performance(inst, consistent=consistent, seed=seed, seconds=seconds, swing_from=swing_from)
    write_notes(midi, notes)
    run_offline(inst, tmp_path / name, midi=midi, duration=seconds)
    return read_events(tmp_path / name / "events.jsonl"), notes


@pytest.fixture(scope="module", params=SEEDS, ids=[f"seed {s}" for s in SEEDS])
def steady(request, tmp_path_factory) -> tuple[int, list[dict], list[NoteEvent]]:
    """(seed, events, the visitor's notes) of a run with a visitor keeping to the style."""
    return request.param, *run(tmp_path_factory.mktemp("structure"), "consistent", seed=request.param)


@pytest.fixture
def consistent(steady) -> list[dict]:
    return steady[1]


def on_lattice(intervals: np.ndarray, metre: str, pulse: float, tolerance: float = 0.15) -> np.ndarray:
    """Whether each interval is a whole number of the reading's finest level (its smallest
    ratio × its pulse: a sixteenth of a duple beat, a triplet eighth of a triple one), within
    ``tolerance`` of that level: the heard ratio lattice, and every sum of its durations."""
    step = min(METRES[metre]) * pulse
    k = np.round(intervals / float(step))
    return (k >= 1) & (np.abs(intervals - k * float(step)) <= tolerance * float(step))


def colony_intervals(events: list[dict], since: float) -> np.ndarray:
    onsets = [e["time"] for e in events if e["kind"] == "note" and e["time"] >= since]
    intervals = inter_onset_intervals(onsets, min_gap=CHORD_GAP)
    return intervals[intervals <= LONGEST_INTERVAL]  # a longer gap is a pause, as the colony hears it


def test_the_colony_plays_on_the_heard_ratio_lattice(consistent):
    readings = [e for e in consistent if e["kind"] == "reading"]
    assert readings and readings[-1]["metre"] == "duple"  # the visitor's eighths, quarters and halves
    pulse = readings[-1]["pulse"]
    assert pulse == pytest.approx(BEAT, rel=0.05)
    assert readings[0]["t"] < ALONE + 10.0  # trusted within seconds of the visitor's arrival
    intervals = colony_intervals(consistent, since=readings[0]["t"])
    assert len(intervals) > 300
    share = on_lattice(intervals, "duple", pulse).mean()
    assert share >= 0.95, share
    # The check bites: intervals as random as the colony's own (same count and range) are not.
    random = np.random.default_rng(0).uniform(intervals.min(), intervals.max(), intervals.size)
    assert on_lattice(random, "duple", pulse).mean() < 0.5


def transitions(events: list[dict]) -> list[tuple[str, str]]:
    """(a creature's phrase before, the phrase it played next), in the order played: each
    creature's own succession, as the shared model records it."""
    out, last = [], {}
    for e in events:
        if e["kind"] == "selection" and e["tuple"] in STYLE:
            creature = e["creature"]
            if creature in last:
                out.append((last[creature], e["tuple"]))
            last[creature] = e["tuple"]
    return out


def conditional_entropy(pairs: list[tuple[str, str]]) -> float:
    """H(next | before) in bits, plug-in."""
    joint, before = Counter(pairs), Counter(a for a, _ in pairs)
    n = len(pairs)
    return -sum(c / n * math.log2(c / before[a]) for (a, _), c in joint.items())


WINDOW = 30
"""Transitions compared at each end: the same count, so the estimate's bias is the same."""


def entropy_fall(events: list[dict]) -> tuple[float, float]:
    pairs = transitions(events)
    assert len(pairs) >= 3 * WINDOW
    return conditional_entropy(pairs[:WINDOW]), conditional_entropy(pairs[-WINDOW:])


def test_phrase_transition_entropy_falls_with_a_consistent_style(steady, consistent, tmp_path):
    first, last = entropy_fall(consistent)
    assert last <= 0.7 * first, (first, last)
    # The fall is learnt from the visitor, not the colony reinforcing its own choices: a
    # visitor playing the same phrases in random order leaves it high.
    first, last = entropy_fall(run(tmp_path, "random order", seed=steady[0], consistent=False)[0])
    assert last > 0.7 * first, (first, last)


def notes_in_fifths(events: list[dict]) -> tuple[int, int]:
    times = np.array([e["time"] for e in events if e["kind"] == "note"])
    fifth = SECONDS / 5
    return int((times < fifth).sum()), int((times >= SECONDS - fifth).sum())


def test_the_scripted_arc_changes_note_density(steady, consistent, tmp_path):
    """The arc starts at the top of its cycle and reaches the bottom at ten minutes."""
    first, last = notes_in_fifths(consistent)
    assert last > 0 and first >= 2 * last, (first, last)
    first, last = notes_in_fifths(run(tmp_path, "flat", seed=steady[0], flat_arc=True)[0])
    assert max(first, last) < 2 * min(first, last), (first, last)  # the arc, not the input, makes the change


SWING = 300.0
"""When the visitor starts to swing, in the run that changes metre (four minutes in)."""


def surprised_on(events: list[dict], onsets: list[float]) -> np.ndarray:
    """Per visitor note, whether ada's expectation of it was violated with a salient surprise
    (> 0.1, as confident as that: the 'surprise' events of her 'keep time' tuple) before the
    next note."""
    times = np.array([e["t"] for e in events if e["kind"] == "surprise" and e.get("tuple") == "keep time"
                      and e["surprise"] > 0.1])
    bounds = np.append(onsets, np.inf)
    return np.array([bool(((times >= a) & (times < b)).any()) for a, b in zip(bounds[:-1], bounds[1:])])


def first_swung(notes: list[NoteEvent]) -> int:
    """The first note whose interval from the note before is off the duple lattice (a swung
    eighth): where the rhythm changes."""
    onsets = np.array([n.time for n in notes])
    eighths = np.diff(onsets) / (BEAT / 2)
    return int(np.flatnonzero(np.abs(eighths - np.round(eighths)) > 0.25)[0]) + 1


CRY = 10.0
"""Seconds after the first swung note in which ada's cry is listened for."""


def cry_pitches() -> set[int]:
    """The pitches of ada's startle phrase (the style's phrases use none of them)."""
    inst = load_installation(installations.path("structure"))
    ada = next(spec for spec in inst.specs if spec.name == "ada")
    pitches = set(ada.tuples["startle"].action.params()["pitches"])
    assert not pitches & {p for phrase, _ in phrases(inst).values() for p in phrase}
    return pitches


def cries(events: list[dict], pitches: set[int]) -> np.ndarray:
    """When ada's startle phrase sounds: the times of her notes of its pitches."""
    return np.array([e["time"] for e in events
                     if e["kind"] == "note" and e["creature"] == "ada" and e["pitch"] in pitches])


def rest_beats(events: list[dict], since: float, until: float) -> float:
    """The colony's median rest between ``since`` and ``until``, in the visitor's beats."""
    return float(np.median([e["duration"] for e in events if e["kind"] == "stop" and e["tuple"] == "rest"
                            and since <= e["t"] < until])) / BEAT


SWUNG = SWING + 120.0
"""The end of the run that changes metre: two minutes of swing."""


@pytest.fixture(scope="module")
def swinging(steady, tmp_path_factory) -> tuple[list[dict], list[NoteEvent]]:
    """(events, the visitor's notes) of the run whose visitor starts to swing at SWING: the
    steady run's visitor until then."""
    return run(tmp_path_factory.mktemp("swing"), "swing", seed=steady[0], seconds=SWUNG, swing_from=SWING)


def test_a_change_of_metre_surprises_ada_within_four_notes_and_startles_her(steady, swinging):
    _, calm, calm_notes = steady
    events, notes = swinging
    onsets = np.array([n.time for n in notes])
    change = first_swung(notes)
    trusted = next(e["t"] for e in events if e["kind"] == "reading") + 10.0
    fired = surprised_on(events, list(onsets))
    before = (onsets >= trusted) & (onsets < onsets[change])
    assert fired[before].mean() <= 0.05, fired[before].mean()
    assert fired[change:change + 4].any(), fired[change - 4:change + 8]
    # The same visitor who never swings (the steady run: the same notes until the swing):
    # at most 5 % of the notes over ten minutes surprise her, and none at the change.
    calm_onsets = np.array([n.time for n in calm_notes])
    same = int((onsets < SWING).sum())
    assert (calm_onsets[:same] == onsets[:same]).all()
    calm_fired = surprised_on(calm, list(calm_onsets))
    assert calm_fired[calm_onsets >= trusted].mean() <= 0.05
    at_change = int(np.searchsorted(calm_onsets, onsets[change]))
    assert not calm_fired[at_change:at_change + 4].any()
    # Heard: a whole cry within CRY seconds of the first swung note, none then in the steady
    # run, and on the steady rhythm at most one a minute.
    pitches = cry_pitches()
    cried, calm_cried = cries(events, pitches), cries(calm, pitches)
    window = [onsets[change], onsets[change] + CRY]
    assert ((cried >= window[0]) & (cried < window[1])).sum() >= len(pitches)
    assert not ((calm_cried >= window[0]) & (calm_cried < window[1])).any()
    minutes = (onsets[change] - trusted) / 60.0
    assert ((cried >= trusted) & (cried < onsets[change])).sum() / len(pitches) <= minutes
    assert (calm_cried >= trusted).sum() / len(pitches) <= (SECONDS - trusted) / 60.0
    # The colony hears the new metre: once the triple reading is the best its rests, a bar of
    # it, are three beats long, not four (as they stay in the steady run).
    triple = next(e["t"] for e in events if e["kind"] == "reading" and e["t"] > SWING and e["metre"] == "triple")
    assert rest_beats(events, trusted, onsets[change]) == pytest.approx(4.0, abs=0.25)
    assert rest_beats(events, triple + 5.0, SWUNG) == pytest.approx(3.0, abs=0.25)
    assert rest_beats(calm, triple + 5.0, SWUNG) == pytest.approx(4.0, abs=0.25)


def division_run(events: list[dict], since: float, until: float) -> np.ndarray:
    """The inter-onset intervals of cy's run of eighths (the four notes of her phrase b that
    she keeps in steps of the heard division) in the phrases she starts between ``since``
    and ``until``."""
    inst = load_installation(installations.path("structure"))
    pitches = phrases(inst)["b"][0]
    notes = sorted((e["time"], e["pitch"]) for e in events if e["kind"] == "note" and e["creature"] == "cy")
    out = []
    for start in (e["t"] for e in events if e["kind"] == "selection" and e["creature"] == "cy"
                  and e["tuple"] == "b" and since <= e["t"] < until):
        phrase = [(t, p) for t, p in notes if t >= start][:len(pitches)]
        assert [p for _, p in phrase] == pitches  # the phrase, played out
        out.extend(np.diff([t for t, _ in phrase[:5]]))
    return np.array(out)


def unevenness(intervals: np.ndarray) -> float:
    """The 90th over the 10th percentile of ``intervals``: 1 for an even run, 2 for one whose
    notes are long and short, 2:1."""
    assert intervals.size >= 8
    return float(np.percentile(intervals, 90) / np.percentile(intervals, 10))


def test_cy_keeps_time_on_the_division_and_swings_when_the_visitor_does(steady, swinging):
    """cy's eighths are steps of the division of the best reading as the colony hears the beat
    filled: even while the visitor plays straight, long-short 2:1 once the visitor swings
    and the triple reading has heard it; in the steady run, over the same minutes, even."""
    _, calm, _ = steady
    events, _ = swinging
    trusted = next(e["t"] for e in events if e["kind"] == "reading") + 10.0
    triple = next(e["t"] for e in events if e["kind"] == "reading" and e["t"] > SWING and e["metre"] == "triple")
    before = division_run(events, trusted, SWING)
    assert unevenness(before) < 1.1 and np.median(before) == pytest.approx(BEAT / 2, rel=0.05)
    assert unevenness(division_run(events, triple + 5.0, SWUNG)) == pytest.approx(2.0, rel=0.1)
    assert unevenness(division_run(calm, triple + 5.0, SWUNG)) < 1.1
