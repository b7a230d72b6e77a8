"""A shared room's parts in one process (issue 21, "one room across machines"): the wire and its
refusals, two shares on loopback with configured peers (no multicast), remote creatures as
neighbours, percepts and sound sources on a stage, and places that survive a restart. The
four-process run with mDNS and Link is tests/test_room_across_processes.py."""

from __future__ import annotations

import select
import socket
import textwrap

import numpy as np
import pytest
from pythonosc.osc_message_builder import OscMessageBuilder
from pythonosc.udp_client import SimpleUDPClient

from creatures.clock import SimulatedClock
from creatures.config import ConfigError
from creatures.events import EventLog
from creatures.persist import StateFileError
from creatures.room.share import RoomShare
from creatures.room.spec import ShareSpec
from creatures.runtime.offline import run_offline
from creatures.runtime.schema import load_installation
from creatures.runtime.session import Session
from creatures.runtime.shared_room import open_shared_room
from midi.notes import NoteEvent
from midi.sinks import MemorySink

EPOCH = 1_800_000_000.0
ROW = [2.0, 3.0, 0.5, 0.0, 1.0, 0.0, 0.25]  # at (2, 3), moving +x at 0.5 m/s, facing +x


def shares(*own: list[str], room: str = "gallery") -> list[RoomShare]:
    """Shares on loopback that know each other's ports (the port each got is only known once
    bound, so the peers are set after)."""
    made = [RoomShare(ShareSpec(room=room, discover=False), names, EPOCH) for names in own]
    for i, s in enumerate(made):
        s.owner += f"-{i}"  # one process here plays several: each its own owner
        s.configured = {("127.0.0.1", o.port) for o in made if o is not s}
    return made


def wait_for(share: RoomShare, t: float) -> list:
    """Poll until a datagram has been taken (loopback delivers in microseconds; the socket is
    waited on, not slept on)."""
    select.select([share.socket], [], [], 2.0)
    return share.poll(t)


def test_bodies_cross_and_are_placed_where_they_stand_now():
    a, b = shares(["a-0", "a-1"], ["b-0"])
    a.publish(1.0, ["a-0", "a-1"], np.array([ROW, [5, 5, 0, 0, 0, 1, 0.3]]))
    wait_for(b, 1.0)
    names, rows = b.others(1.4)  # 0.4 s after the stamp: moved on by its velocity
    assert names == ["a-0", "a-1"]
    assert rows[0, :2] == pytest.approx([2.2, 3.0], abs=1e-6)
    assert rows[1, :2] == pytest.approx([5.0, 5.0]) and rows[1, 6] == pytest.approx(0.3)
    # Asked for an instant before the stamp (the stage asks at its crowd's time, then sub-steps
    # to now), it stands where it was then, not where the stamp has it a tick later.
    assert b.others(0.8)[1][0, :2] == pytest.approx([1.9, 3.0], abs=1e-6)
    assert b.joined == [a.owner] and b.counts()["remote"] == 2
    for s in (a, b):
        s.close()


def test_a_process_leaves_by_bye_by_silence_and_is_taken_over_by_its_restart():
    a, b = shares(["a-0"], ["b-0"])
    a.publish(0.0, ["a-0"], np.array([ROW]))
    wait_for(b, 0.0)
    b.poll(b.spec.timeout + 0.5)  # nothing more from a: its creature leaves with it
    assert b.others(3.0)[0] == [] and b.left == [(a.owner, "silent")]
    a.publish(3.0, ["a-0"], np.array([ROW]))
    wait_for(b, 3.0)
    restarted = RoomShare(ShareSpec(room="gallery", discover=False), ["a-0"], EPOCH)
    restarted.owner += "-again"  # a new process: a new owner, the same creature names
    restarted.configured = {("127.0.0.1", b.port)}
    moved = [9.0, 9.0, 0.0, 0.0, 1.0, 0.0, 0.25]
    restarted.publish(3.1, ["a-0"], np.array([moved]))
    wait_for(b, 3.1)
    assert b.remote["a-0"].owner == restarted.owner and b.others(3.1)[1][0, :2] == pytest.approx([9.0, 9.0])
    a.close()  # the old owner's bye takes nothing: a-0 is the new owner's now
    wait_for(b, 3.2)
    assert b.others(3.2)[0] == ["a-0"]
    restarted.close()
    wait_for(b, 3.3)
    assert b.others(3.3)[0] == [] and (restarted.owner, "bye") in b.left
    b.close()


