"""The simulated clicker trainer (``[input.trainer]``, creatures/runtime/trainer.py): an offline
run of the shipped duncan is a training session, with no recording, no espeak-ng and no
hardware. The learning is read from the dog's own ``trick held`` events against the times the
trainer's cues were said, not from the trainer's judgement of its trials."""

from __future__ import annotations

import itertools
import json
from pathlib import Path

import numpy as np
import pytest

from audio.cepstrum import distances_to
from audio.formants import vowels_of, word
from audio.utterance import DEFAULT_RADIUS
from creatures.config import ConfigError
from creatures.kinds.hearing_parts import Ear, HearingSpec
from creatures.runtime import live
from creatures.runtime.offline import run_offline
from creatures.runtime.schema import load_installation
from creatures.runtime.trainer_spec import TrainerSection
from duncan_configs import SHIPPED, with_trainer

QUICK = "\n[output]\nwav = false\nmidi = false\nreport = false\n"


def _config(tmp_path: Path, text: str) -> Path:
    config = tmp_path / "duncan.toml"
    config.write_text(text + QUICK, encoding="utf-8")
    return config


def _session(config: Path, out: Path) -> list[dict]:
    """The whole shipped run (240 s, ~40 cues) offline; its events."""
    run_offline(load_installation(config), out)
    return [json.loads(line) for line in (out / "events.jsonl").read_text().splitlines()]


def _held_within(events: list[dict], trick: str, lo: float, hi: float) -> bool:
    return any(e["kind"] == "trick held" and e["trick"] == trick and lo <= e["t"] <= hi for e in events)


def _on_cue(events: list[dict]) -> tuple[list[bool], list[bool]]:
    """For each cue said: was its trick held within its window after it (2 s, a beg 4 s), and
    within as long just before it (the same trick, unbidden)?"""
    said = [e for e in events if e["kind"] == "cue said"]
    window = {"beg": 4.0}
    cued = [_held_within(events, c["trick"], c["end"], c["end"] + window.get(c["trick"], 2.0)) for c in said]
    unbidden = [_held_within(events, c["trick"], c["at"] - window.get(c["trick"], 2.0), c["at"]) for c in said]
    return cued, unbidden


@pytest.fixture(scope="module")
def trained(tmp_path_factory) -> list[dict]:
    where = tmp_path_factory.mktemp("trained")
    return _session(_config(where, SHIPPED.read_text(encoding="utf-8")), where / "out")


