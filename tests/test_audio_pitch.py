"""Pitched sound events to note events (audio/pitch.py)."""

from __future__ import annotations

import numpy as np
import pytest

from audio.pitch import note_events, velocity_from_level
from audio.segment import SoundEvent, frame_levels_db
from audio.sources import load_audio
from midi.notes import NoteEvent
from audio_fixtures import SR, Recorder, midi_to_hz, noise, recording, tone, warm_librosa  # noqa: F401

pytestmark = pytest.mark.usefixtures("warm_librosa")


def event(x: np.ndarray, start: float = 0.0) -> SoundEvent:
    x = np.asarray(x, dtype=np.float32)
    return SoundEvent(start, start + len(x) / SR, x, SR, float(frame_levels_db(x, 256).max()))


def test_harmonic_tones_midi_40_to_90_within_half_a_semitone(
    rng: np.random.Generator, record: Recorder
) -> None:
    within = 0
    pitches = np.arange(40, 91)
    for midi in pitches:
        played = midi + rng.uniform(-0.3, 0.3)  # an out-of-tune player
        x = tone(midi_to_hz(played), 0.3, harmonics=8, rms=0.05)
        notes = note_events(event(load_audio(record(x + noise(0.3, rng, rms=0.0005)))))
        within += len(notes) == 1 and abs(notes[0].pitch - played) <= 0.5
    assert within >= 0.95 * len(pitches), f"{within}/{len(pitches)} notes within ±0.5 semitone"


def test_pitch_survives_a_missing_fundamental(rng: np.random.Generator) -> None:
    f = midi_to_hz(50)
    t = np.arange(int(0.4 * SR)) / SR
    x = sum(np.sin(2 * np.pi * k * f * t) / k for k in range(2, 7)) * 0.05
    assert [n.pitch for n in note_events(event(x))] == [50]


def test_a_melody_in_one_event_becomes_notes_in_order() -> None:
    x = np.concatenate([tone(midi_to_hz(m), 0.25, rms=0.05) for m in (60, 64, 67)])
    notes = note_events(event(x, start=3.0))
    assert all(isinstance(n, NoteEvent) and n.channel == 0 for n in notes)
    assert [n.pitch for n in notes] == [60, 64, 67]
    assert [n.time for n in notes] == sorted(n.time for n in notes)
    assert notes[0].time == pytest.approx(3.0, abs=0.05)
    assert all(n.duration == pytest.approx(0.25, abs=0.06) for n in notes)


def test_noise_gives_no_notes(rng: np.random.Generator) -> None:
    assert note_events(event(noise(0.4, rng, rms=0.05))) == []


def test_velocity_follows_level() -> None:
    soft, loud = (note_events(event(tone(220.0, 0.3, rms=r)))[0] for r in (0.005, 0.2))
    assert soft.velocity < loud.velocity
    assert velocity_from_level(0.0) == 127 and velocity_from_level(-80.0) == 1
