"""sand:stone: rock creatures that sing only their precomposed phrases, more when present,
less when they hear music far away on the circle of fifths, and never longer than a breath.
The rock is an authored creature (installations/creatures/sandstone.toml); a run's keys are
its authored keys (``drives.breath.inputs.singing`` is the breath singing uses a second)."""

from __future__ import annotations

import itertools
import json
import math
import tempfile
from pathlib import Path

import numpy as np
import pytest

import installations
from creatures.clock import SimulatedClock
from creatures.config import ConfigError
from creatures.events import EventLog, read_events
from creatures.kinds import KINDS, load_all
from creatures.runtime.offline import run_offline
from creatures.persist import StateFileError
from creatures.runtime.schema import load_installation
from creatures.runtime.session import Session
from creatures.runtime.world import World
from midi.fifths import circular_distance, fifths_vector
from midi.files import write_notes
from midi.notes import NoteEvent
from midi.scheduler import NoteScheduler
from midi.sinks import MemorySink

TICK = 0.02
C, CS, D, DS, E, F, FS, G, GS, A, AS, B = range(60, 72)


# -- the circle-of-fifths metric -------------------------------------------------------------
@pytest.mark.parametrize("a, b, steps", [
    (C, G, 1), (C, F, 1), (C, D, 2), (C, AS, 2), (C, A, 3), (C, DS, 3), (C, E, 4), (C, GS, 4),
    (C, B, 5), (C, CS, 5), (C, FS, 6), (C, C + 12, 0), (C - 24, G + 12, 1), (E, AS, 6),
])
def test_fifths_distance_exact_values(a, b, steps):
    """A single note's direction on the circle: two notes' distance is their pitch classes'."""
    assert circular_distance(fifths_vector([a]), fifths_vector([b])) == pytest.approx(steps, abs=1e-9)
    assert circular_distance(fifths_vector([b]), fifths_vector([a])) == pytest.approx(steps, abs=1e-9)


def test_fifths_distance_is_a_metric_on_pitch_classes():
    d = np.array([[circular_distance(fifths_vector([a]), fifths_vector([b])) for b in range(12)] for a in range(12)])
    d = np.round(d, 9)
    assert (d == d.T).all() and (np.diag(d) == 0).all() and d.max() == 6
    assert all(d[a, c] <= d[a, b] + d[b, c] for a, b, c in itertools.product(range(12), repeat=3))
    # every pitch class has two neighbours a fifth away and one tritone opposite
    assert ((d == 1).sum(axis=1) == 2).all() and ((d == 6).sum(axis=1) == 1).all()


def test_passages_in_neighbouring_keys_are_one_fifth_apart():
    major = np.array([0, 2, 4, 5, 7, 9, 11])
    c_major = fifths_vector(60 + major)
    assert circular_distance(c_major, fifths_vector(67 + major)) == pytest.approx(1.0, abs=1e-9)
    assert circular_distance(c_major, fifths_vector(65 + major)) == pytest.approx(1.0, abs=1e-9)
    assert circular_distance(c_major, fifths_vector(66 + major)) == pytest.approx(6.0, abs=1e-9)
    assert circular_distance(c_major, np.zeros(2)) == 6.0  # nothing heard is never "correlated"


# -- the chemistry with inputs re-set every soft-state step ------------------------------------
def test_changing_inputs_reuse_one_propagator_and_stay_exact(rng):
    """Presence × boredom re-sets the inputs every step; the step's (Φ, Ψ) is reused and
    each step still equals the exponential of the augmented system [[M, b], [0, 0]]."""
    from scipy.linalg import expm

    from creatures.behaviour.motivation import Motivation

    m = Motivation({"desire": 0.0, "boredom": 0.0, "breath": 1.0, "pulse": 1.0},
                   decay={"desire": 0.03, "boredom": 0.03, "breath": 0.1, "pulse": 0.5},
                   coupling={("pulse", "desire"): 0.1, ("pulse", "boredom"): -0.1}, floor=None)
    big = np.zeros((5, 5))
    big[:4, :4] = m.coupling - np.diag(m.decay)
    t = 0.0
    for step in range(50):
        m.set_input(t, "desire", float(rng.uniform(-0.5, 0.5)))
        m.set_input(t, "boredom", float(rng.uniform(0.0, 0.1)))
        big[:4, 4] = m.growth + m.decay * m.equilibrium + m.inputs
        expected = (expm(big * 0.1) @ np.append(m.levels, 1.0))[:4]
        t = 0.1 * (step + 1)  # clock sums: the steps differ in the last bits
        m.advance(t)
        np.testing.assert_allclose(m.levels, expected, rtol=1e-12, atol=1e-14)
    assert len(m._propagators) == 1


