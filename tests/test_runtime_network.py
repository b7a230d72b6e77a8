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


def test_another_colony_with_a_creature_of_our_name_is_said_and_counted_not_silent(tmp_path):
    """Two machines running one config: each colony's "ada" took the other's every message
    for its own voice sent back and dropped it, counted nowhere, so neither heard the other
    and nothing said why. Now a message under our name from another colony's socket is
    counted (``name clash``) and said once; our own voice sent back (a peer list naming this
    colony) is counted apart (``own voice``), and neither is counted as taken."""
    port_a, port_b = free_port(), free_port()
    a, net_a = colony(tmp_path, "ada", port_a, [port_b])
    config = tmp_path / "b.toml"
    config.write_text('title = "b"\n[[creature]]\nname = "ada"\nkind = "exchange"\n')
    clock = SimulatedClock()
    b = Session(load_installation(config), clock, EventLog(), MemorySink())
    said: list[str] = []
    net_b = Network(OscSection(port=port_b, peers=[f"127.0.0.1:{port_a}", f"127.0.0.1:{port_b}"]),
                    b.world, clock, say=said.append)
    try:
        net_a.publish(0.0)
        a.world.play(a.creatures[0], NoteEvent(0.0, 67, 80, 0, 0.5))
        net_b.publish(0.0)  # to itself too: its own voice comes back
        deadline = time.monotonic() + 5.0
        while net_b.name_clash < 3 or net_b.own_voice < 2:  # a's hello, state and note; b's hello and state
            assert time.monotonic() < deadline, f"heard {net_b.counts()}"
            net_b.wait(0.05)
            net_b.poll(0.0)
        net_a.publish(0.5)
        while net_b.name_clash < 5:
            assert time.monotonic() < deadline, f"heard {net_b.counts()}"
            net_b.wait(0.05)
            net_b.poll(0.5)
    finally:
        net_a.close()
        net_b.close()
    assert not any(e["kind"] == "heard" for e in b.log.records) and "ada" not in b.world.peers
    (clash,) = [e for e in b.log.records if e["kind"] == "peer name clash"]  # said once, counted each time
    assert clash["creature"] == "ada" and clash["address"].startswith("127.0.0.1:")
    assert len(said) == 1 and "'ada'" in said[0] and "another name" in said[0]
    counts = net_b.counts()
    assert counts["dropped"]["name clash"] == net_b.name_clash and counts["dropped"]["own voice"] == net_b.own_voice
    assert counts["received"] == net_b.listener.received - net_b.name_clash - net_b.own_voice
