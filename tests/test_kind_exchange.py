"""exchange: notes fed to one creature appear, transformed, in another creature's output —
for the Exchange class and for the same colony written as authored creatures
(installations/authored/exchange.toml)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import installations
from creatures.events import read_events
from creatures.kinds.parts import shared_graph
from creatures.runtime.offline import run_offline
from creatures.runtime.schema import load_installation
from midi.files import write_notes
from midi.notes import NoteEvent

PHRASE = [60, 62, 64, 67, 69, 72, 74, 76]

CONFIGS = {"class": installations.path("exchange"),
           "authored": Path(installations.__file__).parent / "authored" / "exchange.toml"}


def variations(original: list[int], played: list[int]) -> set[str]:
    """Which transformations of ``original`` show in ``played``: transposition (a pitch a
    fourth, fifth or octave from one heard, not itself heard), retrograde (some descending
    step of the phrase's ascending pairs) or reordering (a heard pitch order not in order)."""
    found = set()
    heard = set(original)
    if any(p not in heard and any(abs(p - q) in (5, 7, 12) for q in heard) for p in played):
        found.add("transposition")
    rank = {p: i for i, p in enumerate(original)}
    ranks = [rank[p] for p in played if p in rank]
    steps = np.diff(ranks)
    if (steps == -1).any():
        found.add("retrograde")
    if (steps < 0).any() or (steps > 1).any():
        found.add("reordering")
    return found


def test_variations_detector():
    assert variations(PHRASE, PHRASE) == set()
    assert "retrograde" in variations(PHRASE, PHRASE[::-1])
    assert variations(PHRASE, [60, 67]) == {"reordering"}
    assert variations(PHRASE, [65]) == {"transposition"}


@pytest.mark.parametrize("config", CONFIGS)
def test_notes_fed_to_one_creature_reach_another_transformed(tmp_path: Path, config: str):
    inst = load_installation(CONFIGS[config])
    inst.settings.output.wav = inst.settings.output.report = False
    phrase = tmp_path / "phrase.mid"
    write_notes(phrase, [NoteEvent(1.0 + 0.3 * i + 6.0 * r, p, 96, 0, 0.25)
                         for r in range(3) for i, p in enumerate(PHRASE)])
    run_offline(inst, tmp_path / "out", midi=phrase, duration=45)
    events = read_events(tmp_path / "out" / "events.jsonl")
    placed = {}
    for e in events:
        if e["kind"] == "placed":
            placed.setdefault(e["creature"], []).append(e["source"])
    # Only the first creature hears the input; the others hear only the colony.
    assert set(placed["ada"]) >= {"input"}
    assert "input" not in set(placed.get("bo", [])) | set(placed.get("cy", []))
    others = [e["pitch"] for e in events if e["kind"] == "note" and e["creature"] in ("bo", "cy")]
    shared = set(others) & set(PHRASE)
    assert len(shared) >= 3, f"too little of the phrase reached the others: {sorted(set(others))}"
    assert variations(PHRASE, others), "passages passed on unchanged"


@pytest.mark.parametrize("config", CONFIGS)
def test_ratio_metric_gives_a_body_on_the_exchange_graph(config: str):
    plain, ratios = shared_graph(False), shared_graph(True)
    assert not plain.weights.ratios and ratios.weights.ratios
    assert plain.edges() != ratios.edges()  # the perturbed time metric reshapes the topology
    inst = load_installation(CONFIGS[config])
    cy = next(spec for spec in inst.specs if spec.name == "cy")
    assert cy.ratio_metric