# -- running creatures -----------------------------------------------------------------------
def _toml(value) -> str:
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    return repr(value)


def _run(tmp_path: Path, creatures: list[dict], *, duration: float, heard: list[NoteEvent] | None = None,
         seed: int = 3) -> list[dict]:
    """Run sandstone creatures offline (no audio) and return the events."""
    tmp_path.mkdir(parents=True, exist_ok=True)
    lines = ['title = "t"', f"seed = {seed}", f"tick = {TICK}", "[output]", "wav = false", "report = false"]
    if heard is not None:
        write_notes(tmp_path / "in.mid", heard)
        lines += ["[input]", 'midi = "in.mid"']
    else:
        lines += ["[input]", 'generate = "none"']
    for i, keys in enumerate(creatures):
        lines += ["[[creature]]", f'name = "rock{i}"', 'kind = "sandstone"', f"channel = {i}"]
        lines += [f"{k} = {_toml(v)}" for k, v in keys.items()]
    config = tmp_path / "sandstone.toml"
    config.write_text("\n".join(lines) + "\n")
    run_offline(load_installation(config), tmp_path / "out", duration=duration)
    return read_events(tmp_path / "out" / "events.jsonl")


def _notes(events: list[dict], creature: str = "rock0") -> list[dict]:
    return [e for e in events if e["kind"] == "note" and e["creature"] == creature]


def _activations(events: list[dict], tuple_: str, creature: str = "rock0") -> list[tuple[float, float]]:
    """(start, stop) of every activation of ``tuple_`` (a last one still running ends at the end)."""
    spans, start = [], None
    for e in events:
        if e.get("creature") != creature or e.get("tuple") != tuple_:
            continue
        if e["kind"] == "selection" and not e.get("kept"):
            start = e["t"]
        elif e["kind"] == "stop":
            spans.append((start, e["t"]))
            start = None
    if start is not None:
        spans.append((start, events[-1]["t"]))
    return spans


PRESENCE, PHRASES = "percepts.presence.points", "tuples.sing.action.phrases"
EAGERNESS, SATIATION = 'drives.desire.inputs."eager presence"', "drives.desire.inputs.singing"
HABITUATION, BREATH_USE = "drives.boredom.inputs.presence", "drives.breath.inputs.singing"


def _phrases(spec) -> list:
    return spec.tuples["sing"].action.params()["phrases"]


def _rocks(specs) -> list:
    """The singing rocks of the shipped installation, not its statue (which sings nothing)."""
    return [spec for spec in specs if "sing" in spec.tuples]


def _spec(**keys):
    """The shipped rock creature, named a, with ``keys`` merged over it."""
    lines = ['title = "x"', "[[creature]]", 'name = "a"', 'kind = "sandstone"']
    with tempfile.TemporaryDirectory() as folder:
        config = Path(folder) / "rock.toml"
        config.write_text("\n".join(lines + [f"{k} = {v}" for k, v in keys.items()]) + "\n")
        return load_installation(config).specs[0]


def test_every_note_comes_from_the_phrases_in_order(tmp_path):
    """All six rocks of the shipped installation: each rock's whole note sequence is its
    phrases read in order (cycling), so it never skips, reorders or invents a note."""
    inst = load_installation(installations.path("sandstone"))
    inst.settings.output.wav = inst.settings.output.report = False
    run_offline(inst, tmp_path, duration=60.0)
    events = read_events(tmp_path / "events.jsonl")
    singers = 0
    assert not _notes(events, "ozymandias")  # the statue
    for spec in _rocks(inst.specs):
        notes = _notes(events, spec.name)
        song = itertools.cycle([pitch for phrase in _phrases(spec) for pitch, _ in phrase])
        assert [n["pitch"] for n in notes] == [next(song) for _ in notes], spec.name
        onsets = [n["time"] for n in notes]
        assert onsets == sorted(onsets) and all(n["duration"] > 0 for n in notes)
        singers += len(notes) > 5
    assert singers >= 4


