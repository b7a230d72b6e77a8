"""The colony's heard pulse: MIDI notes and pitch-tracked audio teach one low-integer-ratio
model through the shared onset helper, and a creature's rests sample it."""

from __future__ import annotations

import numpy as np
import pytest

from creatures.clock import SimulatedClock
from creatures.events import EventLog, read_events
from creatures.runtime.inputs import render_notes
from creatures.runtime.pulse import HeardPulse
from creatures.runtime.schema import load_installation
from creatures.runtime.session import Session
from midi.notes import NoteEvent
from midi.sinks import MemorySink

BEAT = 0.6  # 100 BPM
CONFIG = """
title = "pulse"
seed = 2
tick = 0.04
[audio]
sample_rate = 22050
[output]
report = false
[[creature]]
name = "ada"
kind = "exchange"
tuples.rest.until.pulse = 2  # rests in the time of what it hears
"""


def _rhythm(n: int, rng: np.random.Generator) -> list[NoteEvent]:
    """Quarters, eighths, halves and dotted quarters at 100 BPM, ±3 % jitter, on a scale."""
    beats = rng.choice([1.0, 0.5, 2.0, 1.5], size=n, p=[0.4, 0.3, 0.15, 0.15])
    times = 1.0 + np.concatenate([[0.0], np.cumsum(beats[:-1] * BEAT * rng.uniform(0.97, 1.03, n - 1))])
    pitches = rng.choice([60, 62, 64, 65, 67, 69, 71, 72], size=n)
    return [NoteEvent(float(t), int(p), 90, 0, float(0.8 * b * BEAT)) for t, p, b in zip(times, pitches, beats)]


def _session(tmp_path, log: EventLog | None = None) -> Session:
    config = tmp_path / "pulse.toml"
    config.write_text(CONFIG)
    return Session(load_installation(config), SimulatedClock(), log or EventLog(), MemorySink())


def _run(session: Session, seconds: float, audio: np.ndarray | None = None) -> None:
    sr, tick = session.sample_rate, session.inst.settings.tick
    for step in range(1, int(round(seconds / tick)) + 1):
        t0, t = (step - 1) * tick, step * tick
        session.clock.advance_to(t)
        a, b = int(round(t0 * sr)), int(round(t * sr))
        session.step(t, b - a, None if audio is None else audio[a:b], audio=False)


def test_chords_count_once_and_pauses_are_not_durations():
    pulse = HeardPulse()
    for t in (0.0, 0.004, 0.6, 1.2, 1.205, 1.8, 9.0, 9.6):  # two chords, then a pause
        pulse.hear(t)
    pulse.settle()
    assert pulse.heard == 4  # 0.6, 0.6, 0.6 and 0.6 after the pause; the 7.2 s gap is no duration
    pulse.hear(9.3)  # recognised late: older than what was already learnt
    pulse.settle()
    assert pulse.heard == 4


def test_midi_notes_teach_the_colony_the_beat_and_rests_fall_on_its_lattice(tmp_path):
    session = _session(tmp_path)
    for note in _rhythm(120, np.random.default_rng(1)):
        session.world.inject(note)
    _run(session, 100.0)
    pulse = session.world.pulse
    assert pulse.ready and abs(pulse.model.pulse - BEAT) / BEAT < 0.02
    rest = next(tu for tu in session.creatures[0].group.tuples if tu.name == "rest").do_until.model
    lengths = np.array([rest.sample(np.random.default_rng(i)) for i in range(300)]) / rest.beats
    lattice = np.array([float(r) for r in pulse.model.ratios]) * pulse.model.pulse
    off = np.min(np.abs(np.log(lengths[:, None] / lattice[None, :])), axis=1)
    assert np.all(off <= pulse.model.tolerance)  # every rest is a whole number of heard durations
    assert len(np.unique(np.argmin(np.abs(np.log(lengths[:, None] / lattice)), axis=1))) >= 3  # of several kinds


def test_pitch_tracked_audio_teaches_the_same_pulse(tmp_path):
    session = _session(tmp_path)
    session.transcribe = True
    notes = _rhythm(60, np.random.default_rng(4))
    _run(session, 50.0, render_notes(notes, session.sample_rate, 50.0))
    pulse = session.world.pulse
    assert pulse.heard >= 40
    assert pulse.model.pulse == pytest.approx(BEAT, rel=0.03)


def test_the_colony_logs_surprise_when_the_heard_rhythm_changes(tmp_path):
    """The pulse's surprise is a percept in the log: 60 notes at 100 BPM surprise it at most
    once after it is ready (once, measured, at 10.6 s), then triplet eighths surprise it at their
    first notes (at the second triplet, measured)."""
    session = _session(tmp_path, EventLog(tmp_path / "events.jsonl"))
    steady = _rhythm(60, np.random.default_rng(2))
    end = steady[-1].time + BEAT
    triplets = [NoteEvent(end + i * BEAT / 3, 67, 90, 0, 0.1) for i in range(12)]
    for note in steady + triplets:
        session.world.inject(note)
    _run(session, end + 5.0)
    session.log.close()
    surprises = [e["t"] for e in read_events(tmp_path / "events.jsonl") if e["kind"] == "surprise"]
    assert sum(t < end for t in surprises) <= 1
    assert any(end <= t <= triplets[3].time + 2 * session.inst.settings.tick for t in surprises)
