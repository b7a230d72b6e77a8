"""three creatures: two creatures and a performer in one room. Each creature answers the
others — B sings material it can only have heard from A — and the performer's material
turns up in what they sing."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import soundfile

from audio.cepstrum import cepstra, distances_to
from audio.formants import word
from audio.utterance import Utterance, UtterancePercept, save_aural_model
from audio_fixtures import SR, warm_librosa  # noqa: F401
from creatures.clock import SimulatedClock
from creatures.config import ConfigError
from creatures.events import EventLog, read_events
from creatures.runtime.offline import run_offline
from creatures.runtime.schema import load_installation
from creatures.runtime.session import Session
from midi.sinks import MemorySink

PERFORMER, SEEDED = "ai", "oe"  # what the performer plays; what only A remembers at the start

pytestmark = pytest.mark.usefixtures("warm_librosa")

CONFIG = """\
title = "three creatures test"
seed = {seed}
tick = 0.02
[audio]
sample_rate = 22050
air = true
[output]
report = false
[[creature]]
name = "a"
kind = "three_creatures"
pan = -1.0
seed_model = "{model}"
[[creature]]
name = "b"
kind = "three_creatures"
pan = 1.0
"""


def performance(rng: np.random.Generator, length: float = 60.0) -> np.ndarray:
    """The performer: "ai" words every 2–4 s."""
    x = np.zeros(int(length * SR), np.float32)
    t = 1.0
    while t < length - 2:
        w = word(PERFORMER, rng, SR, stretch=rng.uniform(0.9, 1.1), f0=rng.uniform(110, 140), rms=0.05)
        x[int(t * SR) : int(t * SR) + len(w)] += w
        t += len(w) / SR + rng.uniform(2.0, 4.0)
    return x


@pytest.fixture(scope="module")
def room(tmp_path_factory) -> tuple[Path, list[dict]]:
    base = tmp_path_factory.mktemp("three")
    rng = np.random.default_rng(4)
    seed = UtterancePercept()
    for k in range(4):
        w = word(SEEDED, rng, SR, stretch=rng.uniform(0.9, 1.1), rms=0.05).astype(np.float32)
        seed.members.append(Utterance(w, SR, cepstra(w, SR), float(k)))
    save_aural_model(seed, base / "seed.json")
    soundfile.write(base / "performer.wav", performance(rng), SR, subtype="FLOAT")
    (base / "three.toml").write_text(CONFIG.format(seed=1, model=base / "seed.json"))
    run_offline(load_installation(base / "three.toml"), base / "out", audio=base / "performer.wav")
    return base / "out", read_events(base / "out" / "events.jsonl")


def sung_classes(out: Path, events: list[dict], creature: str, channel: int) -> list[str]:
    """What each of ``creature``'s songs in out.wav sounds like (it is alone on ``channel``)."""
    mix, sr = soundfile.read(out / "out.wav")
    rng = np.random.default_rng(9)
    templates = {c: [cepstra(word(c, rng, SR), SR) for _ in range(3)] for c in (PERFORMER, SEEDED)}
    heard = []
    for e in (e for e in events if e["kind"] == "sing" and e["creature"] == creature):
        piece = mix[int(e["start"] * sr) : int(e["end"] * sr), channel].astype(np.float32)
        assert np.sqrt(np.mean(piece**2)) > 1e-3
        c = cepstra(piece, sr)
        heard.append(min(templates, key=lambda k: distances_to(c, templates[k]).min()))
    return heard


def test_b_sings_what_it_heard_only_from_a_and_both_sing_the_performer(room):
    out, events = room
    a, b = sung_classes(out, events, "a", 0), sung_classes(out, events, "b", 1)
    assert SEEDED in a, "A sings its seeded memories"
    assert SEEDED in b, "B sings the seeded material, which only A could have sung to it"
    assert PERFORMER in a and PERFORMER in b, "the performer's material is in both creatures' output"


def test_creatures_hear_each_other_not_themselves(room):
    _, events = room
    songs = {c: [(e["start"], e["end"]) for e in events if e["kind"] == "sing" and e["creature"] == c] for c in "ab"}
    for me, other in (("a", "b"), ("b", "a")):
        heard = [(e["start"], e["end"]) for e in events if e["kind"] == "sound" and e["creature"] == me]
        of_other = [h for h in heard if any(s - 0.05 <= h[0] <= e + 0.1 for s, e in songs[other])]
        assert of_other, f"{me} hears {other}'s songs through the air"
        assert not any(s <= h[0] <= e for h in heard for s, e in songs[me]), f"{me} is deaf while it sings"


def test_motivation_memory_and_flushes_are_logged(room):
    _, events = room
    kinds = {e["kind"] for e in events}
    assert {"sound", "sing", "flush", "selection", "values", "motivation", "percepts"} <= kinds
    flushed = [e for e in events if e["kind"] == "flush" and e["sounds"]]
    assert flushed, "the score computer re-seeded memories from the input"
    remembered = {e["tuple"] for e in events if e["kind"] == "selection"}
    assert {"remember", "ignore", "sing"} <= remembered


def test_a_missing_seed_model_is_a_config_error_naming_the_key(tmp_path):
    config = tmp_path / "three.toml"
    config.write_text(CONFIG.format(seed=1, model=tmp_path / "nowhere.json"))
    with pytest.raises(ConfigError, match=r"creature\.0\.seed_model.*file not found"):
        load_installation(config)


def test_memory_survives_a_save(room, tmp_path):
    out, _ = room
    inst = load_installation(out.parent / "three.toml")
    first = Session(inst, SimulatedClock(), EventLog(tmp_path / "a.jsonl"), MemorySink()).creatures[0]
    saved = json.loads(json.dumps(first.state()))
    again = Session(inst, SimulatedClock(), EventLog(tmp_path / "b.jsonl"), MemorySink()).creatures[0]
    again.memory = []
    again.restore(saved)
    assert [m.origin for m in again.memory] == ["seed"] * 4
    assert all(np.abs(a.profile - b.profile).max() < 0.05 for a, b in zip(first.memory, again.memory))
    with pytest.raises(ValueError, match="malformed saved memory"):
        again.restore({"memory": [{"samples": "???"}], "motivation": saved["motivation"]})
