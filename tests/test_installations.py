"""Every shipped installation validates and runs offline for 60 simulated seconds, producing a
valid .mid, .wav and events.jsonl, identically for a fixed seed."""

from __future__ import annotations

import hashlib
from pathlib import Path

import mido
import pytest
import soundfile

import installations
from creatures.events import read_events
from creatures.runtime.offline import run_offline
from creatures.runtime.schema import load_installation
from midi.files import read_notes

SECONDS = 60.0


def _digest(out: Path) -> dict[str, str]:
    return {name: hashlib.sha256((out / name).read_bytes()).hexdigest()
            for name in ("out.mid", "out.wav", "events.jsonl")}


@pytest.mark.slow
@pytest.mark.parametrize("name", installations.names())
def test_shipped_installation_runs_offline_deterministically(name, tmp_path):
    inst = load_installation(installations.path(name))
    inst.settings.output.report = False
    inst.settings.output.frames = False
    first = run_offline(inst, tmp_path / "a", duration=SECONDS)
    out = tmp_path / "a"
    info = soundfile.info(out / "out.wav")
    assert info.samplerate == inst.settings.audio.sample_rate and info.channels == 2
    assert info.frames == round(SECONDS * info.samplerate)
    mido.MidiFile(out / "out.mid")  # a standard file any DAW opens
    events = read_events(out / "events.jsonl")
    assert events[0]["kind"] == "run" and events[-1]["kind"] == "end"
    played = [e for e in events if e["kind"] == "note"]
    heard = [e for e in events if e["kind"] == "heard"]
    # out.mid: what the creatures played, and what they heard on its own "input" track
    assert first.notes_played == len(played) and len(read_notes(out / "out.mid")) == len(played) + len(heard)
    run_offline(inst, tmp_path / "b", duration=SECONDS)
    assert _digest(tmp_path / "a") == _digest(tmp_path / "b")


def test_every_shipped_config_validates():
    for name in installations.names():
        inst = load_installation(installations.path(name))
        assert inst.specs, name
