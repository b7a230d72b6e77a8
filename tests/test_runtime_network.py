"""A colony on the network: each creature speaks notes and state under its own name at a
bounded rate; what other colonies say is heard, kept for the creatures and logged."""

from __future__ import annotations

import socket
import time
from typing import Callable

import pytest

from creatures.clock import SimulatedClock
from creatures.events import EventLog
from creatures.runtime.network import STATE_EVERY, Network
from creatures.runtime.schema import OscSection, load_installation
from creatures.runtime.session import Session
from midi.notes import NoteEvent
from midi.osc import Heard, OscListener
from midi.sinks import MemorySink


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def colony(tmp_path, name: str, port: int, peers: list[int]) -> tuple[Session, Network]:
    config = tmp_path / f"{name}.toml"
    config.write_text(f'title = "{name}"\n[[creature]]\nname = "{name}"\nkind = "exchange"\n')
    clock = SimulatedClock()
    session = Session(load_installation(config), clock, EventLog(), MemorySink())
    osc = OscSection(port=port, peers=[f"127.0.0.1:{p}" for p in peers])
    return session, Network(osc, session.world, clock, say=print)


def gather(listener: OscListener, enough: Callable[[list[Heard]], bool], timeout: float = 5.0) -> list[Heard]:
    heard: list[Heard] = []
    deadline = time.monotonic() + timeout
    while not enough(heard) and time.monotonic() < deadline:
        listener.wait(0.05)
        heard += listener.poll()
    return heard


def test_each_creature_speaks_under_its_own_name_at_a_bounded_rate(tmp_path):
    ear = OscListener(SimulatedClock())
    session, network = colony(tmp_path, "ada", free_port(), [ear.port])
    try:
        for step in range(51):  # a tick every 20 ms for one second
            network.publish(step * 0.02)
        ada = session.creatures[0]
        session.world.play(ada, NoteEvent(1.0, 64, 90, 0, 0.25))
        heard = gather(ear, lambda h: any(x.kind == "note" for x in h))
    finally:
        network.close()
        ear.close()
    assert {h.creature for h in heard} == {"ada"}
    hellos = [h for h in heard if h.kind == "hello"]
    assert len(hellos) == 3 == 1 + int(1.0 / STATE_EVERY)  # at 0, 0.5 and 1 s: 2 Hz, not every tick
    assert {h.args for h in hellos} == {(network.listener.port,)}
    state = {h.args[0]: h.args[1] for h in heard if h.kind == "state"}
    assert set(state) == {"boredom", "hunger", "action"}
    assert state["boredom"] == pytest.approx(ada.motivation.level("boredom", 1.0), abs=1e-3)
    assert [(h.note.pitch, h.note.velocity) for h in heard if h.kind == "note"] == [(64, 90)]


def test_what_another_colony_says_is_heard_kept_for_the_creatures_and_logged(tmp_path):
    port_a, port_b = free_port(), free_port()
    a, net_a = colony(tmp_path, "ada", port_a, [port_b])
    b, net_b = colony(tmp_path, "bo", port_b, [port_a])
    try:
        net_a.publish(0.0)
        a.world.play(a.creatures[0], NoteEvent(0.0, 67, 80, 0, 0.5))
        deadline = time.monotonic() + 5.0
        while "action" not in b.world.peers.get("ada", {}) or not any(e["kind"] == "heard" for e in b.log.records):
            assert time.monotonic() < deadline, "no state or note from ada"
            net_b.wait(0.05)
            net_b.poll(0.0)
            b.world.deliver(0.0)
    finally:
        net_a.close()
    bored = a.creatures[0].motivation.level("boredom")
    assert b.world.peers["ada"]["boredom"] == pytest.approx(bored, abs=1e-3)  # a remote creature's boredom
    assert b.world.peers["ada"]["action"] == "none"  # it has not ticked yet
    kinds = [e["kind"] for e in b.log.records]
    assert "peer" in kinds and "peer state" in kinds
    (heard,) = [e for e in b.log.records if e["kind"] == "heard"]
    assert (heard["source"], heard["pitch"]) == ("ada", 67)
    assert [e["source"] for e in b.log.records if e["kind"] == "placed"] == ["ada"]  # bo heard it
    # ada's colony closed: its bye makes bo's colony forget ada.
    deadline = time.monotonic() + 5.0
    while "ada" in b.world.peers:
        assert time.monotonic() < deadline, "no bye from ada"
        net_b.wait(0.05)
        net_b.poll(0.0)
    net_b.close()
    assert [e for e in b.log.records if e["kind"] == "peer left"][0]["creature"] == "ada"
