"""Duncan's tricks on a motor graph with no way to a trick's pose (an edited body, a body from
files whose "lie down" clip no edge reaches): the trick is refused and logged, and the dog goes on.
``Trick.start`` called the path finder directly, so its ``NoPath`` ended the creature's tick."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from creatures.clock import SimulatedClock
from creatures.events import EventLog
from creatures.runtime.schema import load_installation
from creatures.runtime.session import Session
from midi.sinks import MemorySink

SHIPPED = Path(__file__).resolve().parents[1] / "installations" / "duncan.toml"
SR = 22050


@pytest.fixture
def cut_off():
    """The shipped dog, its "lie down" poses an island no edge from the rest of its graph enters."""
    inst = load_installation(SHIPPED)
    clock = SimulatedClock()
    log = EventLog(keep_in_memory=10**6)
    session = Session(inst, clock, log, MemorySink())
    dog = session.creatures[0]
    graph = dog.body.own_graph()
    island = set(graph.poses.labelled("lie down").tolist())
    for a, b in list(graph.edges()):
        if b in island and a not in island:
            graph.forbid(a, b)
    assert dog.body.motor.position(0.0).node not in island  # the seed's body starts outside it (on a sit)
    return session, clock, log, dog


def test_a_trick_whose_pose_no_path_reaches_is_refused_and_logged(cut_off):
    session, clock, log, dog = cut_off
    down = next(tp for tp in dog.group.tuples if tp.name == "quiet|lie down")
    clock.advance_to(0.05)
    down.action.start(0.05, down)  # raised NoPath ("none of … goal node(s) is reachable")

    refused = [e for e in log.records if e["kind"] == "trick refused"]
    assert [(e["creature"], e["trick"], e["tuple"]) for e in refused] == [("duncan", "lie down", "quiet|lie down")]
    assert not any(e["kind"] == "trick" for e in log.records)  # no trick under way to click
    assert dog.doing is None
    for t in np.arange(0.1, 3.0, 0.05):  # the body stays on its sit: it never holds the refused trick
        clock.advance_to(float(t))
        down.action.update(float(t))
        assert down.action.done(float(t)) == 0.0
    assert not any(e["kind"] == "trick held" for e in log.records)


def test_the_dog_goes_on_choosing_after_a_refused_trick(cut_off):
    """Through its own selections for two simulated minutes: every lie down it chose is refused,
    and the other tricks it offers are still done."""
    session, clock, log, dog = cut_off
    tick = session.inst.settings.tick
    frames = round(tick * SR)
    silence = np.zeros(frames, np.float32)
    for step in range(1, round(120.0 / tick)):
        t = step * tick
        clock.advance_to(t)
        session.step(t, frames, silence, audio=False)
    session.close()
    started = [e["trick"] for e in log.records if e["kind"] == "trick"]
    refused = [e["trick"] for e in log.records if e["kind"] == "trick refused"]
    held = {e["trick"] for e in log.records if e["kind"] == "trick held"}
    assert refused and set(refused) == {"lie down"} and "lie down" not in started
    assert held >= {"sit", "beg"}
