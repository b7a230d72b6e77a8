"""three creatures' score computer: "their memories were periodically flushed with
pre-selected samples by an external 'score providing' computer" (thesis, "three creatures
(performance)"). At each scripted time the memory holds the score's samples, and what the
creatures sing afterwards is those samples."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import soundfile

from audio.cepstrum import cepstra
from audio.formants import word
from audio.utterance import Utterance, UtterancePercept, load_aural_model, save_aural_model
from audio_fixtures import SR, warm_librosa  # noqa: F401
from creatures.clock import SimulatedClock
from creatures.config import ConfigError
from creatures.events import EventLog, read_events
from creatures.runtime.offline import run_offline
from creatures.runtime.schema import load_installation
from creatures.runtime.session import Session
from installations import path as installation_path
from midi.sinks import MemorySink
from test_kind_three import performance

pytestmark = pytest.mark.usefixtures("warm_librosa")

FIRST, SECOND = 10.0, 22.0  # the scripted flushes' times
SLOTS = 4

CONFIG = """\
title = "three creatures score test"
seed = 2
tick = 0.02
duration = 34.0
[audio]
sample_rate = 22050
air = true
[output]
report = false
[[creature]]
name = "a"
kind = "three_creatures"
pan = -1.0
memory_size = {slots}
flush_size = 0                # no flushes from the input: only the score's
urge_gain = 2.5               # every sound heard moves it to sing
interest_growth = 0.0         # interest, once spent, stays spent: nothing heard after
interest_cost = 1.0           # the first sound is remembered, so songs after a flush are the score's
[[creature.score]]
at = {first}
model = "{a}"
slots = {slots}
[[creature.score]]
at = {second}
model = "{b}"
slots = {slots}
"""


def model(path: Path, vowel: str, first_time: float, rng: np.random.Generator) -> set[float]:
    """Save an aural model of ``SLOTS`` ``vowel`` words heard at ``first_time`` + k; their times."""
    tree = UtterancePercept()
    for k in range(SLOTS):
        w = word(vowel, rng, SR, stretch=rng.uniform(0.9, 1.1), rms=0.05).astype(np.float32)
        tree.members.append(Utterance(w, SR, cepstra(w, SR), first_time + k))
    save_aural_model(tree, path)
    return {first_time + k for k in range(SLOTS)}


@pytest.fixture(scope="module")
def scored(tmp_path_factory) -> tuple[Path, list[dict], set[float], set[float]]:
    base = tmp_path_factory.mktemp("score")
    rng = np.random.default_rng(5)
    a, b = model(base / "a.json", "oe", 1000.0, rng), model(base / "b.json", "ieu", 2000.0, rng)
    soundfile.write(base / "performer.wav", performance(rng, 34.0), SR, subtype="FLOAT")
    (base / "score.toml").write_text(CONFIG.format(slots=SLOTS, first=FIRST, second=SECOND,
                                                   a=base / "a.json", b=base / "b.json"))
    run_offline(load_installation(base / "score.toml"), base / "out", audio=base / "performer.wav")
    return base, read_events(base / "out" / "events.jsonl"), a, b


def test_the_memory_holds_the_scores_samples_right_after_each_flush(scored):
    _, events, a, b = scored
    flushes = [e for e in events if e["kind"] == "flush" and e["source"] == "score"]
    assert [round(e["t"], 1) for e in flushes] == [FIRST, SECOND]
    for flush, samples in zip(flushes, (a, b)):
        assert {origin for origin, _ in flush["memory"]} == {"score"}
        assert {time for _, time in flush["memory"]} == samples
    before = [e for e in events if e["kind"] == "percepts" and e["t"] < FIRST - 1]
    assert before and before[-1]["sizes"]["score"] == 0 and before[-1]["sizes"]["heard"] == 1


def test_what_is_sung_after_a_flush_comes_from_it(scored):
    """Until the creature next remembers a sound it hears (its spent interest still takes in
    a sound less familiar than nothing: a negative correlation), it sings only the score's
    samples; after that, only the score's samples and that sound."""
    _, events, a, b = scored
    songs = [e for e in events if e["kind"] == "sing"]
    remembered = [e["end"] for e in events if e["kind"] == "sound" and e["remembered"]]
    assert not any(e["origin"] == "score" for e in songs if e["start"] < FIRST)
    for start, end, samples in ((FIRST, SECOND, a), (SECOND, np.inf, b)):
        later = [r for r in remembered if start <= r < end]
        until = min([*later, end])
        pure = [e for e in songs if start <= e["start"] < until]
        assert len(pure) >= 2, "the performer moves the creature to sing"
        assert all(e["origin"] == "score" and e["heard_at"] in samples for e in pure)
        rest = [e for e in songs if until <= e["start"] < end]
        assert all(e["heard_at"] in {*samples, *later} for e in rest)