def test_two_live_processes_claiming_one_creature_are_counted_and_said_not_a_jumping_creature():
    a, twin, b = shares(["a-0"], ["a-0"], ["b-0"])  # one config run twice: both own "a-0"
    here, there = np.array([[1.0, 1.0, 0, 0, 1, 0, 0.25]]), np.array([[9.0, 9.0, 0, 0, 1, 0, 0.25]])
    seen = []
    for step in range(6):
        t = 0.1 * step
        for share, row in ((a, here), (twin, there)):
            share.publish(t, ["a-0"], row)
            wait_for(b, t)
            seen.append(tuple(b.others(t)[1][0, :2]))
    # The twin took it once (as a restart would) and keeps it: the first owner speaking of it
    # again is the clash, dropped and counted, not a creature at (1, 1) and (9, 9) in turn.
    assert seen == [(1.0, 1.0)] + [(9.0, 9.0)] * 11
    assert b.remote["a-0"].owner == twin.owner and b.dropped["owner clash"] == 5
    assert b.clashes == [("a-0", twin.owner, a.owner)]  # said once for the name
    twin.close()  # the holder leaves: the name is the other's again
    wait_for(b, 0.6)
    a.publish(0.7, ["a-0"], here)
    wait_for(b, 0.7)
    assert b.remote["a-0"].owner == a.owner and b.others(0.7)[1][0, :2] == pytest.approx([1.0, 1.0])
    for s in (a, b):
        s.close()


def test_notes_arrive_stamped_with_when_they_started():
    a, b = shares(["a-0"], ["b-0"])
    a.publish(2.5, ["a-0"], np.array([ROW]))  # it stands somewhere before it is heard
    a.played("a-0", NoteEvent(2.5, 64, 90, 0, 0.3))
    a.played("b-0", NoteEvent(2.5, 64, 90, 0, 0.3))  # not a's: never sent
    (heard,) = wait_for(b, 2.6)
    assert heard[0] == "a-0" and heard[1].time == pytest.approx(2.5) and heard[1].pitch == 64
    for s in (a, b):
        s.close()


class Skewed:
    """A Link timeline at 120 BPM as a process sees it whose Unix clock is ``fast`` seconds
    ahead and whose beats count ``ahead`` more (Link shares phase, not beat numbers)."""

    tempo = 120.0

    def __init__(self, fast: float = 0.0, ahead: float = 0.0) -> None:
        self.fast, self.ahead = fast, ahead

    def beat_at(self, unix: float) -> float:
        return (unix - self.fast - EPOCH) * 2.0 + self.ahead


@pytest.mark.parametrize("sender, hearer, heard_at", [
    (Skewed(0.08, 170.0), Skewed(), 2.5),  # both have Link: placed by the beat's phase
    (Skewed(-0.2, 3.0), Skewed(), 2.5),  # a slow clock, nearly half a beat
    (Skewed(0.08, 170.0), None, 2.58),  # the hearer has no Link: by the Unix stamp
    (None, Skewed(), 2.58),  # the sender has none (beat -1): by the Unix stamp
])
def test_a_note_is_placed_by_its_link_beat_when_both_sides_have_link(sender, hearer, heard_at):
    """The sender's Unix clock is 80 ms fast (-200 ms slow in the second case) and its Link
    beats are numbered differently, at the same phase: a note it plays at 2.5 s is heard at
    2.5 s on the hearer's clock when both have Link, at its Unix stamp (2.58 s) otherwise."""
    a, b = shares(["a-0"], ["b-0"])
    a.timeline, b.timeline = sender, hearer
    a.epoch = EPOCH + (0.08 if sender is None else sender.fast)  # its Unix clock, as its timeline's
    a.publish(2.5, ["a-0"], np.array([ROW]))
    a.played("a-0", NoteEvent(2.5, 64, 90, 0, 0.3))
    (heard,) = wait_for(b, 2.6)
    assert heard[1].time == pytest.approx(heard_at, abs=1e-6)
    for s in (a, b):
        s.close()