def test_the_shipped_dog_learns_its_cues_from_the_simulated_trainer(trained):
    events = trained
    said = [e for e in events if e["kind"] == "cue said"]
    cued, unbidden = _on_cue(events)
    third = len(said) // 3
    early, late, idle = np.mean(cued[:third]), np.mean(cued[-third:]), np.mean(unbidden[-third:])
    print(f"{len(said)} cues, {sum(e['kind'] == 'reward' for e in events)} clicks; P(trick within its window) "
          f"{early:.2f} in the first third, {late:.2f} in the last; unbidden {idle:.2f}")
    assert len(said) >= 35 and {c["word"] for c in said} == {"seated", "lie down", "paws up"}
    assert late >= 0.75 and early <= 0.4  # untrained it rarely answers a cue; trained, nearly always
    assert idle <= 0.25  # and not because it does the trick all the time
    for trick in ("sit", "lie down", "beg"):  # every cue is learnt, not one trick done to every cue
        answered = [ok for ok, c in zip(cued, said) if c["trick"] == trick]
        assert np.mean(answered[len(answered) // 2:]) >= 0.6, trick


def test_each_spoken_cue_is_one_sound_class_of_the_dog(trained):
    """The dog hears every cue the trainer said, and each word always as the same class of its own."""
    said = [e for e in trained if e["kind"] == "cue said"]
    heard = [e for e in trained if e["kind"] == "cue"]
    assert len(heard) == len(said)
    classes = {}
    for cue, sound in zip(said, heard):
        classes.setdefault(cue["word"], set()).add(sound["sound"])
    assert all(len(s) == 1 for s in classes.values()), classes
    assert len(set.union(*classes.values())) == 3
    assert sum(e["kind"] == "hypothesis" for e in trained) == 3


def test_clicks_go_through_the_input_map_on_the_tick_after_the_trick_was_seen(trained):
    trials = [e for e in trained if e["kind"] == "trial"]
    rewards = [e for e in trained if e["kind"] == "reward"]
    clicked = [e for e in trials if e["clicked"]]
    assert len(rewards) == len(clicked) >= 15
    assert all(0.04 < r["t"] - c["t"] < 0.06 for r, c in zip(rewards, clicked))  # one tick (0.05 s) later
    assert all(r["amount"] == 3.0 and r["credited"] for r in rewards)  # the /click map's reward


def test_the_beg_is_clicked_on_a_percentile_schedule(trained):
    """A beg seen after its cue is clicked only when at least as high as the median of the last
    five begs seen so (Galbicka's percentile schedule); other tricks whenever seen."""
    seen = [e for e in trained if e["kind"] == "trial" and e["held"]]
    begs = [e for e in seen if e["trick"] == "beg"]
    assert len(begs) >= 8 and any(not e["clicked"] for e in begs)
    for k, beg in enumerate(begs):
        bar = np.median([b["height"] for b in begs[max(0, k - 5):k]]) if k else -np.inf
        assert beg["clicked"] == (beg["height"] >= bar)
    assert all(e["clicked"] for e in seen if e["trick"] != "beg")


def test_without_the_click_map_the_trainer_rewards_nothing_and_the_dog_learns_nothing(tmp_path):
    text = SHIPPED.read_text(encoding="utf-8")
    route = '[[input.map]]\nosc = "/click"\nto = "reward"\namount = 3.0\nrate = 0.3\nwindow = 1.0\n'
    assert route in text
    config = _config(tmp_path, text.replace(route, ""))
    inst = load_installation(config)
    assert any("no [[input]] map with to = \"reward\" takes it" in note for note in inst.notes)
    events = _session(config, tmp_path / "out")
    assert not any(e["kind"] == "reward" for e in events)
    assert sum(e["kind"] == "trial" and e["clicked"] for e in events) >= 5  # it clicked, into nothing
    cued, _ = _on_cue(events)
    print(f"unclicked: P(trick within its window) {np.mean(cued[-len(cued) // 3:]):.2f} in the last third")
    assert np.mean(cued[-len(cued) // 3:]) <= 0.4


def test_the_shipped_cues_are_distinct_words_to_the_dogs_ear_and_one_vowel_words_are_not():
    """The trainer's voice varied as shipped (pitch, stretch, level from their ranges), heard by
    duncan's ear: each of the shipped cues lies within the ear's radius of its own repeats and
    far from the other cues; formant "sit", "down" and "beg" (a vowel each) do not."""
    spec = TrainerSection(creature="duncan", cues={"seated": "sit", "lie down": "lie down", "paws up": "beg"})
    rng = np.random.default_rng(5)

    def heard(cue: str) -> list:
        parts = []
        for _ in range(6):
            parts += [word(vowels_of(cue), rng, 22050, stretch=float(rng.uniform(*spec.stretch)),
                           f0=float(rng.uniform(*spec.pitch)), rms=float(rng.uniform(*spec.level))), np.zeros(22050)]
        audio = np.concatenate([np.zeros(11025), *parts]).astype(np.float32)
        ear = Ear(HearingSpec(half_duplex=False, memory=1.0))
        return [u for i in range(0, len(audio), 1102)
                for u in ear.listen((i + 1102) / 22050, audio[i:i + 1102], 22050)]

    def spread(words: list[str]) -> tuple[float, float]:
        sounds = {w: heard(w) for w in words}
        assert all(len(s) == 6 for s in sounds.values())
        within = max(max(distances_to(u.features, [v.features for v in sounds[w] if v is not u]))
                     for w in words for u in sounds[w])
        between = min(min(distances_to(u.features, [v.features for v in sounds[b]]))
                      for a, b in itertools.permutations(words, 2) for u in sounds[a])
        return within, between

    within, between = spread(list(spec.cues))
    print(f"shipped cues: within {within:.2f}, between {between:.2f}")
    assert within < DEFAULT_RADIUS < 2 * DEFAULT_RADIUS < between
    within, between = spread(["sit", "down", "beg"])
    print(f"one-vowel cues: within {within:.2f}, between {between:.2f}")
    assert between < within  # no classes at all


def _load_with(tmp_path: Path, table: str) -> None:
    load_installation(_config(tmp_path, with_trainer(table)))


@pytest.mark.parametrize("table,error", [
    ('[input.trainer]\ncreature = "duncan"\ncues = { seated = "sit" }\nwindw = 2.0\n',
     r"duncan\.toml:\d+: input\.trainer\.windw: .*did you mean 'window'"),
    ('[input.trainer]\ncreature = "dunkan"\ncues = { seated = "sit" }\n',
     r"duncan\.toml:\d+: input\.trainer\.creature: no creature named 'dunkan' \(did you mean 'duncan'\?\)"),
    ('[input.trainer]\ncreature = "duncan"\ncues = { seated = "sit", "lie down" = "lie dwn" }\n',
     r"duncan\.toml:\d+: input\.trainer\.cues\.lie down: 'duncan' has no trick 'lie dwn' \(did you mean 'lie down'\?\)"),
    ('[input.trainer]\ncreature = "duncan"\ncues = { sit = "sit" }\n',
     r"duncan\.toml:\d+: input\.trainer\.cues: .*'sit' is said as the one vowel 'i'"),
    ('[input.trainer]\ncreature = "duncan"\ncues = { seated = "sit", beaded = "beg" }\n',
     r"duncan\.toml:\d+: input\.trainer\.cues: .*'beaded' and 'seated' are said as one formant word"),
    ('[input.trainer]\ncreature = "duncan"\ncues = { "paws up" = "beg" }\nevery = [3.0, 5.0]\n',
     r"duncan\.toml:\d+: input\.trainer: .*every: cues 3 s apart overlap the windows"),
    ('[input.trainer]\ncreature = "duncan"\ncues = { seated = "sit" }\nshaping = "sit"\n',
     r"duncan\.toml:\d+: input\.trainer\.shaping: 'duncan' holds 'sit' at no height to shape"),
    ('[input.trainer]\ncreature = "duncan"\ncues = { seated = "sit" }\nwindows = { begg = 4.0 }\n',
     r"duncan\.toml:\d+: input\.trainer\.windows\.begg: no cue asks for 'begg'"),
    ('[input.trainer]\ncreature = "duncan"\ncues = { seated = "sit" }\nlevel = [0.0, 1.0]\n',
     r"duncan\.toml:\d+: input\.trainer\.level\.0: .*greater than or equal to 0\.001 \(got 0\.0\)"),
    ('[input.trainer]\ncreature = "duncan"\ncues = { seated = "sit" }\npitch = [nan, 120.0]\n',
     r"duncan\.toml:\d+: input\.trainer\.pitch"),
], ids=["unknown key", "creature", "trick", "one vowel", "same word", "every", "shaping", "windows", "level", "nan"])
def test_a_wrong_trainer_is_a_config_error_at_its_line(tmp_path, table, error):
    with pytest.raises(ConfigError, match=error):
        _load_with(tmp_path, table)


def test_a_dog_taught_fewer_tricks_than_the_shipped_cues_ask_for_is_told_which_cue(tmp_path):
    text = SHIPPED.read_text(encoding="utf-8").replace('kind = "duncan"\n', 'kind = "duncan"\ntricks = ["sit", "beg"]\n')
    with pytest.raises(ConfigError, match=r"duncan\.toml:\d+: input\.trainer\.cues\.lie down: 'duncan' has no "
                                          r"trick 'lie down' \(its tricks: sit, beg\)"):
        load_installation(_config(tmp_path, text))


def test_a_live_run_says_it_leaves_the_trainer_out(tmp_path):
    text = (SHIPPED.read_text(encoding="utf-8").replace('input_device = "default"', "output = false")
            .replace("port = 9000", ""))
    said: list[str] = []
    summary = live.run_live(load_installation(_config(tmp_path, text)), duration=0.3, state=tmp_path / "state",
                            say=said.append)
    assert summary.ticks >= 3
    assert any(m.startswith("[input.trainer] is for offline runs") for m in said), said


def test_the_config_reference_documents_every_key_of_the_trainer():
    """docs/config.md's top level left out every row naming `creature` (meant for the
    ``[[creature]]`` list, which has a section of its own), so the trainer's ``creature`` key
    went undocumented."""
    from creatures.runtime.docs import config_reference

    page = config_reference()
    section = page[page.index("`[input.trainer]` —"):]
    section = section[:section.index("\n\n`[", 1)] if "\n\n`[" in section else section
    for key in TrainerSection.model_fields:
        assert f"| `{key}` |" in section, key
    assert "| `creature` | list" not in page.split("## `[[input]]`")[0]  # the creatures' list: its own section


def test_the_trainers_voice_goes_on_over_a_recording_block_by_block():
    """Given a recording (``--audio``), the dog hears it with the cues over it: block by block,
    the recording plus one cue begun where the trainer's clock says, nothing made ahead."""
    from types import SimpleNamespace

    from creatures.runtime.trainer import Trainer

    spec = TrainerSection(creature="duncan", cues={"seated": "sit"}, every=(4.0, 4.0))
    said: list[dict] = []
    trainer = Trainer(spec, SimpleNamespace(name="duncan"), None, lambda kind, **f: said.append({"kind": kind, **f}), 22050,
                      np.random.default_rng(1))
    recording = np.random.default_rng(2).normal(0, 0.01, 22050 * 10).astype(np.float32)
    blocks = [trainer.heard(recording[a:a + 1102], a, a + 1102) for a in range(0, 22050 * 10 - 1102, 1102)]
    heard = np.concatenate(blocks)
    voice = heard - recording[:len(heard)]
    sounding = np.flatnonzero(np.abs(voice) > 1e-6)
    assert [round(f["at"], 3) for f in said if f["kind"] == "cue said"] == [4.0, 8.0]  # every 4 s, the first 4 s in
    assert abs(sounding[0] / 22050 - 4.0) < 0.02 and 0.3 < (sounding[sounding < 8 * 22050][-1] - sounding[0]) / 22050 < 0.6
    assert len(trainer.voice) < 22050  # one cue held at a time


def test_a_run_too_short_to_train_says_how_long_would(tmp_path):
    """30 s (the demo's default until 2026-12-07) give the dog a few cues and no chance to learn: the summary says what
    the trainer did and how long a session trains it, not a silent untrained dog."""
    summary = run_offline(load_installation(_config(tmp_path, SHIPPED.read_text(encoding="utf-8"))), tmp_path / "out",
                          duration=30.0)
    (line,) = [m for m in summary.messages if m.startswith("trainer:")]
    said = [json.loads(x) for x in (tmp_path / "out" / "events.jsonl").read_text().splitlines()]
    cues = sum(e["kind"] == "cue said" for e in said)
    assert 3 <= cues <= 6 and line.startswith(f"trainer: {cues} cues said to duncan, ")
    assert "too few to learn from (about 40 cues train it: --duration 240)" in line