@pytest.mark.parametrize("edit, message", [
    (("at = 22.0", "at = 5.0"), r"score\.toml:\d+.*creature\.0\.score.*times must increase"),
    (("at = 10.0", "at = -1.0"), r"score\.toml:\d+.*creature\.0\.score\.0\.at"),
    (("b.json", "nowhere.json"), r"score\.toml:\d+.*creature\.0\.score\.1\.model.*file not found"),
])
def test_a_bad_score_is_a_config_error_with_file_and_line(scored, tmp_path, edit, message):
    base = scored[0]
    config = tmp_path / "score.toml"
    config.write_text((base / "score.toml").read_text().replace(*edit))
    with pytest.raises(ConfigError, match=message):
        load_installation(config)
    run = subprocess.run([sys.executable, "-m", "creatures.cli", "offline", str(config), "--out", str(tmp_path / "out")],
                         capture_output=True, text=True)
    assert run.returncode == 2 and "score" in run.stderr and "Traceback" not in run.stderr


def test_a_score_flush_into_a_memory_not_yet_full_keeps_every_memory_it_has_room_for(tmp_path):
    """memory_size 8, three seeded sounds, a flush of four slots: 8 − 4 = 4 memories may stay,
    so all three seeds stay beside the four samples. The slice ``memory[3 − 4:]`` kept only
    the newest seed (5 memories, two seeds forgotten for no reason)."""
    rng = np.random.default_rng(9)
    seeds = model(tmp_path / "seed.json", "oe", 0.0, rng) - {3.0}
    tree = load_aural_model(tmp_path / "seed.json")
    tree.members = [u for u in tree.members if u.time in seeds]
    save_aural_model(tree, tmp_path / "seed.json")
    scored = model(tmp_path / "a.json", "ieu", 1000.0, rng)
    (tmp_path / "s.toml").write_text(CONFIG.format(slots=8, first=1.0, second=2.0, a=tmp_path / "a.json",
                                                   b=tmp_path / "a.json")
                                     .replace("slots = 8", "slots = 4")
                                     .replace("flush_size = 0", f'flush_size = 0\nseed_model = "{tmp_path / "seed.json"}"'))
    session = Session(load_installation(tmp_path / "s.toml"), SimulatedClock(), EventLog(tmp_path / "e.jsonl"),
                      MemorySink())
    creature = session.creatures[0]
    assert [m.utterance.time for m in creature.memory] == [0.0, 1.0, 2.0]
    creature.tick(1.0)
    assert sorted(m.utterance.time for m in creature.memory) == [0.0, 1.0, 2.0, *sorted(scored)]


# -- the shipped piece's score (installations/three_creatures.toml) -------------------------

SHIPPED = installation_path("three_creatures").parent / "three_creatures"


def _model_times(name: str) -> set[float]:
    return {u.time for u in load_aural_model(SHIPPED / name).members}


@pytest.fixture(scope="module")
def shipped(tmp_path_factory) -> list[dict]:
    out = tmp_path_factory.mktemp("shipped") / "out"
    run_offline(load_installation(installation_path("three_creatures")), out)
    return read_events(out / "events.jsonl")


def test_the_shipped_score_flushes_each_creature_with_its_words_and_they_sing_them(shipped):
    """At 12 s each creature is given its own four spoken words, at 24 s the other's; from
    the first flush on, each sings words of the score the performer moved it to sing."""
    a, b = _model_times("score-a.json"), _model_times("score-b.json")
    given = {"left": (a, b), "right": (b, a)}
    for name, models in given.items():
        flushes = [e for e in shipped if e["kind"] == "flush" and e["source"] == "score" and e["creature"] == name]
        assert [round(e["t"], 2) for e in flushes] == [12.0, 24.0]
        for flush, model in zip(flushes, models):
            assert model <= {time for origin, time in flush["memory"] if origin == "score"}
        sung = [e for e in shipped if e["kind"] == "sing" and e["creature"] == name and e["origin"] == "score"]
        assert sung, f"{name} never sang the score"
        assert all(e["start"] >= 12.0 and e["heard_at"] in models[0] | (models[1] if e["start"] >= 24 else set())
                   for e in sung)