def test_a_foreign_osc_client_is_heard_and_junk_is_dropped_and_counted():
    """python-osc's client (not our code) speaks the protocol with float32 numbers and at = 0
    ("now"); every datagram that does not fit is dropped and counted by cause."""
    (b,) = shares(["b-0"])
    client = SimpleUDPClient("127.0.0.1", b.port)
    row = np.array([ROW], "<f4").tobytes()
    client.send_message("/room/bodies", ["gallery", "tracker", 1, 0.0, -1.0, "visitor-1", row])
    wait_for(b, 5.0)
    assert b.others(5.0)[1][0, :2] == pytest.approx([2.0, 3.0])  # stamped "now" by the hearer
    junk = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    for data in (b"not osc at all", b"\x00" * 20000):  # not OSC; too large
        junk.sendto(data, ("127.0.0.1", b.port))
    client.send_message("/room/bodies", ["gallery", "t", 1, 0.0, -1.0, "x", b"\x00" * 5])  # rows of 5 bytes
    client.send_message("/room/bodies", ["gallery", "t", 1, 0.0, -1.0, "x,x", row + row])  # a name twice
    client.send_message("/room/bodies", ["gallery", "t", 1, 0.0, -1.0, "x",
                                         np.array([[np.nan, 0, 0, 0, 1, 0, 0.2]], "<f4").tobytes()])
    client.send_message("/room/bodies", ["gallery", "t", 1, 0.0, -1.0, "x",
                                         np.array([[1, 1, 500, 0, 1, 0, 0.2]], "<f4").tobytes()])  # 500 m/s
    client.send_message("/room/bodies", ["gallery", "t", 1, 0.0, -1.0, "b-0", row])  # one of b's own names
    client.send_message("/room/bodies", ["elsewhere", "t", 1, 0.0, -1.0, "x", row])
    client.send_message("/room/bodies", ["gallery", "t", 1, 0.0])  # too few arguments
    client.send_message("/room/note", ["gallery", "t", "x", 60, 0, 0.5, 0.0, -1.0])  # velocity 0
    client.send_message("/elsewhere", [1])
    for _ in range(40):
        wait_for(b, 5.0)
        if sum(b.dropped.values()) >= 11:
            break
    assert dict(b.dropped) == {"not osc": 1, "oversize": 1, "arguments": 5, "name clash": 1, "other room": 1,
                               "type tags": 1, "address": 1}
    assert b.others(5.0)[0] == ["visitor-1"]
    b.close()


def test_positions_stamped_far_from_now_are_dropped_and_counted_not_kept_for_ever():
    """A process whose clock is 100 s off (NTP not running there), its Unix stamps sent as
    doubles by python-osc's client: a stamp 100 s slow once left the room unsaid (placed, then
    timed out in the same poll, nothing counted); one 100 s fast was never timed out, so a
    creature its owner stopped naming stayed in the room for as long as its owner spoke."""
    (b,) = shares(["b-0"])
    client = SimpleUDPClient("127.0.0.1", b.port)

    def bodies(owner: str, at: float, *names: str) -> None:
        builder = OscMessageBuilder("/room/bodies")
        for kind, value in (("s", "gallery"), ("s", owner), ("i", 1), ("d", EPOCH + at), ("d", -1.0),
                            ("s", ",".join(names)), ("b", np.array([ROW] * len(names), "<f4").tobytes())):
            builder.add_arg(value, kind)
        client.send(builder.build())

    bodies("slow", 10.0 - 100.0, "slowpoke")
    wait_for(b, 10.0)
    assert b.others(10.0)[0] == [] and b.dropped["time"] == 1
    bodies("fast", 10.0 + 100.0, "fast-0", "fast-1")
    wait_for(b, 10.0)
    for t in (10.5, 11.0, 13.0, 14.5):  # fast-0 named only in the first
        bodies("fast", t + 100.0, "fast-1")
        wait_for(b, t)
    assert b.others(14.5)[0] == [] and b.dropped["time"] == 6
    bodies("fast", 15.0 + 1.5, "fast-0", "fast-1")  # 1.5 s ahead: within the 2 s timeout, taken
    wait_for(b, 15.0)
    for t in (16.0, 17.0, 18.0, 19.0):
        bodies("fast", t + 1.5, "fast-1")
        wait_for(b, t)
    assert b.others(19.0)[0] == ["fast-1"] and b.dropped["time"] == 6  # fast-0 gone after the timeout
    b.close()


