"""A crowd's creatures ticked together (``Authored.tick_many``: their drives advanced as one
array, their selection's triggers, expected values and work as arrays across them) do
exactly what ticking them one by one does: the same events in the same order, the same
notes, the same learnt state, bit for bit."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from creatures.authored.creature import Authored
from creatures.clock import SimulatedClock
from creatures.events import EventLog
from creatures.kinds.base import CreatureKind
from creatures.runtime.schema import load_installation
from creatures.runtime.session import Session
from midi.notes import NoteEvent
from midi.sinks import MemorySink

CROWD = """
title = "crowd"
seed = 8
tick = 0.04
[output]
report = false
[room]
width = 12.0
depth = 12.0
listener = [6.0, 6.0]
hearing = {{ law = "inverse", reference = 0.5, threshold = -30.0, loud = 100 }}
{lod}

[[creature]]
name = "s"
count = 14
kind = "authored"
drive_ceiling = 1.0
[creature.vary]
"drives.boredom.level" = [0.0, 0.4]
"drives.boredom.growth" = [0.05, 0.2]
"tuples.call.action.transpose" = [-5, 5]
[creature.vehicle]
steer = [{{ behaviour = "wall_avoidance", weight = 3.0 }}, {{ behaviour = "separation", weight = 2.0 }},
         {{ behaviour = "wander", weight = 1.0 }}]
[creature.drives.boredom]
level = 0.2
growth = 0.1
on_heard = -0.05
coupling = {{ eager = 0.02 }}
[creature.drives.eager]
level = 1.0
growth = 0.06
decay = 0.1
on_played = -0.3
[creature.percepts.heard]
type = "heard"
window = 0.5
[creature.percepts.bored]
type = "drive"
drive = "boredom"
scale = "level"
[creature.percepts.eager]
type = "drive"
drive = "eager"
[creature.percepts.keen]
type = "and"
of = ["heard", "eager"]
logic = "product"
[creature.percepts.crowded]
type = "crowding"
radius = 2.0
full = 3
[creature.percepts.calm]
type = "not"
of = "crowded"
[creature.tuples.echo]
trigger = "keen"
action = {{ type = "echo", count = 3, mutation = 0.3, steps = [-2, 2], jitter = 0.02, velocity = 90 }}
until = {{ done = true, seconds = 3.0 }}
value = 2.0
[creature.tuples.call]
trigger = "bored"
action = {{ type = "play_phrase", pitches = [60, 64, 67], durations = 0.2, velocity = 110 }}
until = {{ done = true, seconds = 2.0 }}
value = {{ value = 1.0, plastic = false }}
[creature.tuples.listen]
trigger = "calm"
action = "rest"
until = {{ gaussian = [1.0, 0.4], graded = true }}
value = 0.6
[creature.groups.song]
tuples = ["echo", "call", "listen"]
alpha = 0.2
discount = 0.9
multiple = 1.2
temperature = 0.5

[[creature]]
name = "odd"
kind = "authored"
[creature.drives.boredom]
level = 0.5
growth = 0.1
[creature.percepts.their]
type = "sensed"
creature = "s-3"
percept = "bored"
[creature.tuples.call]
trigger = "their"
action = {{ type = "play_note", pitch = 72, velocity = 100, duration = 0.3 }}
until = {{ done = true, seconds = 1.0 }}
value = 1.0
[creature.tuples.listen]
action = "rest"
until = {{ seconds = 0.7 }}
value = 0.5
[creature.groups.song]
tuples = ["call", "listen"]
alpha = 0.0

[[creature]]
name = "slow"
count = 6
kind = "authored"
soft_rate = 6.0
[creature.drives.boredom]
level = 0.3
growth = 0.08
on_played = -0.5
[creature.percepts.bored]
type = "drive"
drive = "boredom"
[creature.percepts.onset]
type = "onset"
[creature.tuples.call]
trigger = "bored"
action = {{ type = "play_note", pitch = 55, velocity = 70, duration = 0.4 }}
until = {{ done = true, seconds = 1.0 }}
value = 1.0
[creature.tuples.start]
trigger = "onset"
action = "rest"
until = {{ percept = "onset", fresh = true, seconds = 0.8 }}
value = 0.7
[creature.tuples.listen]
action = "rest"
until = {{ gaussian = [1.2, 0.3] }}
value = 0.4
[creature.groups.song]
tuples = ["call", "start", "listen"]
alpha = 0.0
"""


def run(tmp_path: Path, together: bool, monkeypatch: pytest.MonkeyPatch, *, lod: str = "",
        seconds: float = 12.0) -> tuple[bytes, str, list]:
    """Events, every creature's state and the notes sent, after ``seconds`` of the crowd with
    a visitor's notes from outside; ``together`` false ticks each creature alone."""
    folder = tmp_path / ("together" if together else "alone")
    folder.mkdir(parents=True)
    path = folder / "crowd.toml"
    path.write_text(CROWD.format(lod=lod))
    if not together:
        monkeypatch.setattr(Authored, "tick_many", classmethod(CreatureKind.tick_many.__func__))
    clock = SimulatedClock()
    log = EventLog(folder / "events.jsonl")
    sink = MemorySink()
    session = Session(load_installation(path), clock, log, sink)
    for k in range(int(round(seconds / 0.04))):
        t = clock.advance(0.04)
        if k % 40 == 7:
            session.world.inject(NoteEvent(round(t, 6), 62 + k % 5, 100, 0, 0.3))
        session.step(t, 0, None, audio=False)
    log.close()
    monkeypatch.undo()
    states = json.dumps([c.state() for c in session.creatures], sort_keys=True, default=str)
    return (folder / "events.jsonl").read_bytes(), states, list(sink.messages)


@pytest.mark.parametrize("lod", ["", "lod = { near = 3.0, levels = 2, decide_budget = 12 }"])
def test_a_crowd_ticked_together_does_what_it_does_one_by_one(tmp_path, monkeypatch, lod):
    together = run(tmp_path / "a", True, monkeypatch, lod=lod)
    alone = run(tmp_path / "b", False, monkeypatch, lod=lod)
    events = together[0].decode().splitlines()
    kinds = {json.loads(line)["kind"] for line in events}
    assert {"selection", "note", "credit", "stop"} <= kinds  # the crowd chose, sang and learnt
    assert sum('"interruption"' in line for line in events) > 0  # and changed its mind
    assert together[0] == alone[0]
    assert together[1] == alone[1]
    assert together[2] == alone[2]


def test_only_creatures_whose_percepts_read_their_own_state_tick_together(tmp_path):
    path = tmp_path / "crowd.toml"
    path.write_text(CROWD.format(lod=""))
    session = Session(load_installation(path), SimulatedClock(), EventLog(keep_in_memory=0), MemorySink())
    shares = {c.name: c._shares for c in session.creatures}
    assert shares["s-0"] and shares["slow-0"]
    assert not shares["odd"]  # it reads another creature's percept
