"""Duncan's config (creatures/kinds/duncan.py): what an installation may set and what it is
refused, with file, key and line."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from creatures.clock import SimulatedClock
from creatures.config import ConfigError
from creatures.events import EventLog
from duncan_configs import with_trainer
from creatures.runtime.schema import load_installation
from creatures.runtime.session import Session
from midi.sinks import MemorySink

SHIPPED = Path(__file__).resolve().parents[1] / "installations" / "duncan.toml"
SR = 22050


def _config(tmp_path: Path, keys: str) -> Path:
    """The shipped dog with ``keys`` of its own, without the shipped trainer, whose cues name
    the shipped tricks (tests/test_trainer.py: a dog lacking one is told which cue)."""
    config = tmp_path / "duncan.toml"
    config.write_text(with_trainer("").replace('kind = "duncan"\n', f'kind = "duncan"\n{keys}\n'))
    return config


def test_a_dog_of_fewer_tricks_needs_no_offers_or_notes_for_the_tricks_it_lacks(tmp_path):
    """``offers`` and ``notes`` default to the shipped tricks; a dog taught only sit and beg was
    refused for the defaults' 'lie down' ("offers: 'lie down' is not one of the tricks", then
    "notes: 'lie down' = 55 must name a trick"), keys its config never wrote. The defaults'
    entries for tricks it lacks are not its own."""
    inst = load_installation(_config(tmp_path, 'tricks = ["sit", "beg"]'))
    dog = Session(inst, SimulatedClock(), EventLog(tmp_path / "e.jsonl"), MemorySink()).creatures[0]
    assert dog.spec.offers == ["sit", "beg"]
    assert dog.spec.notes == {"sit": 60, "beg": 64, "stand": 48}
    assert [tp.name for tp in dog.group.tuples] == ["whatever|stand", "quiet|sit", "quiet|beg"]


def test_offers_written_for_a_trick_the_dog_lacks_are_still_refused(tmp_path):
    with pytest.raises(ConfigError, match=r"duncan\.toml:\d+.*offers: 'roll over' is not one of the tricks"):
        load_installation(_config(tmp_path, 'tricks = ["sit", "beg"]\noffers = ["roll over"]'))


def test_notes_written_for_a_trick_the_dog_lacks_are_still_refused(tmp_path):
    with pytest.raises(ConfigError, match=r"duncan\.toml:\d+.*notes: 'roll over'"):
        load_installation(_config(tmp_path, 'tricks = ["sit", "beg"]\noffers = []\nnotes = {"roll over" = 67}'))


@pytest.mark.parametrize("keys, key", [('tricks = ["sit", "beg", "sit"]', "tricks"),
                                       ('offers = ["sit", "sit"]', "offers")])
def test_a_trick_named_twice_is_refused(tmp_path, keys, key):
    """Accepted, ``tricks = ["sit", "beg", "sit"]`` gave every cue two "heard/k|sit" tuples of
    one name (twice the chance of sitting on any cue, their two values saved under one key)."""
    with pytest.raises(ConfigError, match=rf"duncan\.toml:\d+.*{key}: 'sit' is named twice"):
        load_installation(_config(tmp_path, keys))


def test_a_restored_beg_model_keeps_its_clicked_begs_and_the_configs_prior_and_size(tmp_path):
    """The beg model's prior and buffer size are settings (GaussianModel.restore: "an edited
    config wins over a saved file"); the saved clicked begs are what the dog learnt. Restored
    with ``GaussianModel.from_dict``, a dog saved at prior 0.2 and size 6 kept both after its
    config said prior_mean 0.6, size 10 and prior_weight 0.5: its beg mean stayed the saved
    0.623 (0.668 with the config's prior)."""
    first = Session(load_installation(SHIPPED), SimulatedClock(), EventLog(tmp_path / "a.jsonl"),
                    MemorySink()).creatures[0]
    for height in (0.9, 0.95, 1.0):
        first.beg_height.update(height)
    saved = first.state()
    edited = _config(tmp_path, "beg = { prior_mean = 0.6, size = 10, prior_weight = 0.5 }")
    dog = Session(load_installation(edited), SimulatedClock(), EventLog(tmp_path / "b.jsonl"), MemorySink()).creatures[0]
    dog.restore(saved)
    model = dog.beg_height
    assert (model.prior_mean, model.prior_weight, model.size) == (0.6, 0.5, 10)
    assert {0.9, 0.95, 1.0} <= set(model.buffer.tolist())  # the clicked begs came back


def _cues(count: int, rng: np.random.Generator) -> tuple[np.ndarray, list[float]]:
    """A recording of one cue (a 220 Hz tone of 0.4 s, the same each time) every 6 s from 3 s,
    over a quiet noise floor; and when each cue ends."""
    t = np.arange(int(0.4 * SR)) / SR
    tone = (0.5 * np.sin(2 * np.pi * 220 * t) * np.hanning(len(t))).astype(np.float32)
    audio = rng.normal(0.0, 0.002, int((3 + 6 * count + 4) * SR)).astype(np.float32)
    ends = []
    for k in range(count):
        start = int((3.0 + 6 * k) * SR)
        audio[start:start + len(tone)] += tone
        ends.append((start + len(tone)) / SR)
    return audio, ends


def _session(tmp_path: Path, cues: int, seed: int, *, state: dict | None = None, clicks: bool = True):
    """The offline loop on the shipped dog hearing ``cues`` cues; with ``clicks`` a trainer
    clicks (OSC /click, on the next tick) a sit held within 2 s of a cue's end, without them
    learning is frozen. Returns the dog, its ``trick`` events and the clicks given."""
    inst = load_installation(SHIPPED)
    clock = SimulatedClock()
    log = EventLog(keep_in_memory=10**6)
    session = Session(inst, clock, log, MemorySink())
    dog = session.creatures[0]
    if state is not None:
        dog.restore(state)
    if not clicks:
        dog.group.alpha = 0.0
    audio, ends = _cues(cues, np.random.default_rng(seed))
    tick, due, clicked = inst.settings.tick, [], set()
    for step in range(1, int(len(audio) / SR / tick)):
        t = step * tick
        clock.advance_to(t)
        while due and due[0] <= t:
            session.inputs.osc("/click", (), due.pop(0), "osc")
        a, b = int(round((step - 1) * tick * SR)), int(round(t * SR))
        session.step(t, b - a, audio[a:b], audio=False)
        doing = dog.doing
        for k, end in enumerate(ends):
            if clicks and k not in clicked and end <= t <= end + 2.0 and doing is not None \
                    and doing.name == "sit" and doing.held_from is not None:
                clicked.add(k)
                due.append(round(t + tick, 6))
    session.close()
    tricks = [r for r in log.records if r.get("kind") == "trick" and r["trick"] != dog.spec.rest]
    answers = [next((r["tuple"] for r in tricks if end <= r["t"] <= end + 1.0), None) for end in ends]
    return dog, answers, len(clicked)


def test_a_restored_dog_keeps_its_cues_and_does_the_trained_trick_on_one(tmp_path):
    """A cue's tuples ("heard/1 | sit") exist only while its sound class does. Its classes
    were not saved, so the restored dog dropped every learnt cue value (only the fixed
    "whatever" and "quiet" tuples came back): trained to sit on a tone (12 clicks in 20 cues,
    "heard/1 | sit" 4.04), after a restore it answered the tone with any trick, as a fresh dog
    does (2 sits in 10 cues, learning frozen); with its classes kept, 10 sits in 10."""
    trained, _, clicks = _session(tmp_path, 20, 1)
    assert clicks >= 8
    saved = json.loads(json.dumps(trained.state()))
    learnt = {name: v for name, v in trained.group.value_state().items() if name.startswith("heard/")}
    assert learnt["heard/1|sit"]["value"] > 3.0

    fresh = Session(load_installation(SHIPPED), SimulatedClock(), EventLog(tmp_path / "e.jsonl"),
                    MemorySink()).creatures[0]
    fresh.restore(saved)
    assert [(c.name, len(c.members), c.radius) for c in fresh.heard.utterance_children()] == \
        [(c.name, len(c.members), fresh.spec.sharpness) for c in trained.heard.utterance_children()]
    assert {name: v for name, v in fresh.group.value_state().items() if name.startswith("heard/")} == learnt

    dog, answers, _ = _session(tmp_path, 10, 2, state=saved, clicks=False)
    assert [c.name for c in dog.heard.utterance_children()] == ["heard/1"]  # the tone is the cue it knew
    assert answers.count("heard/1|sit") >= 7, answers


def test_a_running_dog_of_the_default_tricks_can_drop_one_as_a_fresh_config_can():
    """The defaults' offers and notes, filtered to the dog's tricks, were marked written, so a
    live change of its tricks (the console, a zone: spec_keys.with_key) took the defaults'
    "roll over" pitch as the author's and refused to drop that trick (a review)."""
    from creatures.kinds.duncan import DuncanSpec
    from creatures.kinds.spec_keys import with_key

    dog = DuncanSpec(name="d", kind="duncan", body={"figure": "dog"})
    assert "notes" not in dog.model_fields_set and "offers" not in dog.model_fields_set
    fewer = with_key(dog, "tricks", ["sit", "beg", "lie down"], "d")
    assert "roll over" not in fewer.notes and "roll over" not in fewer.offers
