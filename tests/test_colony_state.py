"""The colony's heard pulse is saved with the creatures and restored on restart, like any
learned state; a damaged colony file is named, and a state directory without one still loads."""

from __future__ import annotations

import json

import numpy as np
import pytest

import installations
from creatures.clock import SimulatedClock
from creatures.events import EventLog
from creatures.persist import StateFileError
from creatures.runtime.schema import load_installation
from creatures.runtime.session import COLONY_FILE, Session
from midi.notes import NoteEvent
from midi.sinks import MemorySink

TICK = 0.04


def _session(seconds: float, *, rhythm: float | None = None) -> Session:
    inst = load_installation(installations.path("exchange"))
    clock = SimulatedClock()
    session = Session(inst, clock, EventLog(), MemorySink())
    if rhythm is not None:  # beats of 1, 1, 1, 2 times ``rhythm``
        onsets = 0.5 + rhythm * np.cumsum(np.tile([1, 1, 1, 2], int(seconds / rhythm)))
        for i, onset in enumerate(onsets[onsets < seconds]):
            session.world.inject(NoteEvent(round(float(onset), 6), 60 + i % 5, 90, 0, 0.2))
    for step in range(1, int(round(seconds / TICK)) + 1):
        clock.advance_to(step * TICK)
        session.step(step * TICK, 0, None, audio=False)
    return session


def test_the_heard_pulse_survives_a_restart(tmp_path):
    heard = _session(12.0, rhythm=0.25)
    assert heard.world.pulse.ready and heard.world.pulse.model.pulse == pytest.approx(0.25, rel=0.05)
    heard.save_state(tmp_path)
    fresh = _session(0.04)
    assert not fresh.world.pulse.ready
    assert fresh.load_state(tmp_path) == ["ada", "bo", "cy"]
    assert fresh.world.pulse.heard == heard.world.pulse.heard
    assert fresh.world.pulse.model.to_dict() == heard.world.pulse.model.to_dict()
    assert fresh.world.pulse.ready  # ada's rests fall on the pulse at once, not after eight more notes


def test_state_without_a_colony_file_still_loads(tmp_path):
    _session(1.0, rhythm=0.25).save_state(tmp_path)
    (tmp_path / COLONY_FILE).unlink()
    fresh = _session(0.04)
    assert fresh.load_state(tmp_path) == ["ada", "bo", "cy"]
    assert fresh.world.pulse.heard == 0


@pytest.mark.parametrize("damage", ["heard", "pulse", "ratio"])
def test_a_damaged_colony_file_is_named(damage, tmp_path):
    _session(4.0, rhythm=0.25).save_state(tmp_path)
    path = tmp_path / COLONY_FILE
    document = json.loads(path.read_text())
    if damage == "heard":
        document["heard"] = -3
    elif damage == "pulse":
        del document["pulse"]
    else:
        document["pulse"]["ratios"][0][1] = 0  # a ratio n/0
    path.write_text(json.dumps(document))
    with pytest.raises(StateFileError, match=f"{COLONY_FILE}: malformed colony state"):
        _session(0.04).load_state(tmp_path)
