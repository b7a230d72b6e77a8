"""The body stream: offline it is exactly what ``figure()`` drew at each frame time; on the
wire it is OSC python-osc reads; live it arrives at its rate; a slow sink costs the creatures
nothing (frames dropped and counted)."""

from __future__ import annotations

import shutil
import socket
import subprocess
import threading
import time

import numpy as np
import pytest
from pythonosc.dispatcher import Dispatcher
from pythonosc.osc_packet import OscPacket
from pythonosc.osc_server import ThreadingOSCUDPServer

from creatures.clock import SimulatedClock
from creatures.events import EventLog, read_events
from creatures.runtime import live
from creatures.runtime.body_stream import BodyStream, Frame, hello_of, snapshot
from creatures.runtime.offline import run_offline
from creatures.runtime.schema import load_installation
from creatures.runtime.session import Session
from creatures.runtime.stream_sinks import MemoryStreamSink, OscStreamSink, read_stream
from creatures.view.rerender import load_replay
from midi.sinks import MemorySink
from colony_fixtures import creature_tables

COLONY = 'title = "stream"\ntick = 0.02\nseed = 5\n' + creature_tables("ada", "bo")


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def _session(tmp_path, extra: str = "") -> Session:
    config = tmp_path / "colony.toml"
    config.write_text(COLONY + extra)
    return Session(load_installation(config), SimulatedClock(), EventLog(keep_in_memory=0), MemorySink())


def test_the_stream_file_is_read_from_the_path_a_user_types(tmp_path):
    """docs/stream.md names ``read_stream`` as the reader of an offline ``stream.jsonl``; given the
    path as text (``read_stream("out/stream.jsonl")``) it raised AttributeError: 'str' has no open."""
    path = tmp_path / "stream.jsonl"
    path.write_text('{"kind": "hello", "rate": 60.0, "creatures": []}\n{"kind": "frame", "index": 0}\n')
    assert read_stream(str(path)) == ({"kind": "hello", "rate": 60.0, "creatures": []}, [{"kind": "frame", "index": 0}])


def test_offline_stream_is_what_figure_drew_at_each_frame_time(tmp_path, monkeypatch):
    """60 frames a second over 20 ms ticks: frame times fall between ticks, and each frame
    holds the body its creature's last tick left (recorded here from figure() itself)."""
    config = tmp_path / "colony.toml"
    config.write_text(COLONY + "[output]\nwav = false\nreport = false\n[stream]\nfile = true\nrate = 60\n")
    drawn: list[tuple[float, list[np.ndarray]]] = []
    step = Session.step

    def recording(self, t, *args, **kwargs):
        if not drawn:
            drawn.append((0.0, [np.array(c.figure()[0]) for c in self.creatures]))
        mix = step(self, t, *args, **kwargs)
        drawn.append((t, [np.array(c.figure()[0]) for c in self.creatures]))
        return mix

    monkeypatch.setattr(Session, "step", recording)
    summary = run_offline(load_installation(config), tmp_path / "out", duration=8.0)
    hello, frames = read_stream(summary.files["stream"])
    assert hello["rate"] == 60 and [c["creature"] for c in hello["creatures"]] == ["ada", "bo"]
    assert hello["creatures"][0]["joints"][:2] == ["pelvis", "spine"]
    assert [f["index"] for f in frames] == list(range(481))  # 0 .. 8 s inclusive
    times = [t for t, _ in drawn]
    moved = 0.0
    for frame in frames:
        assert frame["time"] == pytest.approx(frame["index"] / 60, abs=1e-12)
        _, figures = drawn[np.searchsorted(times, frame["time"] + 1e-9, side="right") - 1]
        for pose, figure in zip(frame["poses"], figures):
            np.testing.assert_allclose(pose["positions"], figure, rtol=0, atol=1e-6)
        moved = max(moved, float(np.abs(np.array(frames[0]["poses"][0]["positions"]) - figures[0]).max()))
    assert moved > 0.05  # the bodies moved: a frozen stream would not pass
    # Rotations, offsets and root give the positions back (forward kinematics).
    from creatures.motor.skeleton import _forward_kinematics

    ada = hello["creatures"][0]
    pose = frames[-1]["poses"][0]
    offsets = np.array(ada["offsets"])
    root = np.array(pose["positions"][0]) - offsets[0]
    fk = _forward_kinematics(np.array(pose["rotations"])[None], root[None], np.array(ada["parents"]), offsets)[0]
    np.testing.assert_allclose(fk, pose["positions"], atol=1e-9)
    # Every note the log says was played is in the stream, under its creature.
    events = read_events(summary.files["events"])
    logged = sorted((e["creature"], e["pitch"]) for e in events if e["kind"] == "note")
    streamed = sorted((n[0], n[1]) for f in frames for n in f["played"])
    assert logged and streamed == logged
    heard = [n for f in frames for n in f["heard"]]
    assert len(heard) == sum(e["kind"] == "heard" for e in events) > 0
    actions = {p["action"] for f in frames for p in f["poses"]}
    assert actions & {"wander", "seek note", "rest"}, actions
    assert all(set(p["drives"]) == {"boredom", "hunger"} for p in frames[-1]["poses"])