ROOM = """
title = "shared"
seed = 1
tick = 0.02
[output]
report = false
[room]
width = 10.0
depth = 10.0
{share}
[[creature]]
name = "me"
kind = "authored"
[creature.vehicle]
at = [5.0, 5.0]
radius = 0.25
max_speed = 1.0
steer = [{{ behaviour = "separation", weight = 1.0 }}]
neighbours = 4
reach = 2.0
[creature.percepts]
crowded = {{ type = "crowding", radius = 1.0, full = 1 }}
heard = {{ type = "heard", window = 0.5 }}
[creature.tuples.listen]
action = "rest"
until = {{ seconds = 1.0 }}
[creature.groups.main]
tuples = ["listen"]
alpha = 0.0
"""


def session(tmp_path, share: str = "") -> Session:
    path = tmp_path / "shared.toml"
    path.write_text(textwrap.dedent(ROOM.format(share=share)))
    return Session(load_installation(path), SimulatedClock(), EventLog(), MemorySink())


def test_a_remote_creature_is_a_neighbour_a_percept_and_a_sound_source(tmp_path):
    """Beside a remote creature 0.5 m to its right, a creature that only separates moves away
    from it, counts it in its crowd, and hears its note from there, late by the distance."""
    s = session(tmp_path)
    (sender,) = shares(["you"])
    share = RoomShare(ShareSpec(room="gallery", discover=False), ["me"], EPOCH)
    s.stage.attach(share, s.world)
    sender.configured = {("127.0.0.1", share.port)}
    sender.publish(0.0, ["you"], np.array([[5.5, 5.0, 0, 0, 1, 0, 0.25]]))
    sender.played("you", NoteEvent(0.0, 67, 100, 0, 0.5))
    select.select([share.socket], [], [], 2.0)
    t = 0.0
    for _ in range(50):
        t = s.clock.advance(0.02)
        s.step(t, 0, None, audio=False)
    me = s.creatures[0]
    assert s.stage.v.pos[0, 0] < 4.9  # pushed away from the remote creature, to its left
    assert me.percept("crowded").evaluate(t) == 0.0  # moved out of the 1 m radius
    assert s.stage.crowding("me", 2.0) == 1
    heard = me.ear.last(1)
    assert heard and heard[0].pitch == 67 and heard[0].time == pytest.approx(0.5 / 343, abs=1e-5)  # 0.5 m, within the 3 mm it moved
    for x in (sender, share):
        x.close()


def test_places_survive_a_restart_and_a_damaged_one_names_its_file(tmp_path):
    s = session(tmp_path)
    for _ in range(30):
        t = s.clock.advance(0.02)
        s.step(t, 0, None, audio=False)
    s.stage.v.pos[0] = [7.25, 1.5]
    s.save_state(tmp_path / "state")
    again = session(tmp_path)
    assert again.load_state(tmp_path / "state") == ["me"]
    assert again.stage.v.pos[0] == pytest.approx([7.25, 1.5])
    path = tmp_path / "state" / "me.json"
    path.write_text(path.read_text().replace('"at": [\n   7.25', '"at": [\n   "east"'))
    with pytest.raises(StateFileError, match="me.json.*place.at"):
        session(tmp_path).load_state(tmp_path / "state")


def test_share_config_errors_and_an_offline_run_says_it_is_alone(tmp_path):
    path = tmp_path / "shared.toml"
    path.write_text(textwrap.dedent(ROOM.format(share='share = { room = "gallery", peers = ["nowhere"] }')))
    with pytest.raises(ConfigError) as info:
        load_installation(path)
    assert info.value.line == 10 and "host:port" in info.value.message
    busy = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    busy.bind(("127.0.0.1", 0))
    port = busy.getsockname()[1]
    s = session(tmp_path, f'share = {{ room = "gallery", port = {port}, discover = false }}')
    with pytest.raises(ConfigError) as info:
        open_shared_room(s.inst, s, EPOCH, print)
    assert info.value.key == "room.share.port" and "in use" in info.value.message
    busy.close()
    summary = run_offline(s.inst, tmp_path / "out", duration=1.0)
    assert any("[room.share] is for live runs" in m for m in summary.messages)