def test_presence_makes_a_creature_sing_more(tmp_path):
    counts = []
    for level in (0.2, 0.5, 0.9):
        events = _run(tmp_path / str(level), [{PRESENCE: [[0.0, level]]}], duration=40.0)
        counts.append(len(_notes(events)))
    assert counts[0] < counts[1] < counts[2], counts
    assert counts[2] >= 2 * counts[0] > 0


def _arpeggio_loop(root: int, duration: float) -> list[NoteEvent]:
    shape = [0, 4, 7, 12, 7, 4]  # a major arpeggio, six eighths at 120 BPM
    return [NoteEvent(round(0.25 * i, 6), root + shape[i % 6], 90, 0, 0.22) for i in range(int(duration / 0.25))]


def test_uncorrelated_music_suppresses_singing(tmp_path):
    """The same creature (C major) under the same presence, hearing the same rhythm in G
    (a fifth away: correlated) or in F# (a tritone away: uncorrelated)."""
    spec = _spec()
    key = fifths_vector(np.array([p for phrase in _phrases(spec) for p, _ in phrase]))
    within = spec.percepts["discord"].params()["within"]
    near, far = _arpeggio_loop(G, 40.0), _arpeggio_loop(FS, 40.0)
    assert circular_distance(fifths_vector(np.array([n.pitch for n in near])), key) < within
    assert circular_distance(fifths_vector(np.array([n.pitch for n in far])), key) > 5.0
    rock = [{PRESENCE: [[0.0, 0.8]]}]
    with_near = _run(tmp_path / "near", rock, duration=40.0, heard=near)
    with_far = _run(tmp_path / "far", rock, duration=40.0, heard=far)
    assert len(_notes(with_far)) <= 0.5 * len(_notes(with_near)), (len(_notes(with_far)), len(_notes(with_near)))
    discord = lambda events: max(e["levels"]["discord"] for e in events if e["kind"] == "percepts")  # noqa: E731
    assert discord(with_near) == 0.0 < discord(with_far)
    assert any(e["kind"] == "selection" and e["tuple"] == "listen" for e in with_far)


def test_a_rock_left_away_longs_to_sing_and_calls_out_over_discord(tmp_path):
    """A rock away from the centre (presence 0) hearing music a tritone from its key all the
    while: its desire drains under the discord, and without longing it never sings; with it,
    silence breeds longing and the rock calls out a few notes once about every two minutes
    (longing grows by 1 in 100 s, reaches desire from 1.0 and outweighs any discord by 1.5)."""
    far = _arpeggio_loop(FS, 300.0)
    away = _run(tmp_path / "away", [{PRESENCE: [[0.0, 0.0]]}], duration=300.0, heard=far)
    onsets = np.array([n["time"] for n in _notes(away)])
    calls = np.split(onsets, np.flatnonzero(np.diff(onsets) > 10.0) + 1)
    assert len(calls) == 2 and all(3 <= len(call) <= 12 for call in calls), onsets
    assert 100.0 < calls[0][0] < 150.0 and 100.0 < calls[1][0] - calls[0][-1] < 150.0
    unmoved = _run(tmp_path / "unmoved", [{PRESENCE: [[0.0, 0.0]], "drives.desire.inputs.lonely": 0.0}],
                   duration=300.0, heard=far)
    assert _notes(unmoved) == []