def test_osc_frames_are_read_by_python_osc(tmp_path):
    session = _session(tmp_path)
    receiver = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    receiver.bind(("127.0.0.1", 0))
    receiver.settimeout(5)
    stream = BodyStream(session.world, 30.0, threaded=False)
    memory = MemoryStreamSink()
    stream.subscribe(memory)
    stream.subscribe(OscStreamSink([receiver.getsockname()]))
    for step in range(1, 6):
        session.clock.advance_to(step * 0.02)
        session.step(step * 0.02, 441, None, audio=False)
        stream.advance(step * 0.02)
    stream.close()
    messages: dict[str, list] = {}
    receiver.setblocking(False)
    try:
        while True:
            for timed in OscPacket(receiver.recv(65536)).messages:
                messages.setdefault(timed.message.address, []).append(list(timed.message.params))
    except BlockingIOError:
        pass
    receiver.close()
    assert messages["/colony/hello"][0][:2] == [pytest.approx(30.0), 2]
    skeleton = messages["/body/ada/skeleton"][0]
    hello = memory.hellos[0]
    assert skeleton[0::2] == list(hello.joints) and skeleton[1::2] == list(hello.parents)
    assert messages["/body/ada/drive_names"][0] == ["boredom", "hunger"]
    assert [m[0] for m in messages["/colony/frame"]] == [0, 1, 2, 3]  # 0.1 s at 30 Hz: frames 0..3
    for params, frame in zip(messages["/body/bo/pose"], memory.frames):
        assert params[0] == pytest.approx(frame.time, abs=1e-12)
        np.testing.assert_allclose(np.reshape(params[1:], (-1, 3)), frame.poses[1].positions, atol=1e-6)
    np.testing.assert_allclose(np.reshape(messages["/body/bo/rotation"][-1], (-1, 4)),
                               memory.frames[-1].poses[1].rotations, atol=1e-6)
    np.testing.assert_allclose(messages["/body/ada/drives"][-1], memory.frames[-1].poses[0].drives, atol=1e-6)
    assert messages["/body/ada/action"][-1] == [memory.frames[-1].poses[0].action]