@pytest.mark.parametrize("share, key, why", [
    ('host = "::1"', "room.share.host", "room share host '::1' is not IPv4"),
    ('host = "no-such-host.invalid"', "room.share.host", "does not resolve"),
    ('peers = ["127.0.0.1:40000", "[::1]:40000"]', "room.share.peers.1", "is IPv6"),
    ('peers = ["no-such-host.invalid:40000"]', "room.share.peers.0", "cannot be resolved"),
    ('peers = ["127.0.0.1:0"]', "room.share.peers.0", "a port in 1..65535"),
    ('peers = ["127.0.0.1:\u00b2"]', "room.share.peers.0", "a port in 1..65535"),
])
def test_a_share_host_or_peer_no_socket_could_use_is_a_config_error_at_load(tmp_path, share, key, why):
    """As [osc]'s host and peers are: an IPv6 or unresolvable host or peer loaded, and was said
    only once a live run had set up its session and its devices; a bad peer's error named
    [room.share], not the peer, and quoted the whole table."""
    path = tmp_path / "shared.toml"
    path.write_text(textwrap.dedent(ROOM.format(share=f'share = {{ room = "gallery", {share} }}')))
    with pytest.raises(ConfigError, match=why) as info:
        load_installation(path)
    assert (info.value.key, info.value.line) == (key, 10) and "{" not in info.value.message