def test_breath_runs_out_and_forces_pauses(tmp_path):
    use, recovery = 0.3, 0.1
    longest = math.log(use / (use - recovery)) / recovery  # full breath to none, singing throughout
    eager = {PRESENCE: [[0.0, 1.0]], EAGERNESS: 1.0, SATIATION: 0.0, HABITUATION: 0.0,
             "drives.breath.decay": recovery, PHRASES: [[[60 + i % 5, 0.5] for i in range(40)]]}
    events = _run(tmp_path / "short", [{**eager, BREATH_USE: -use}], duration=40.0)
    sings, notes = _activations(events, "sing"), _notes(events)
    assert len(notes) > 40 and len(sings) >= 3
    for n in notes:  # every note starts inside a singing activation
        assert any(a - 1e-9 <= n["time"] <= b + 1e-9 for a, b in sings), n
    stretches = {}
    for start, stop in sings:
        inside = [n for n in notes if start - 1e-9 <= n["time"] <= stop + 1e-9]
        if inside:
            stretches[stop] = max(n["time"] + n["duration"] for n in inside) - min(n["time"] for n in inside)
    assert max(stretches.values()) <= longest
    breathless = [e["t"] for e in events if e["kind"] == "breathless"]
    assert len(breathless) >= 2
    # it ran out *during long singing*: the stretches that ended breathless used most of a breath
    ran_out = [stop for stop in stretches if any(stop - 2 * TICK <= t <= stop for t in breathless)]
    assert len(ran_out) >= 2 and all(stretches[stop] >= 0.6 * longest for stop in ran_out)
    for t in breathless[:-1]:  # each time it ran out: it stopped singing and paused to breathe
        following = [e for e in events if e["kind"] == "selection" and e["t"] > t]
        assert following[0]["tuple"] == "pause"
        pauses = [(a, b) for a, b in _activations(events, "pause") if a > t]
        assert pauses[0][1] - pauses[0][0] >= 0.5
    # with breath to spare, the same creature sings one long stretch instead
    deep = _run(tmp_path / "deep", [{**eager, BREATH_USE: -0.01}], duration=40.0)
    assert max(b - a for a, b in _activations(deep, "sing")) > 3 * longest
    assert not any(e["kind"] == "breathless" for e in deep)


def test_a_note_longer_than_a_whole_breath_is_sung_while_the_breath_lasts(tmp_path):
    """A note no full breath can hold (8 beats at 60 BPM, breath for 3.3 s) was never begun:
    the rock, breathless before it, paused, recovered and came back to it again and again.
    It sang its first note and then nothing for the rest of the run, ending a turn ten times a
    second (in five minutes of the shipped rocks at tempo 10, within its bounds: 2 notes,
    6,165 breathless turns). Begun on a fresh breath, such a note is now sung for as long as
    the breath lasts, and the song goes on after the pause that follows."""
    song = [[[60, 1.0], [62, 8.0], [64, 1.0], [65, 1.0]]]
    events = _run(tmp_path, [{PRESENCE: [[0.0, 1.0]], PHRASES: song, "tuples.sing.action.tempo": 60.0}],
                  duration=60.0)
    notes = _notes(events)
    assert [n["pitch"] for n in notes[:8]] == [60, 62, 64, 65] * 2
    breath = 1.0 / 0.3  # a full breath at the rate singing draws it
    for long, after in zip(notes, notes[1:]):
        if long["pitch"] == 62:  # sung on a breath, which it spends: the next note waits for the next breath
            assert long["duration"] <= breath and after["time"] >= long["time"] + long["duration"]
    assert len([e for e in events if e["kind"] == "breathless"]) <= len(notes)


def test_the_shortest_notes_a_song_may_have_are_sung_at_a_bounded_rate(tmp_path):
    """Sixteenths of a beat at the fastest tempo, no rest between segments: every note is
    sung, at most 16 × 400 / 60 × 2 (internal time at twice the tempo) a second."""
    events = _run(tmp_path, [{PRESENCE: [[0.0, 1.0]], PHRASES: [[[72, 0.0625]]], "tuples.sing.action.tempo": 400.0,
                              "tuples.sing.action.phrase_rest": 0.0}], duration=5.0)
    onsets = np.array([n["time"] for n in _notes(events)])
    assert len(onsets) > 100 and np.diff(onsets).min() >= 0.0625 * 60 / 400 / 2 - 1e-6


