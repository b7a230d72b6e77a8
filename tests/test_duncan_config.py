"""Duncan's config (creatures/kinds/duncan.py): what an installation may set and what it is
refused, with file, key and line."""

from __future__ import annotations

from pathlib import Path

import pytest

from creatures.clock import SimulatedClock
from creatures.config import ConfigError
from creatures.events import EventLog
from creatures.runtime.schema import load_installation
from creatures.runtime.session import Session
from midi.sinks import MemorySink

SHIPPED = Path(__file__).resolve().parents[1] / "installations" / "duncan.toml"


def _config(tmp_path: Path, keys: str) -> Path:
    config = tmp_path / "duncan.toml"
    config.write_text(SHIPPED.read_text().replace('kind = "duncan"\n', f'kind = "duncan"\n{keys}\n'))
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