def test_the_shipped_score_models_are_what_aural_model_makes_of_the_shipped_words(tmp_path):
    """The models are reproducible from the samples by the command the config's header gives."""
    for model, prefix in (("score-a.json", "a-"), ("score-b.json", "b-")):
        out = tmp_path / model
        run = subprocess.run([sys.executable, "-m", "creatures.cli", "aural-model", str(out),
                              *map(str, sorted(SHIPPED.glob(f"{prefix}*.wav")))], capture_output=True, text=True)
        assert run.returncode == 0, run.stderr
        made, shipped_model = load_aural_model(out), load_aural_model(SHIPPED / model)
        assert [u.time for u in made.members] == [u.time for u in shipped_model.members]
        for mine, theirs in zip(made.members, shipped_model.members):
            np.testing.assert_array_equal(mine.samples, theirs.samples)
            np.testing.assert_allclose(mine.features, theirs.features, atol=1e-9)


def test_the_score_model_is_found_beside_the_config_from_any_working_directory(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    inst = load_installation(installation_path("three_creatures"))
    assert [Path(flush.model) for flush in inst.specs[0].score] == [SHIPPED / "score-a.json", SHIPPED / "score-b.json"]


@pytest.mark.parametrize("arguments, message", [
    (["model.txt", "{wav}"], "written as a .json file"),
    (["model.json", "missing.wav"], "missing.wav: no such sound file"),
    (["model.json", "{silent}"], "silent.wav: silent: nothing to remember"),
    (["nowhere/model.json", "{wav}"], "nowhere: no such folder"),
    (["--top-db", "nan", "model.json", "{wav}"], "'nan' is not a number in [0, 120]"),
])
def test_aural_model_refuses_bad_input_with_a_clear_error_and_writes_nothing(tmp_path, arguments, message):
    soundfile.write(tmp_path / "silent.wav", np.zeros(SR, np.float32), SR)
    filled = [a.format(wav=SHIPPED / "a-again.wav", silent=tmp_path / "silent.wav") for a in arguments]
    run = subprocess.run([sys.executable, "-m", "creatures.cli", "aural-model", *filled],
                         capture_output=True, text=True, cwd=tmp_path)
    assert run.returncode == 2 and message in run.stderr and "Traceback" not in run.stderr
    assert not list(tmp_path.glob("model.*"))


def test_aural_model_replaces_a_model_only_when_told_to(tmp_path):
    made = [sys.executable, "-m", "creatures.cli", "aural-model"]
    first = subprocess.run([*made, "model.json", str(SHIPPED / "a-again.wav"), str(SHIPPED / "a-answer.wav")],
                           capture_output=True, text=True, cwd=tmp_path)
    again = subprocess.run([*made, "model.json", str(SHIPPED / "a-again.wav")], capture_output=True, text=True,
                           cwd=tmp_path)
    assert first.returncode == 0 and again.returncode == 2 and "give --force" in again.stderr
    assert len(load_aural_model(tmp_path / "model.json").members) == 2  # kept as it was
    forced = subprocess.run([*made, "--force", "model.json", str(SHIPPED / "a-again.wav")], capture_output=True,
                            text=True, cwd=tmp_path)
    assert forced.returncode == 0 and len(load_aural_model(tmp_path / "model.json").members) == 1


def test_the_run_summary_counts_the_sounds_they_sing(tmp_path):
    """Creatures that sing sounds play no notes: the summary says what they did instead."""
    run = subprocess.run([sys.executable, "-m", "creatures.cli", "offline", "three_creatures", "--duration", "20",
                          "--out", str(tmp_path / "out"), "--no-progress"], capture_output=True, text=True)
    sung = sum(e["kind"] == "sing" for e in read_events(tmp_path / "out" / "events.jsonl"))
    assert run.returncode == 0 and sung > 0
    assert f"0 notes played, {sung} sounds sung or words read" in run.stdout
