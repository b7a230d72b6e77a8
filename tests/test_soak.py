"""A reduced soak (10 simulated minutes of the 3-creature exchange colony at a 1 s tick):
nothing that could grow for weeks grows — queues stay bounded, memory is flat after warm-up,
the events log rotates and every note is closed. ``python -m bench soak`` runs 24 hours."""

from __future__ import annotations

import json

from bench.soak import soak
from creatures.motor.programs import MotorSystem


def test_ten_minutes_of_exchange_stay_bounded(tmp_path, monkeypatch):
    # A small cap shows the arrival log (the leak this soak found) filling up and stopping.
    monkeypatch.setattr(MotorSystem, "ARRIVALS_KEPT", 8)
    result = soak(tmp_path, seconds=600.0, tick=1.0, visit_every=120.0, log_bytes=64 * 1024, samples=20)

    assert result.notes_played > 50  # the colony was busy all along, not idle
    last = result.samples[-1].queues
    assert last["motor arrivals"] == 3 * 8  # full, and no further
    assert result.max_queues["motor arrivals"] == 3 * 8
    assert result.max_queues["note spaces"] <= 3 * 48  # exchange's max_notes per creature
    for name in ("world pending", "scheduler heap", "placed/struck tables"):
        assert result.max_queues[name] < 200, (name, result.max_queues)
    assert last["log in memory"] == 0  # the file log keeps nothing in memory

    assert result.growth("traced") < 0.05, [s.traced for s in result.samples]
    assert result.growth("rss") < 0.05, [s.rss for s in result.samples]

    # Rotation: the live file plus two backups, each near the bound, all valid JSONL.
    names = sorted(p.name for p in result.log_files)
    assert names == ["events.jsonl", "events.jsonl.1", "events.jsonl.2"], names
    assert max(result.log_bytes) < 64 * 1024 + 4096
    for path in result.log_files:
        for line in path.read_text().splitlines():
            json.loads(line)

    assert result.sink.counts["note_on"] == result.sink.counts["note_off"] > 0
    assert result.sink.hanging == 0 and result.sink.out_of_order == 0