def test_the_frame_index_wraps_where_osc_ints_end_and_the_stream_goes_on(tmp_path):
    """``/colony/frame index:i`` is an OSC int32: at 240 frames a second the index passes it
    after 103 days (at 60, 414), and every frame from then on raised in the sender (counted
    as sink errors; nothing reached a renderer again). It wraps; the time goes on."""
    session = _session(tmp_path)
    receiver = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    receiver.bind(("127.0.0.1", 0))
    receiver.settimeout(5)
    sink = OscStreamSink([receiver.getsockname()])
    sink.hello([hello_of(c, i) for i, c in enumerate(session.creatures)], 240.0)
    late = 2**31 + 5
    sink.frame(Frame(late, late / 240.0, tuple(snapshot(c) for c in session.creatures)))
    sink.close()
    addresses = []
    while not any(a == "/body/bo/action" for a, _ in addresses):
        addresses += [(t.message.address, t.message.params) for t in OscPacket(receiver.recv(65536)).messages]
    receiver.close()
    assert dict(addresses)["/colony/frame"] == [5, late / 240.0]
    assert "/body/ada/pose" in dict(addresses)


class _Stuck:
    """A sink that holds the sender thread until let go."""

    def __init__(self) -> None:
        self.go = threading.Event()
        self.frames: list[int] = []

    def hello(self, hellos, rate) -> None:
        pass

    def frame(self, frame) -> None:
        self.go.wait(10)
        self.frames.append(frame.index)

    def close(self) -> None:
        pass


def test_a_stuck_renderer_costs_frames_not_ticks(tmp_path):
    session = _session(tmp_path)
    stream = BodyStream(session.world, 50.0, queue_size=2)
    stuck = _Stuck()
    stream.subscribe(stuck)
    started = time.perf_counter()
    for k in range(10):
        assert stream.advance(k * 0.02) == 1  # one frame per call, never waiting
    assert time.perf_counter() - started < 2.0  # the stuck sink holds nothing up (it waits 10 s)
    assert 7 <= stream.dropped <= 8  # one in the sender's hands (or not yet), two queued
    stuck.go.set()
    stream.close()
    assert len(stuck.frames) == 10 - stream.dropped and stuck.frames == sorted(stuck.frames)
    # Live, a loop busy past several frame times takes only the latest.
    assert stream.advance(0.5) == 1 and stream.skipped == 15


@pytest.mark.realtime  # alone: it times a live loop in real time, which a busy neighbour test delays
def test_live_stream_arrives_at_its_rate(tmp_path):
    """A live run streaming 60 frames a second (more often than its 50 ticks: frames are
    taken between ticks too) to a python-osc server on loopback: frames arrive at 60/s ± 10 %
    by the monotonic clock the run's WallClock reads."""
    arrivals: list[tuple[float, int]] = []
    poses: list[str] = []
    dispatcher = Dispatcher()
    dispatcher.map("/colony/frame", lambda address, index, t: arrivals.append((time.monotonic(), index)))
    dispatcher.map("/body/*/pose", lambda address, *args: poses.append(address))
    server = ThreadingOSCUDPServer(("127.0.0.1", 0), dispatcher)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    config = tmp_path / "live.toml"
    config.write_text("realtime = false\n" + COLONY + "[audio]\noutput = false\n"
                      f"[stream]\nrate = 60\ntargets = [\"127.0.0.1:{server.server_address[1]}\"]\n")
    log = tmp_path / "events.jsonl"
    try:
        summary = live.run_live(load_installation(config), duration=3.0, log_path=log, say=lambda m: None)
    finally:
        server.shutdown()
        server.server_close()
    assert len(arrivals) >= 160
    span = arrivals[-1][0] - arrivals[0][0]
    rate = (len(arrivals) - 1) / span
    assert 54.0 <= rate <= 66.0, rate
    counts = summary.outlets["stream"]
    assert counts["frames"] == len(arrivals) + counts["dropped"]  # every frame taken arrived or was counted
    assert [e for e in read_events(log) if e["kind"] == "stream"][-1]["frames"] == counts["frames"]
    assert set(poses) == {"/body/ada/pose", "/body/bo/pose"}