def test_a_share_port_in_use_or_another_listeners_refuses_the_run_before_its_state_folder(tmp_path, capsys):
    """``creatures run`` made and locked the state folder, loaded the creatures and opened the
    devices before it found the [room.share] port taken; one the [osc] listener also names
    was found only by the share's own bind, said as "another program"."""
    from creatures import cli

    path, state = tmp_path / "shared.toml", tmp_path / "state"
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as busy:
        busy.bind(("127.0.0.1", 0))
        port = busy.getsockname()[1]
        path.write_text(textwrap.dedent(ROOM.format(share=f'share = {{ room = "gallery", port = {port} }}')))
        assert cli.main(["run", str(path), "--state", str(state), "--duration", "0.2"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "room.share.port" in err and "already in use" in err
    assert not state.exists()
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as free:
        free.bind(("127.0.0.1", 0))
        port = free.getsockname()[1]
    path.write_text(textwrap.dedent(ROOM.format(share=f'share = {{ room = "gallery", port = {port} }}'))
                    + f"[osc]\nport = {port}\n")
    assert cli.main(["run", str(path), "--state", str(state), "--duration", "0.2"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"room.share.port: port {port} is [osc] port too" in err
    assert not state.exists()


def test_positions_go_out_on_the_rate_and_stale_or_unplaced_things_are_dropped():
    """At a 0.04 s tick and 25 updates a second every tick sends (t + 1/rate from a tick a hair
    early skipped one in six); a note from a creature not yet placed, or far off in time, is
    dropped and counted; a creature its owner stops speaking of leaves after the timeout."""
    a, b = shares(["a-0", "a-1"], ["b-0"])
    ticks = [k * 0.04 for k in range(1, 101)]
    for t in ticks:
        a.publish(t, ["a-0", "a-1"], np.array([ROW, ROW]))
    assert a.sent == len(ticks)
    a.played("a-0", NoteEvent(3.5, 60, 90, 0, 0.2))  # b polls only now: a-0 was placed first
    for _ in range(40):
        wait_for(b, 4.0)
        if b.received >= len(ticks) + 1:
            break
    c = RoomShare(ShareSpec(room="gallery", discover=False), ["c-0"], EPOCH)
    c.owner += "-c"
    c.configured = {("127.0.0.1", b.port)}
    c.played("c-0", NoteEvent(4.0, 60, 90, 0, 0.2))  # c-0 has never said where it stands
    wait_for(b, 4.0)
    a.publish(4.04, ["a-0"], np.array([ROW]))  # a speaks only of a-0 from now on
    a.played("a-0", NoteEvent(60.0, 60, 90, 0, 0.2))  # a minute ahead: not a note to keep
    wait_for(b, 4.04)
    stale = sum(4.0 - t > b.spec.timeout for t in ticks)  # positions b read more than the timeout late
    assert b.dropped["unplaced"] == 1 and b.dropped["time"] == stale + 1 and stale == 49
    a.publish(6.0, ["a-0"], np.array([ROW]))
    wait_for(b, 6.1)
    assert b.others(6.1)[0] == ["a-0"]  # a-1 unheard for 2.1 s > timeout
    for s in (a, b, c):
        s.close()


def test_without_zeroconf_or_aalink_the_room_is_shared_with_configured_peers(tmp_path, monkeypatch):
    monkeypatch.setitem(__import__("sys").modules, "zeroconf", None)  # `import zeroconf` raises ImportError
    monkeypatch.setitem(__import__("sys").modules, "aalink", None)
    s = session(tmp_path, 'share = { room = "gallery", link = true, peers = ["127.0.0.1:9"] }')
    said: list[str] = []
    shared = open_shared_room(s.inst, s, EPOCH, said.append)
    assert shared is not None and shared.discovery is None and shared.link is None
    assert any("pip install zeroconf" in m for m in said) and any("pip install aalink" in m for m in said)
    assert shared.share.targets() == {("127.0.0.1", 9)}
    shared.close()
    with pytest.raises(ConfigError) as info:  # said at load (test_a_share_host_or_peer_…_at_load)
        session(tmp_path, 'share = { room = "gallery", discover = false, peers = ["no-such-host.invalid:9000"] }')
    assert info.value.key == "room.share.peers.0" and "cannot be resolved" in info.value.message
    bad = session(tmp_path, 'share = { room = "gallery", discover = false, peers = ["127.0.0.1:9000"] }')
    bad.inst.settings.room.share.peers = ["no-such-host.invalid:9000"]  # a name that stopped resolving since
    with pytest.raises(ConfigError) as info:
        open_shared_room(bad.inst, bad, EPOCH, said.append)
    assert info.value.key == "room.share.peers.0" and "does not resolve" in info.value.message


class Beat:
    """A shared timeline that jumps (a Link session joined late, a machine that slept)."""

    tempo = 120.0

    def __init__(self) -> None:
        self.offset = 0.0

    def beat_at(self, unix: float) -> float:
        return (unix - EPOCH) * 2.0 + self.offset


def test_each_shared_beat_is_heard_once_and_a_jump_is_not_a_flood(tmp_path):
    s = session(tmp_path)
    timeline = Beat()
    share = RoomShare(ShareSpec(room="gallery", discover=False), ["me"], EPOCH, timeline=timeline)
    s.stage.attach(share, s.world)
    heard: list[float] = []
    s.world.pulse.hear = heard.append  # what the colony's pulse is told
    for _ in range(100):  # 2 s at 120 BPM: four beats
        t = s.clock.advance(0.02)
        s.step(t, 0, None, audio=False)
    assert heard == pytest.approx([0.5, 1.0, 1.5, 2.0], abs=1e-9) or heard == pytest.approx([0.0, 0.5, 1.0, 1.5, 2.0])
    timeline.offset = 1e6  # a million beats ahead at once
    del heard[:]
    for _ in range(50):
        t = s.clock.advance(0.02)
        s.step(t, 0, None, audio=False)
    assert 1 <= len(heard) <= 3  # on from the new beat, not a million beats at once
    share.close()


def test_a_paused_run_stays_in_the_room_standing_still(tmp_path):
    s = session(tmp_path)
    (peer,) = shares(["you"])
    share = RoomShare(ShareSpec(room="gallery", discover=False), ["me"], EPOCH)
    share.configured = {("127.0.0.1", peer.port)}
    s.stage.attach(share, s.world)
    s.stage.v.vel[0] = [0.5, 0.0]  # it was walking when the pause came
    for k in range(1, 76):  # 3 s paused at a 0.04 s tick (each sends), past the 2 s timeout
        s.stage.keep_sharing(k * 0.04)
        wait_for(peer, k * 0.04)
    names, rows = peer.others(3.0)
    assert names == ["me"] and rows[0, :2] == pytest.approx(s.stage.v.pos[0]) and not rows[0, 2:4].any()
    for x in (peer, share):
        x.close()
