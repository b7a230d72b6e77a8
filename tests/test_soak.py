"""A reduced soak (5 simulated minutes of the 3-creature exchange colony and a listen creature,
at the schema's coarsest tick, 0.5 s, with a visitor playing all along): nothing that could grow
for weeks grows — containers stay bounded, the learner's models are pruned, memory is flat after
warm-up, the events log rotates and every note is closed. ``python -m bench soak`` runs hours.

Five minutes is not long enough for the shipped bounds to fill (the listen population's 6 × 96
states reach some 200 by then, and memory still grows with them, rightly), so the soak gives its
learner and the motor arrivals small bounds that fill within the first half and measures growth
over the second: a leak shows there, bounded learning does not. The absolute measures (blocks and
traced bytes gained) do not depend on what the process held before, which a relative one did: the
same run passed beside other tests and failed alone."""

from __future__ import annotations

import json

import numpy as np
import pydantic
import pytest

from bench.soak import colony, soak, visits
from creatures.motor.programs import MotorSystem


def test_five_minutes_of_exchange_with_a_listener_stay_bounded(tmp_path, monkeypatch):
    # A small cap shows the arrival log (the leak this soak found) filling up and stopping.
    monkeypatch.setattr(MotorSystem, "ARRIVALS_KEPT", 8)
    result = soak(tmp_path, seconds=300.0, tick=0.5, visit_every=60.0, log_bytes=32 * 1024, samples=20,
                  trace=True, bounds=(2, 8), warm=0.5)

    assert result.creatures == 4 and result.tick == 0.5
    assert result.notes_heard == 5 * 21  # five visits of the three fragments, note by note
    assert result.notes_played > 200  # the colony was busy all along, not idle
    last = result.samples[-1].queues
    assert last["motor arrivals"] == 4 * 8  # full, and no further
    assert result.max_queues["motor arrivals"] == 4 * 8
    assert result.max_queues["note spaces"] <= 3 * 48  # exchange's max_notes per creature
    for name in ("world pending", "scheduler heap", "placed/struck tables", "listen heard, undanced"):
        assert result.max_queues[name] < 200, (name, result.max_queues)
    assert last["log in memory"] == 0  # the file log keeps nothing in memory

    # The learner grew models by fission and was pruned back to its bounds.
    assert result.tally["model spawn"] > 6
    assert result.tally["model retire"] + result.tally["model distil"] > 0
    assert result.max_queues["listen models"] <= 2  # max_models: maintenance follows every lesson
    assert result.state_bound == 2 * 8  # max_models × max_states
    assert result.max_queues["listen model states"] == result.state_bound  # filled, distilled, never passed

    # The measure: the process's memory grows < 5 % after warm-up; over the second half
    # (measured: some 600 blocks and 50 kB of the colony's 4.7 MB traced, from full bounds).
    assert result.growth("rss") < 0.05, [s.rss for s in result.samples]
    before, after = result.medians("blocks")
    assert after - before < 4000, [s.blocks for s in result.samples]
    before, after = result.medians("traced")  # tracemalloc sees only the colony
    assert 0 < before and after - before < 256 * 1024, [s.traced for s in result.samples]

    # Rotation: the live file plus two backups, each near the bound, all valid JSONL.
    names = sorted(p.name for p in result.log_files)
    assert names == ["events.jsonl", "events.jsonl.1", "events.jsonl.2"], names
    assert max(result.log_bytes) < 32 * 1024 + 4096
    assert result.events * 100 > sum(result.log_bytes)  # most of the log was rotated away
    for path in result.log_files:
        for line in path.read_text().splitlines():
            json.loads(line)

    assert result.sink.counts["note_on"] == result.sink.counts["note_off"] > 0
    assert result.sink.hanging == 0 and result.sink.out_of_order == 0


def test_the_soak_runs_only_at_a_tick_a_config_accepts():
    with pytest.raises(pydantic.ValidationError, match="tick"):
        colony("exchange", 20.0, learner=False)
    assert colony("exchange", 0.5, learner=True).settings.tick == 0.5


def test_visits_come_in_time_order_and_must_not_overlap():
    notes = visits(40.0, np.random.default_rng(0))
    times = [next(notes).time for _ in range(3 * 21)]
    assert times == sorted(times) and times[21] == pytest.approx(41.0) and times[42] == pytest.approx(81.0)
    with pytest.raises(ValueError, match="shorter than the fragments"):
        next(visits(20.0, np.random.default_rng(0)))