def test_boredom_softens_and_detaches_the_singing(tmp_path):
    events = _run(tmp_path, [{PRESENCE: [[0.0, 1.0]], HABITUATION: 0.02}], duration=60.0)
    notes = _notes(events)
    early = [n for n in notes if n["time"] < 15.0]
    late = [n for n in notes if n["time"] > 45.0]
    assert early and late
    assert np.mean([n["velocity"] for n in late]) < np.mean([n["velocity"] for n in early]) - 10
    boredom = [e["drives"]["boredom"] for e in events if e["kind"] == "motivation"]
    assert boredom[-1] > boredom[len(boredom) // 4] > boredom[0]


def test_pulse_governs_internal_time(tmp_path):
    """With ``hurry`` (the pulse drive's coupling to desire and boredom) 0 the pulse rests at
    1 and every beat lasts exactly 60/tempo seconds; with ``hurry`` the desire to sing presses
    internal time on."""
    steady = {PRESENCE: [[0.0, 1.0]], EAGERNESS: 1.0, HABITUATION: 0.0, "tuples.sing.action.phrase_rest": 0.0,
              "tuples.sing.action.tempo": 96.0, PHRASES: [[[60, 0.5], [64, 0.5], [67, 0.5], [72, 0.5]]]}

    def hurry(h: float) -> dict:
        return {"drives.pulse.coupling.desire": h, "drives.pulse.coupling.boredom": -h}
    beat = 60.0 / 96.0

    def gaps(events):
        onsets = [n["time"] for n in _notes(events)]
        return np.diff(onsets)[np.diff(onsets) < 2 * 0.5 * beat]  # within a stretch of singing

    calm = gaps(_run(tmp_path / "calm", [{**steady, **hurry(0.0)}], duration=30.0))
    eager = gaps(_run(tmp_path / "eager", [{**steady, **hurry(0.4)}], duration=30.0))
    assert len(calm) > 20 and np.allclose(calm, 0.5 * beat, atol=2e-6)
    assert len(eager) > 20 and np.median(eager) < 0.85 * 0.5 * beat


def test_a_rock_sensor_reading_sets_presence_and_is_not_music(tmp_path):
    rock = {PRESENCE: [[0.0, 0.0]], "percepts.presence.rock": 40}
    reading = [NoteEvent(1.0, 40, 127, 15, 0.1), NoteEvent(1.5, 41, 127, 15, 0.1)]  # ours, another rock's
    sensed = _run(tmp_path / "sensed", [rock], duration=20.0, heard=reading)
    silent = _run(tmp_path / "silent", [rock], duration=20.0, heard=[NoteEvent(1.0, 40, 127, 14, 0.1)])
    percepts = [e for e in sensed if e["kind"] == "percepts" and e["t"] > 1.5]
    assert all(e["levels"]["presence"] == 1.0 and e["levels"]["heard amount"] == 0.0 for e in percepts)
    assert len(_notes(sensed)) > 5
    assert _notes(silent) == []  # on a music channel it is a note to hear, not a reading


# -- state and config ------------------------------------------------------------------------
def _world() -> World:
    clock = SimulatedClock()
    return World(clock, EventLog(None), NoteScheduler(MemorySink(), clock))


def test_state_round_trips_through_json():
    spec = _spec()
    load_all()
    world = _world()
    creature = KINDS["authored"](spec, world, np.random.default_rng(0))
    world.add(creature)
    for step in range(1, 500):
        world.clock.advance_to(step * TICK)
        creature.tick(world.clock.now())
        if step % 50 == 0:
            creature.hear(NoteEvent(world.clock.now(), 66, 90, 3, 0.4), "other")
    state = json.loads(json.dumps(creature.state()))
    assert state["parts"]["tuples"]["sing"] != {"phrase": 0, "note": 0}  # it has sung; the position is saved
    assert state["parts"]["percepts"]["discord"]["weight"] > 0  # and it heard the other rock
    fresh = KINDS["authored"](spec, _world(), np.random.default_rng(1))
    fresh.restore(state)
    again = fresh.state()
    # Levels and positions carry over exactly; times restart with the new run's clock.
    assert again["motivation"].pop("time") == 0.0
    state["motivation"].pop("time")
    assert again == state
    song = {"phrase": len(_phrases(spec)), "note": 0}
    with pytest.raises(ValueError, match="song position"):
        fresh.restore({**state, "parts": {**state["parts"], "tuples": {"sing": song}}})


def test_a_song_resumes_after_a_clock_gap_without_singing_the_gap():
    """A rock still singing when the gallery closed sings on from where it stopped when it
    opens, not every onset of the night at once (a rehearsed week once sent 97 050 notes on
    one morning's first tick)."""
    spec = _spec(**{PRESENCE: "[[0.0, 1.0]]", EAGERNESS: 1.0, SATIATION: 0.0, HABITUATION: 0.0, BREATH_USE: -0.001})
    load_all()
    world = _world()
    creature = KINDS["authored"](spec, world, np.random.default_rng(0))
    world.add(creature)
    onsets: list[float] = []
    world.log.taps.append(lambda record: onsets.append(record["time"]) if record["kind"] == "note" else None)
    t = 0.0
    while len(onsets) < 3:
        t += TICK
        world.clock.advance_to(t)
        creature.tick(t)
    sung, morning = len(onsets), t + 16 * 3600.0
    world.clock.advance_to(morning)
    creature.tick(morning)
    assert creature.tuples["sing"].active
    assert 1 <= len(onsets[sung:]) <= 2 and min(onsets[sung:]) >= morning


@pytest.mark.parametrize("key, value, phrase", [
    ("percepts.presence.points", "[[0.0, 0.5], [10.0, 1.0], [5.0, 0.0]]", "strictly increase"),
    ("percepts.presence.points", "[[0.0, 1.5]]", "0..1"),
    ("tuples.sing.action.phrases", "[[[60, 1.0], [200, 0.5]]]", "phrase 0 note 1"),
    ("tuples.sing.action.phrases", "[[]]", "phrase 0 is empty"),
    # a millionth of a beat was taken, and a rock sang 133,000 notes a tick: 3 s did not end in 6 min
    ("tuples.sing.action.phrases", "[[[72, 0.000001]]]", "phrase 0 note 0: need pitch 0..127 and 1/16 <= beats"),
])
def test_bad_scripts_and_phrases_are_named(tmp_path, key, value, phrase):
    config = tmp_path / "bad.toml"
    config.write_text(f'title = "x"\n[[creature]]\nname = "a"\nkind = "sandstone"\n{key} = {value}\n')
    with pytest.raises(ConfigError) as error:
        load_installation(config)
    assert f"bad.toml:5: creature.0.{key}" in str(error.value) and phrase in str(error.value)


# -- a state folder saved by the class-based sandstone (tests/data/retired/sandstone, a real one)
RETIRED = Path(__file__).parent / "data" / "retired" / "sandstone"


def _session(config: Path | None = None) -> Session:
    return Session(load_installation(config or installations.path("sandstone")), SimulatedClock(), EventLog(),
                   MemorySink())


def test_a_state_saved_by_the_class_based_sandstone_loads_into_the_authored_one(tmp_path):
    session = _session()
    rocks = [c for c in session.creatures if c.spec in _rocks(session.inst.specs)]
    assert sorted(session.load_state(RETIRED)) == sorted(c.name for c in rocks)  # the statue is new
    for creature in rocks:
        saved = json.loads((RETIRED / f"{creature.name}.json").read_text())
        assert saved["kind"] == "sandstone"
        old, now = saved["state"], creature.state()
        assert now["parts"]["tuples"]["sing"] == old["song"]
        assert now["parts"]["percepts"]["discord"] == {k: old["heard"][k] for k in ("vector", "weight")}
        assert now["parts"]["percepts"]["presence"] == old["sensed"]
        levels = now["motivation"]["levels"]
        assert levels.pop("longing") == 0.0  # the class had no longing: it starts as authored
        assert levels == old["motivation"]["levels"]
        assert now["values"]["main"] == old["values"]
    session.save_state(tmp_path)
    assert json.loads((tmp_path / "king.json").read_text())["kind"] == "authored"


def test_a_class_sandstone_state_is_refused_where_nothing_can_take_it(tmp_path):
    config = tmp_path / "c.toml"
    config.write_text('title = "t"\n[[creature]]\nname = "king"\nkind = "exchange"\n')
    with pytest.raises(StateFileError, match=r"king.json: cannot take .* no 'sing_phrases'.*move king.json out"):
        _session(config).load_state(RETIRED)
    state = tmp_path / "state"
    state.mkdir()
    saved = json.loads((RETIRED / "king.json").read_text())
    del saved["state"]["song"]
    (state / "king.json").write_text(json.dumps(saved))
    with pytest.raises(StateFileError, match="king.json: cannot take .* missing 'song'"):
        _session().load_state(state)
    saved["state"]["song"] = {"phrase": 9, "note": 0}
    (state / "king.json").write_text(json.dumps(saved))
    with pytest.raises(StateFileError, match="king.json: malformed authored state .*song position 9/0"):
        _session().load_state(state)
