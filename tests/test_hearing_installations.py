"""The installations that hear audio answer a polyphonic recording in its own pitches.

A four-voice chorale in one key is played by fluidsynth's piano and given to an offline run as
its only input. The pitch-class histogram of what the creatures answer (their note events; for
three creatures, the notes heard in what they sing, transcribed from out.wav) must correlate
with the recording's (Pearson r > 0.5): a silent creature, or one playing at random, does not.
"""

from __future__ import annotations

import numpy as np
import pytest
import soundfile as sf

from audio.transcribe import Transcriber
from creatures.events import read_events
from creatures.runtime.offline import run_offline
from creatures.runtime.schema import load_installation
from installations import path as installation_path
from bench._sampled import chorale, have_sampler, render

pytestmark = [pytest.mark.skipif(not have_sampler(), reason="needs fluidsynth and fluid-soundfont-gm"),
              pytest.mark.slow]

RATE = 22050
SECONDS = 40.0


def histogram(pitches: list[int]) -> np.ndarray:
    return np.bincount(np.asarray(pitches, dtype=int) % 12, minlength=12).astype(float)


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> tuple[object, np.ndarray]:
    notes = chorale(np.random.default_rng(5), 4, SECONDS - 5.0, 36, 88)
    path = tmp_path_factory.mktemp("chorale") / "chorale.wav"
    sf.write(path, render(notes, "piano", RATE), RATE)
    return path, histogram([n.pitch for n in notes])


def answered(name: str, wav: object, out: object, **audio: object) -> list[int]:
    inst = load_installation(installation_path(name))
    for spec in inst.specs:  # three creatures' score flushes spoken words in: not what they heard
        if spec.kind == "three_creatures":
            spec.score = []
    for key, value in audio.items():
        setattr(inst.settings.audio, key, value)
    inst.settings.output.report = False
    run_offline(inst, out, audio=wav, duration=SECONDS)
    return [e["pitch"] for e in read_events(out / "events.jsonl") if e["kind"] == "note"]


@pytest.mark.parametrize("name, audio", [("listen", {}), ("exchange", {"transcribe": True})])
def test_note_creatures_answer_a_chorale_in_its_pitch_classes(recording, tmp_path, name: str, audio: dict) -> None:
    wav, heard = recording
    played = answered(name, wav, tmp_path / "out", **audio)
    assert len(played) >= 20
    r = float(np.corrcoef(histogram(played), heard)[0, 1])
    print(f"{name}: {len(played)} notes, pitch-class r = {r:.2f}")
    assert r > 0.5


def test_three_creatures_sing_back_the_chorale_s_pitch_classes(recording, tmp_path) -> None:
    wav, heard = recording
    answered("three_creatures", wav, tmp_path / "out")
    sung, rate = sf.read(tmp_path / "out" / "out.wav", dtype="float32", always_2d=True)
    ear = Transcriber(rate)
    ear.ended = type(ear.ended)()
    for i in range(0, len(sung), 1024):
        ear.feed(sung[i:i + 1024])
    ear.flush()
    pitches = [n.pitch for n in ear.ended]
    assert len(pitches) >= 10
    r = float(np.corrcoef(histogram(pitches), heard)[0, 1])
    print(f"three creatures: {len(pitches)} notes heard in their song, pitch-class r = {r:.2f}")
    assert r > 0.5
