"""Every shipped installation validates and runs offline for 60 simulated seconds, producing a
valid .mid, .wav and events.jsonl, identically for a fixed seed, and is heard: out.wav is loud
enough over the run and every creature acts (plays a note, sings or reads) often enough, whatever
its output is (ozymandias, soundcreatures and three creatures write no MIDI by design)."""

from __future__ import annotations

import hashlib
from pathlib import Path

import mido
import numpy as np
import pytest
import soundfile

import installations
from installations import CUTTING, SEEN_NOT_HEARD
from creatures.events import read_events
from creatures.runtime.offline import run_offline
from creatures.runtime.schema import load_installation
from midi.files import read_notes

SECONDS = 60.0

LOUDNESS_FLOOR = 0.005
"""Least RMS of out.wav over a run (full scale 1): the quietest shipped piece, soundcreatures,
measures 0.019 over 60 s; a silent one 0."""

ACTS = ("note", "sing", "read")
"""Events that are a creature making sound: a MIDI note, a sung utterance, a part read back."""


ACTS_PER_MINUTE = 2.0
"""Least acts per minute of every creature: the sparsest shipped creature (sandstone's king,
a listener most of the time) plays 3 notes in 60 s, three creatures' sing 3–4 times."""


def assert_heard(name: str, out: Path, events: list[dict], seconds: float) -> None:
    """The run is not silent: ``out.wav`` is above :data:`LOUDNESS_FLOOR` and every creature
    in the config acted at least :data:`ACTS_PER_MINUTE` times a minute."""
    wav, _ = soundfile.read(out / "out.wav")
    rms = float(np.sqrt(np.mean(wav**2)))
    assert rms > LOUDNESS_FLOOR, f"{name}: out.wav RMS {rms:.4f} is below {LOUDNESS_FLOOR}"
    creatures = [spec.name for spec in load_installation(installations.path(name)).specs]
    for creature in creatures:
        if (name, creature) in SEEN_NOT_HEARD:  # its acts are what it shows: its pose moves
            poses = [np.array(e["joints"]) for e in events if e["kind"] == "pose" and e["creature"] == creature]
            moves = sum(np.abs(b - a).max() > 0.01 for a, b in zip(poses, poses[1:]))
            assert moves / (seconds / 60.0) >= ACTS_PER_MINUTE, f"{name}: {creature} moved {moves} times"
            continue
        kinds = ("selection",) if (name, creature) in CUTTING else ACTS
        acts = sum(e["kind"] in kinds and e.get("creature") == creature for e in events)
        rate = acts / (seconds / 60.0)
        assert rate >= ACTS_PER_MINUTE, f"{name}: {creature} acted {acts} times in {seconds:.0f} s"


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
    # out.mid: what the creatures played, and what they heard on its own "input" track; a note
    # logged when it was scheduled but due after the end (a phrase begun in the last second)
    # was never sent
    sounded = [e for e in played if e["time"] < SECONDS]
    assert first.notes_played == len(played) and len(read_notes(out / "out.mid")) == len(sounded) + len(heard)
    assert_heard(name, out, events, SECONDS)
    run_offline(inst, tmp_path / "b", duration=SECONDS)
    assert _digest(tmp_path / "a") == _digest(tmp_path / "b")


def test_every_shipped_config_validates():
    for name in installations.names():
        inst = load_installation(installations.path(name))
        assert inst.specs, name


def test_a_silent_run_is_not_heard(tmp_path):
    """The check above bites: a run whose audio is silence, or whose creature never acts, fails."""
    soundfile.write(tmp_path / "out.wav", np.zeros((22050, 2)), 22050)
    with pytest.raises(AssertionError, match="RMS"):
        assert_heard("exchange", tmp_path, [], 60.0)
    soundfile.write(tmp_path / "out.wav", np.full((22050, 2), 0.1), 22050)
    acts = [{"kind": "note", "creature": name} for name in ("ada", "bo") for _ in range(5)]
    with pytest.raises(AssertionError, match="cy acted 0 times"):
        assert_heard("exchange", tmp_path, acts, 60.0)
    assert_heard("exchange", tmp_path, acts + [{"kind": "note", "creature": "cy"}] * 2, 60.0)