def test_a_creature_without_a_body_streams_its_drives_and_action(tmp_path):
    config = tmp_path / "mixed.toml"
    config.write_text('title = "mixed"\n' + creature_tables("ada") + creature_tables("stone", kind="sandstone"))
    session = Session(load_installation(config), SimulatedClock(), EventLog(keep_in_memory=0), MemorySink())
    receiver = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    receiver.bind(("127.0.0.1", 0))
    receiver.setblocking(False)
    stream = BodyStream(session.world, 30.0, threaded=False)
    stream.subscribe(OscStreamSink([receiver.getsockname()]))
    stream.advance(0.0)
    stream.close()
    addresses = set()
    try:
        while True:
            addresses |= {timed.message.address for timed in OscPacket(receiver.recv(65536)).messages}
    except BlockingIOError:
        pass
    receiver.close()
    stone = {a for a in addresses if a.startswith("/body/stone/")}
    assert stone == {"/body/stone/skeleton", "/body/stone/drive_names", "/body/stone/drives", "/body/stone/action"}
    assert {"/body/ada/pose", "/body/ada/rotation", "/body/ada/effector"} <= addresses


@pytest.mark.skipif(shutil.which("oscdump") is None, reason="liblo-tools' oscdump is not installed")
def test_liblo_reads_the_stream(tmp_path):
    """A foreign OSC library (liblo's oscdump) reads every message of a frame, with its types."""
    port = _free_udp_port()
    dump = subprocess.Popen(["oscdump", "-L", str(port)], stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)
    try:
        session = _session(tmp_path)
        stream = BodyStream(session.world, 30.0, threaded=False)
        memory = MemoryStreamSink()
        stream.subscribe(memory)
        stream.subscribe(OscStreamSink([("127.0.0.1", port)]))
        lines: list[str] = []
        reader = threading.Thread(target=lambda: lines.extend(dump.stdout), daemon=True)
        reader.start()
        deadline = time.monotonic() + 30
        step = 0
        while not any(" /body/bo/pose " in line for line in lines):  # oscdump may still be starting
            assert time.monotonic() < deadline and dump.poll() is None, lines
            step += 1
            session.clock.advance_to(step * 0.02)
            session.step(step * 0.02, 441, None, audio=False)
            stream.advance(step * 0.02)
            time.sleep(0.02)
    finally:
        dump.terminate()
        dump.wait(10)
    reader.join(5)
    messages = [line.split()[1:] for line in lines]  # oscdump: time tag, address, type tags, arguments
    pose = next(m for m in messages if m[0] == "/body/bo/pose")
    joints = len(memory.hellos[1].joints)
    assert pose[1] == "d" + "f" * 3 * joints
    frame = next(f for f in memory.frames if abs(f.time - float(pose[2])) < 1e-9)
    np.testing.assert_allclose(np.array(pose[3:], float).reshape(-1, 3), frame.poses[1].positions, atol=1e-5)
    assert any(m[:2] == ["/body/ada/action", "s"] for m in messages)


def test_a_live_run_logs_poses_to_replay_and_render(tmp_path):
    """A live run with --log writes its bodies as an offline run does (skeletons, then poses at
    [view] log_fps), so `creatures view` and `creatures render` replay it: 2 s at 20 poses a
    second are ~41 frames, each with both bodies, and the bodies moved."""
    config = tmp_path / "live.toml"
    config.write_text("realtime = false\n" + COLONY + "[audio]\noutput = false\n[view]\nlog_fps = 20\n")
    log = tmp_path / "events.jsonl"
    live.run_live(load_installation(config), duration=2.0, log_path=log, say=lambda m: None)
    played = load_replay(tmp_path)
    assert [c["name"] for c in played.hello["creatures"]] == ["ada", "bo"]
    bodied = [f for f in played.frames if set(f["bodies"]) == {"ada", "bo"}]
    assert 36 <= len(bodied) <= 44, len(bodied)
    times = np.array([f["t"] for f in bodied])
    assert np.median(np.diff(times)) == pytest.approx(0.05, abs=0.01)
    assert np.abs(bodied[-1]["bodies"]["ada"] - bodied[0]["bodies"]["ada"]).max() > 1e-3
