"""The view without a browser (issue 19): the poses an offline run logs, the replay built from
them, the live feed's bounded queue, the websocket server, and re-rendering a finished run."""

from __future__ import annotations

import asyncio
import json
import logging
import socket
import struct
import subprocess
import sys
import threading
import time
import tracemalloc

import aiohttp
import numpy as np
import pytest

import installations
from creatures.clock import SimulatedClock
from creatures.config import ConfigError
from creatures.events import EventLog, read_events
from creatures.runtime.live import check_before_running
from creatures.runtime.offline import run_offline
from creatures.runtime.schema import load_installation
from creatures.runtime.session import Session
from creatures.view import feed as feeds
from creatures.view import poses
from creatures.view import server as server_module
from creatures.view.feed import Feed
from creatures.view.poses import PoseLog
from creatures.view.rerender import load_replay, parse_orbit, sampled
from creatures.view.server import LiveSource, ReplaySource, ViewServer, port_problem
from creatures.view.snapshot import place, replay, scene
from midi.notes import NoteEvent
from midi.sinks import MemorySink

SECONDS = 4.0


def exchange_session(log: EventLog) -> tuple[Session, SimulatedClock]:
    clock = SimulatedClock()
    session = Session(load_installation(installations.path("exchange")), clock, log, MemorySink())
    for i, pitch in enumerate((60, 64, 67)):
        session.world.inject(NoteEvent(0.2 + 0.3 * i, pitch, 90, 0, 0.3))
    return session, clock


def step(session: Session, clock: SimulatedClock, ticks: int, then=lambda: None) -> None:
    tick = session.inst.settings.tick
    for _ in range(ticks):
        clock.advance_to(clock.now() + tick)
        session.step(clock.now(), int(round(tick * session.sample_rate)), None, audio=False)
        then()


@pytest.fixture(scope="module")
def offline_run(tmp_path_factory):
    """The shipped exchange colony run offline for a few seconds (poses at [view] log_fps)."""
    out = tmp_path_factory.mktemp("offline")
    inst = load_installation(installations.path("exchange"))
    inst.settings.output.report = False
    run_offline(inst, out, duration=SECONDS)
    return out


def test_poses_are_the_figures_at_the_log_rate():
    log = EventLog(keep_in_memory=100_000)
    session, clock = exchange_session(log)
    logged = PoseLog(10.0, session.world, print)
    figures = {}

    def write() -> None:
        before = len(log.records)
        logged.write()
        if len(log.records) > before:
            figures[round(clock.now(), 6)] = {c.name: c.figure()[0].copy() for c in session.creatures}

    step(session, clock, 50, write)  # 2 s at exchange's 0.04 s tick
    skeletons = [e for e in log.records if e["kind"] == "skeleton"]
    assert [e["creature"] for e in skeletons] == ["ada", "bo", "cy"]
    assert skeletons[0]["parents"] == session.creatures[0].figure()[1].tolist()
    assert [e["place"] for e in skeletons] == [list(place(i, 3)) for i in range(3)]
    pose_events = [e for e in log.records if e["kind"] == "pose"]
    times = sorted({e["t"] for e in pose_events})
    assert len(times) == 21 and len(pose_events) == 63  # frames at 0, 0.1, … 2.0 s of clock time, three bodies each
    assert np.diff(times) == pytest.approx(0.1, abs=0.04 + 1e-9)  # on the tick grid nearest each frame
    for event in pose_events:
        assert np.asarray(event["joints"]) == pytest.approx(figures[event["t"]][event["creature"]], abs=1e-6)
    moved = [np.abs(figures[times[-1]][n] - figures[times[0]][n]).max() for n in ("ada", "bo", "cy")]
    assert max(moved) > 0.01  # the bodies move, so the comparison above means something


def test_the_poses_stop_at_their_budget_and_say_so(monkeypatch):
    monkeypatch.setattr(poses, "POSE_BUDGET", 20_000)
    said = []
    log = EventLog(keep_in_memory=100_000)
    session, clock = exchange_session(log)
    logged = PoseLog(60.0, session.world, said.append)
    step(session, clock, 50, logged.write)
    written = sum(len(json.dumps(e)) for e in log.records if e["kind"] == "pose")
    assert written <= 20_000 * 1.3  # json.dumps spaces vs orjson: the budget is the bound
    assert [e["kind"] for e in log.records].count("poses stopped") == 1 and logged.stopped
    assert said and "20000 bytes" in said[0]


def test_an_offline_run_replays_from_its_log(offline_run):
    played = load_replay(offline_run)
    assert played.hello["mode"] == "replay" and [c["name"] for c in played.hello["creatures"]] == ["ada", "bo", "cy"]
    assert len(played.frames) == int(SECONDS * 10) + 1  # poses at 10/s of clock time, 0 s to the end
    first = played.frames[0]
    assert set(first["bodies"]) == {"ada", "bo", "cy"} and first["bodies"]["ada"].shape == (19, 3)
    events = read_events(offline_run / "events.jsonl")
    heard = [e for e in events if e["kind"] == "heard"]
    carried = [e for f in played.frames for e in f["events"] if e["kind"] == "heard"]
    assert heard and carried == heard[:len(carried)] and len(carried) >= len(heard) - 1
    positions, parents, _ = scene(first, played.hello)
    assert positions.shape == (57, 3) and parents[[0, 19, 38]].tolist() == [-1, -1, -1]
    assert (parents[20:38] >= 19).all() and (parents[39:] >= 38).all()  # each body's bones within it
    assert positions[19:38] == pytest.approx(first["bodies"]["bo"] + place(1, 3))


def test_a_log_with_nothing_to_show_is_refused_and_one_without_bodies_replays_its_events(tmp_path):
    log = tmp_path / "events.jsonl"
    log.write_text('{"t": 0, "kind": "run", "title": "x", "creatures": ["a"]}\n')
    with pytest.raises(ValueError, match="nothing to show"):
        load_replay(tmp_path)
    result = subprocess.run([sys.executable, "-m", "creatures.cli", "view", str(tmp_path)], capture_output=True,
                            text=True, timeout=60)
    assert result.returncode == 2 and "nothing to show" in result.stderr
    with pytest.raises(ValueError, match="no events log"):
        load_replay(tmp_path / "elsewhere")
    with log.open("a") as more:  # a creature without a body: its notes and drives still replay
        for t, pitch in ((0.03, 60), (0.05, 62), (0.31, 64)):
            more.write(json.dumps({"t": t, "kind": "note", "creature": "a", "time": t, "pitch": pitch,
                                   "duration": 0.2}) + "\n")
    played = load_replay(tmp_path)
    assert played.hello["creatures"] == [{"name": "a", "kind": "", "parents": None, "place": [0.0, 0.0, 0.0]}]
    assert [(f["t"], [e["pitch"] for e in f["events"]]) for f in played.frames] == [(0.0, [60, 62]), (0.3, [64])]
    result = subprocess.run([sys.executable, "-m", "creatures.cli", "render", str(tmp_path)], capture_output=True,
                            text=True, timeout=60)
    assert result.returncode == 2 and "no body poses" in result.stderr


def test_a_malformed_pose_names_its_line_and_one_off_its_skeleton_its_creature(tmp_path):
    log = tmp_path / "events.jsonl"
    log.write_text('{"t": 0, "kind": "pose", "creature": "a", "joints": [[0, 1]], "marks": []}\n')
    with pytest.raises(ValueError, match=r"events.jsonl:1: .*'joints'"):
        load_replay(tmp_path)
    log.write_text('{"t": 0, "kind": "skeleton", "creature": "a", "parents": [-1, 0], "place": [0, 0, 0]}\n'
                   '{"t": 0.1, "kind": "pose", "creature": "a", "joints": [[0, 1, 0]], "marks": []}\n')
    with pytest.raises(ValueError, match="'a' at 0.1 s does not fit its skeleton"):
        load_replay(tmp_path)


def test_a_long_log_replays_one_event_at_a_time(tmp_path):
    """A night's log is mostly poses: read whole as dicts, a 10-minute exchange run's 26 MB log
    took 218 MB before the replay began. Replayed one event at a time, a pose is kept as arrays."""
    rng = np.random.default_rng(3)
    joints, marks = rng.random((3000, 19, 3)).round(6), rng.random((3000, 6, 4)).round(6)
    log = tmp_path / "events.jsonl"
    with log.open("w") as out:
        out.write(json.dumps({"t": 0, "kind": "skeleton", "creature": "a", "parents": [-1] + list(range(18)),
                              "place": [0, 0, 0]}) + "\n")
        for k in range(3000):
            out.write(json.dumps({"t": k / 10, "kind": "pose", "creature": "a", "joints": joints[k].tolist(),
                                  "marks": marks[k].tolist()}) + "\n")
            if k % 100 == 7:
                out.write(json.dumps({"t": k / 10, "kind": "note", "creature": "a", "time": k / 10, "pitch": 60,
                                      "duration": 0.2}) + "\n")
    tracemalloc.start()
    try:
        played = load_replay(tmp_path)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert len(played.frames) == 3000 and played.frames[1234]["bodies"]["a"] == pytest.approx(joints[1234])
    assert [f["t"] for f in played.frames if f["events"]] == [k / 10 for k in range(7, 3000, 100)]
    assert scene(played.frames[5], played.hello)[2][2] == (pytest.approx(tuple(marks[5, 2, :3])), marks[5, 2, 3])
    assert peak < 3 * log.stat().st_size  # 1.8 times the log's bytes; held as dicts first, 6.7 times


def test_the_feed_drops_and_counts_what_the_view_is_too_slow_to_take():
    log = EventLog(keep_in_memory=10)
    session, clock = exchange_session(log)
    feed = Feed("exchange", session.creatures, log, clock, 25.0)  # a frame every 0.04 s tick
    step(session, clock, feeds.QUEUED_FRAMES + 5, feed.offer)
    assert feed.dropped == 5  # the queue took QUEUED_FRAMES and nobody emptied it
    taken = feed.take()
    assert taken["status"] == {"dropped": 5, "superseded": feeds.QUEUED_FRAMES - 1, "events_dropped": 0}
    assert taken["t"] == pytest.approx((feeds.QUEUED_FRAMES - 1) * 0.04 + 0.04)  # the newest the queue held
    assert feed.take() is None  # nothing waits now
    kinds = {e["kind"] for e in taken["events"]}
    assert {"selection", "motivation", "values"} <= kinds and "motor" not in kinds and "skeleton" not in kinds
    step(session, clock, 1, feed.offer)
    frame = feed.take()
    assert frame["bodies"]["ada"] == pytest.approx(session.creatures[0].figure()[0])
    for _ in range(feeds.QUEUED_EVENTS + 7):
        log.emit(clock.now(), "note", creature="ada", time=0.0, pitch=60, duration=0.1)
    assert feed.events_dropped == 7 and len(feed.events) == feeds.QUEUED_EVENTS
    feed.close()
    log.emit(clock.now(), "note", creature="ada", time=0.0, pitch=61, duration=0.1)
    assert feed.events[-1]["pitch"] == 60  # closed: the tap is gone


async def _read(url: str, count: int, got: list[dict] | None = None) -> list[dict]:
    """The first ``count`` messages from the view's websocket, other than percept trees (into
    ``got`` as they come, when given, so a caller can wait for one)."""
    got = [] if got is None else got
    async with aiohttp.ClientSession() as client:
        async with client.ws_connect(url + "ws") as ws:
            while len(got) < count:
                message = json.loads((await ws.receive(timeout=10)).data)
                if message["type"] != "trees":
                    got.append(message)
    return got


async def _hello_and_two_frames(server: ViewServer, session: Session, clock: SimulatedClock, feed: Feed,
                                connected=lambda: None) -> list[dict]:
    """What a browser reads from a live view: its hello and the frames of two ticks, the second
    ticked once the first frame was read (``connected`` runs once the browser is, before the
    first tick)."""
    got: list[dict] = []
    reading = asyncio.ensure_future(_read(server.url, 3, got))
    while not server.clients:
        await asyncio.sleep(0.01)
    connected()
    step(session, clock, 1, feed.offer)
    for _ in range(1000):  # the first frame read before the second tick replaces it (the view sends the newest)
        if len(got) >= 2 or reading.done():
            break
        await asyncio.sleep(0.01)
    step(session, clock, 1, feed.offer)
    return await reading


def test_the_server_sends_the_hello_then_the_feeds_frames_on_its_own_thread():
    log = EventLog(keep_in_memory=10)
    session, clock = exchange_session(log)
    feed = Feed("exchange", session.creatures, log, clock, 25.0)
    server = ViewServer(LiveSource(feed, 25.0)).start()
    try:
        hello, first, second = asyncio.run(_hello_and_two_frames(server, session, clock, feed))
        assert hello["type"] == "hello" and hello["mode"] == "live"
        assert [c["parents"] for c in hello["creatures"]][0] == session.creatures[0].figure()[1].tolist()
        assert first["type"] == second["type"] == "frame" and second["t"] > first["t"]
        assert second["bodies"]["cy"] == pytest.approx(session.creatures[2].figure()[0], abs=1e-9)

        async def page() -> tuple[int, str, int]:
            async with aiohttp.ClientSession() as client:
                async with client.get(server.url) as index, client.get(server.url + "static/view.js") as js:
                    return index.status, await index.text(), js.status

        status, text, js = asyncio.run(page())
        assert status == 200 and js == 200 and "view.js" in text

        async def foreign() -> int:
            async with aiohttp.ClientSession() as client:
                async with client.get(server.url, headers={"Host": "evil.example:80"}) as answer:
                    return answer.status

        assert asyncio.run(foreign()) == 403  # a page elsewhere cannot rebind its name onto the view
    finally:
        server.close()
        feed.close()


def test_a_record_orjson_refuses_does_not_stop_the_live_view(tmp_path):
    # A log with a file hands its taps the fields as emitted (a numpy integer key, an integer
    # beyond 64 bits: the log's own line falls back to the standard library for them); the
    # view's encoding raised on such a record and its feeding task died: no frame after it.
    log = EventLog(tmp_path / "events.jsonl")
    session, clock = exchange_session(log)
    feed = Feed("exchange", session.creatures, log, clock, 25.0)
    server = ViewServer(LiveSource(feed, 25.0)).start()
    try:
        _, first, second = asyncio.run(_hello_and_two_frames(
            server, session, clock, feed,
            lambda: log.emit(clock.now(), "values", creature="ada", values={np.int64(3): 0.5}, count=2**70)))
    finally:
        server.close()
        feed.close()
        log.close()
    assert first["events"][0]["values"] == {"3": 0.5} and first["events"][0]["count"] == 2**70
    assert second["type"] == "frame" and second["t"] > first["t"]


def test_a_frame_the_live_view_cannot_make_is_skipped_said_and_counted(monkeypatch):
    """Any error making a frame ended the view's feeding task silently: /status answered on and
    no browser got a frame again for the rest of the run (an audit)."""
    log = EventLog(keep_in_memory=10)
    session, clock = exchange_session(log)
    feed = Feed("exchange", session.creatures, log, clock, 25.0)
    take, broken = feed.take, [True]

    def once_broken():
        if broken:
            broken.clear()
            raise RuntimeError("a reader's slip")
        return take()

    monkeypatch.setattr(feed, "take", once_broken)
    server = ViewServer(LiveSource(feed, 25.0)).start()
    try:
        _, first, second = asyncio.run(_hello_and_two_frames(server, session, clock, feed))

        async def status() -> dict:
            async with aiohttp.ClientSession() as client:
                async with client.get(server.url + "status") as answer:
                    return await answer.json()

        counted = asyncio.run(status())
    finally:
        server.close()
        feed.close()
    assert first["type"] == second["type"] == "frame" and second["t"] > first["t"]
    assert counted["failed"] == 1


def test_a_replay_sends_every_frame_at_its_time(offline_run):
    played = load_replay(offline_run)
    server = ViewServer(ReplaySource(played, speed=20.0)).start()
    try:
        messages = asyncio.run(_read(server.url, 1 + len(played.frames) + 1))
    finally:
        server.close()
    assert messages[0]["mode"] == "replay"
    frames = messages[1:-1]
    assert [f["t"] for f in frames] == [f["t"] for f in played.frames]
    assert np.asarray(frames[0]["bodies"]["ada"]) == pytest.approx(played.frames[0]["bodies"]["ada"])
    assert messages[-1]["type"] == "restart"  # and again from the start, for a kiosk


def test_a_port_in_use_is_a_config_error_before_the_run(tmp_path):
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        assert "cannot be used" in port_problem(port)
        config = tmp_path / "show.toml"
        config.write_text(f'extends = "{installations.path("exchange")}"\n[view]\nport = {port}\n')
        with pytest.raises(ConfigError, match=r"show.toml.*view.*port"):
            check_before_running(load_installation(config), state=None, log_path=None, pictures=None, view=port)


def test_view_keys_are_bounded(tmp_path):
    config = tmp_path / "bad.toml"
    config.write_text(f'extends = "{installations.path("exchange")}"\n[view]\nlog_fps = 600\n')
    with pytest.raises(ConfigError, match=r"bad.toml:3.*log_fps"):
        load_installation(config)


def test_a_camera_is_an_orbit_and_nonsense_is_refused():
    orbit = parse_orbit("0,0,3,0,1,0")
    assert orbit.pose()[:3, 3] == pytest.approx([0.0, 1.0, 3.0])
    assert parse_orbit("90,0,2").pose()[:3, 3] == pytest.approx([2.0, 1.0, 0.0])
    for text in ("1,2", "0,95,3", "0,0,-1", "a,b,c", "0,0,nan"):
        with pytest.raises(ValueError, match="YAW,PITCH,DISTANCE"):
            parse_orbit(text)


def test_sampling_at_another_rate_keeps_the_runs_length():
    frames = [{"t": 0.1 * i} for i in range(11)]  # 1 s at 10/s
    twice = sampled(frames, 20.0)
    assert sum(n for _, n in twice) == 21 and all(n == 2 for _, n in twice[:-1])
    half = sampled(frames, 5.0)
    assert [f["t"] for f, _ in half] == pytest.approx([0.0, 0.2, 0.4, 0.6, 0.8, 1.0])


@pytest.mark.gl
def test_render_draws_every_frame_at_the_size_and_camera_asked(offline_run, tmp_path):
    import imageio.v3 as iio

    out = tmp_path / "render"
    result = subprocess.run([sys.executable, "-m", "creatures.cli", "render", str(offline_run), "--out", str(out),
                             "--width", "200", "--height", "120", "--camera", "30,10,4,0,1,0"],
                            capture_output=True, text=True, timeout=300)
    if "no offscreen OpenGL platform" in result.stderr:
        pytest.skip(result.stderr)
    assert result.returncode == 0, result.stderr
    pngs = sorted((out / "frames").glob("*.png"))
    assert len(pngs) == len(replay(read_events(offline_run / "events.jsonl")).frames)
    first, last = iio.imread(pngs[0]), iio.imread(pngs[-1])
    assert first.shape == (120, 200, 3) and np.abs(first.astype(int) - last).max() > 50  # the bodies moved
    result = subprocess.run([sys.executable, "-m", "creatures.cli", "render", str(offline_run), "--camera", "0,95,1"],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 2 and "YAW,PITCH,DISTANCE" in result.stderr
    video = tmp_path / "new" / "folder"  # the video alone, into a folder not made yet
    result = subprocess.run([sys.executable, "-m", "creatures.cli", "render", str(offline_run), "--out", str(video),
                             "--video", "--no-pngs"], capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    assert (video / "out.mp4").stat().st_size > 1000 and not (video / "frames").exists()


@pytest.mark.gl
def test_a_render_stopped_part_way_leaves_the_last_render_and_the_line_drawings_as_they_were(offline_run, tmp_path,
                                                                                          monkeypatch):
    """Stopped (Ctrl-C) part way, a render had cut the last render's out.mp4 short (a short video
    that plays as if whole) and drawn its frames over the start of the last render's. Now the
    folder is as it was; a render finished beside the line drawings keeps them."""
    from creatures.body import frames as frames_module
    from creatures.body.lines import render_lines
    from creatures.body.render import RenderUnavailable
    from creatures.view.rerender import render_run
    from test_faults import _tree

    out = tmp_path / "render"
    try:
        drawn = render_run(offline_run, out, width=48, height=32, video=True)
    except RenderUnavailable as exc:
        pytest.skip(str(exc))
    lines = render_lines(offline_run, out)
    before = _tree(out)
    write = frames_module.FrameWriter.write

    def stopped(self, frame, *, repeat=1):
        if self.count >= 5:
            raise KeyboardInterrupt
        write(self, frame, repeat=repeat)

    monkeypatch.setattr(frames_module.FrameWriter, "write", stopped)
    with pytest.raises(KeyboardInterrupt):
        render_run(offline_run, out, width=64, height=48, fps=20.0, video=True)
    assert _tree(out) == before
    monkeypatch.undo()
    again = render_run(offline_run, out, width=64, height=48, fps=20.0)
    assert again > drawn and len(list((out / "frames").glob("frame_*.png"))) == again
    assert not (out / "out.mp4").exists()  # this render made none: the last one's went with its frames
    assert len(list((out / "lines").glob("frame_*.svg"))) == lines


def test_the_percept_trees_reach_the_page_live_and_replayed(tmp_path):
    from creatures.view.rerender import learned

    clock = SimulatedClock()
    log = EventLog(keep_in_memory=10)
    session = Session(load_installation(installations.path("ozymandias")), clock, log, MemorySink())
    feed = Feed("ozymandias", session.creatures, log, clock, 25.0)
    server = ViewServer(LiveSource(feed, 25.0)).start()
    try:
        async def until_trees(ws) -> dict:
            while True:
                message = json.loads((await ws.receive(timeout=10)).data)
                if message["type"] == "trees":
                    return message

        async def scenario() -> tuple[dict, list[dict]]:
            async with aiohttp.ClientSession() as client:
                async with client.ws_connect(server.url + "ws") as ws:
                    await ws.receive(timeout=10)  # hello
                    step(session, clock, 1, feed.offer)
                    live = await until_trees(ws)
                async with client.ws_connect(server.url + "ws") as late:  # a browser opened later
                    return live, [json.loads((await late.receive(timeout=10)).data) for _ in range(2)]

        live, (hello, greeting) = asyncio.run(scenario())
    finally:
        server.close()
        feed.close()
    names = [c.name for c in session.creatures]
    assert set(live["trees"]) == set(names) and live["t"] == pytest.approx(clock.now())
    assert live["trees"][names[0]][0]["name"] == session.creatures[0].root.name
    assert hello["type"] == "hello" and greeting == live  # sent at once, not in two seconds
    session.save_state(tmp_path / "state")
    assert learned(tmp_path)["trees"][names[0]] == live["trees"][names[0]]


def test_closing_the_view_closes_a_browser_still_connected():
    """A kiosk's browser is still on the page when the run ends: its socket is closed as
    "going away" and the server's thread ends (it once waited on the browser forever)."""
    played = replay([{"t": 0.0, "kind": "run", "title": "x", "creatures": ["a"]},
                     {"t": 0.01, "kind": "note", "creature": "a", "time": 0.01, "pitch": 60, "duration": 0.1}])
    server = ViewServer(ReplaySource(played)).start()

    async def scenario() -> tuple[aiohttp.WSMessage, float]:
        async with aiohttp.ClientSession() as client:
            async with client.ws_connect(server.url + "ws") as ws:
                assert json.loads((await ws.receive(timeout=10)).data)["type"] == "hello"
                started = time.perf_counter()
                await asyncio.get_running_loop().run_in_executor(None, server.close)
                took = time.perf_counter() - started
                while (message := await ws.receive(timeout=10)).type == aiohttp.WSMsgType.TEXT:
                    pass
                return message, took

    message, took = asyncio.run(scenario())
    assert message.type in (aiohttp.WSMsgType.CLOSE, aiohttp.WSMsgType.CLOSED)
    assert not server._thread.is_alive() and took < 5.0  # the join's own bound is 10 s


class _Flood:
    """A live source of large frames, as fast as the loop goes: a browser that stops reading
    soon has its socket and its queue full."""

    def hello(self) -> dict:
        return {"type": "hello", "title": "flood", "mode": "live", "creatures": []}

    def greeting(self) -> list[str]:
        return []

    async def run(self, clients) -> None:
        text = json.dumps({"type": "frame", "t": 0.0, "pad": "x" * 200_000})
        while True:
            await asyncio.sleep(0.002)
            for client in clients:
                client.offer(text)

    async def serve(self, client) -> None:
        pass


def _open_socket(port: int, receive_buffer: int | None = None) -> socket.socket:
    """A websocket opened by hand (the handshake sent, nothing read): a browser we control."""
    browser = socket.socket()
    if receive_buffer is not None:
        browser.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, receive_buffer)
    browser.settimeout(10)
    browser.connect(("127.0.0.1", port))
    browser.sendall(f"GET /ws HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\n"
                    "Connection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
                    "Sec-WebSocket-Version: 13\r\n\r\n".encode())
    return browser


def test_a_browser_that_stopped_reading_does_not_hold_the_view_open():
    """A frozen kiosk tab keeps its connection but reads nothing: its frames are dropped and
    counted, and when the run stops the view's thread still ends at once (closing it once
    waited for room in that browser's socket until the 10 s join gave up on the thread)."""
    server = ViewServer(_Flood()).start()
    with _open_socket(server.port, receive_buffer=4096):
        deadline = time.monotonic() + 30
        while not any(c.dropped for c in list(server.clients)) and time.monotonic() < deadline:
            time.sleep(0.01)
        assert any(c.dropped for c in list(server.clients))  # its socket is full: it is stuck
        started = time.perf_counter()
        server.close()
        took = time.perf_counter() - started
    assert not server._thread.is_alive() and took < 5.0


def test_the_frames_a_browser_lost_stay_counted_after_it_leaves():
    """/status counts the frames dropped for slow browsers; a browser that stopped reading and
    then went away (a frozen kiosk tab, reloaded) keeps its count there (it once fell to 0)."""
    server = ViewServer(_Flood()).start()
    try:
        with _open_socket(server.port, receive_buffer=4096) as browser:
            deadline = time.monotonic() + 30
            while not any(c.dropped for c in list(server.clients)) and time.monotonic() < deadline:
                time.sleep(0.01)
            lost = sum(c.dropped for c in list(server.clients))
            assert lost > 0
            browser.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
        deadline = time.monotonic() + 10
        while server.clients and time.monotonic() < deadline:
            time.sleep(0.01)
        assert not server.clients

        async def status() -> dict:
            async with aiohttp.ClientSession() as client:
                async with client.get(f"{server.url}status") as answer:
                    return await answer.json()

        reported = asyncio.run(status())
        assert reported["clients"] == 0 and reported["client_dropped"] >= lost
    finally:
        server.close()


def test_browsers_past_the_limit_are_refused_and_counted(monkeypatch):
    """A local script opening sockets in a loop once got a queue and a send per frame each, without bound."""
    monkeypatch.setattr(server_module, "MAX_CLIENTS", 2)
    source = _Gated()
    source.go.set()
    server = ViewServer(source).start()

    async def crowd() -> tuple[list[str], int | None, dict, str]:
        async with aiohttp.ClientSession() as client:
            first = await client.ws_connect(f"{server.url}ws")
            second = await client.ws_connect(f"{server.url}ws")
            hellos = [json.loads((await ws.receive()).data)["type"] for ws in (first, second)]
            try:
                await client.ws_connect(f"{server.url}ws")
                turned = None
            except aiohttp.WSServerHandshakeError as exc:
                turned = exc.status
            async with client.get(f"{server.url}status") as answer:
                status = await answer.json()
            await first.close()
            for _ in range(500):  # the server notices the close on its own thread
                if len(server.clients) < 2:
                    break
                await asyncio.sleep(0.01)
            third = await client.ws_connect(f"{server.url}ws")
            again = json.loads((await third.receive()).data)["type"]
            await third.close()
            await second.close()
            return hellos, turned, status, again

    try:
        hellos, turned, status, again = asyncio.run(crowd())
    finally:
        server.close()
    assert hellos == ["hello", "hello"] and turned == 503
    assert status["clients"] == 2 and status["refused"] == 1 and again == "hello"


class _Gated:
    """A source whose hello waits until the test lets it go: the browser can leave between
    its handshake and its greeting, as one does in a storm of reloads."""

    def __init__(self) -> None:
        self.asked, self.go = threading.Event(), threading.Event()

    def hello(self) -> dict:
        self.asked.set()
        self.go.wait(10)
        return {"type": "hello", "title": "gated", "mode": "live", "creatures": []}

    def greeting(self) -> list[str]:
        return [json.dumps({"type": "trees", "t": 0.0, "trees": {}})]

    async def run(self, clients) -> None:
        pass

    async def serve(self, client) -> None:
        pass


def test_a_browser_gone_before_its_greeting_is_let_go_quietly(caplog):
    """A page reloaded many times leaves sockets closed before the hello reaches them: each is
    let go like one that leaves later (it once raised out of the handler: a traceback in the
    run's output per reload, and the socket kept in the server's set for the rest of the run)."""
    source = _Gated()
    server = ViewServer(source).start()
    try:
        with caplog.at_level(logging.ERROR, logger="aiohttp"):
            browser = _open_socket(server.port)
            assert source.asked.wait(10)  # the handshake is done, the hello not yet sent
            browser.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
            browser.close()  # reset, before the hello
            source.go.set()
            deadline = time.monotonic() + 5
            while server._sockets and time.monotonic() < deadline:
                time.sleep(0.01)
        assert not server._sockets and not server.clients
        assert not [r for r in caplog.records if r.levelno >= logging.ERROR]
    finally:
        server.close()


def test_a_run_restarted_at_once_serves_the_port_its_browser_was_on():
    """A browser left the page (or the run ended under a kiosk's): the server closed the
    connection, which leaves the port in TIME_WAIT for a minute on its side; that must not
    stop the next run serving there (a restarted show once exited with 'port in use' for that
    minute, and the kiosk's page had nothing to reconnect to)."""
    played = replay([{"t": 0.0, "kind": "run", "title": "x", "creatures": ["a"]},
                     {"t": 0.01, "kind": "note", "creature": "a", "time": 0.01, "pitch": 60, "duration": 0.1}])
    server = ViewServer(ReplaySource(played)).start()
    with _open_socket(server.port) as browser:
        browser.sendall(b"\x88\x80\x00\x00\x00\x00")  # a close frame (masked, empty): the page goes away
        while browser.recv(65536):  # the server answers and closes first: its side is in TIME_WAIT
            pass
    server.close()
    assert port_problem(server.port) is None
    ViewServer(ReplaySource(played), server.port).start().close()
    with socket.socket() as taken:  # a port another program listens on is still refused
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        assert port_problem(taken.getsockname()[1]) is not None
        with pytest.raises(OSError):
            ViewServer(ReplaySource(played), taken.getsockname()[1]).start()


def test_creatures_view_on_a_port_in_use_says_so_in_a_sentence(tmp_path, capsys):
    """``creatures view RUN --port P`` where another program listens on P: a sentence naming
    the port and the option, exit 2 (it printed the bare OSError)."""
    from creatures.cli import main

    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        assert main(["view", str(tmp_path), "--port", str(port)]) == 2
    said = capsys.readouterr().err
    assert f"the view's port {port}" in said and "choose another with --port PORT" in said


def test_the_view_port_comes_from_the_option_then_the_config_then_the_default():
    from creatures.cli import DEFAULT_VIEW_PORT, _view_port

    assert _view_port(None, None) is None  # no --view, no [view] port: no view
    assert _view_port(None, 9000) == 9000  # the config's port alone turns it on
    assert _view_port(0, 9000) == 9000 and _view_port(0, None) == DEFAULT_VIEW_PORT  # a bare --view
    assert _view_port(9100, 9000) == 9100


def test_creatures_view_serves_a_run_until_stopped(offline_run):
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    viewer = subprocess.Popen([sys.executable, "-m", "creatures.cli", "view", str(offline_run), "--port", str(port)],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert f"view: open http://127.0.0.1:{port}/" in viewer.stdout.readline()

        async def fetch() -> tuple[int, dict]:
            async with aiohttp.ClientSession() as client:
                async with client.get(f"http://127.0.0.1:{port}/") as page, \
                        client.get(f"http://127.0.0.1:{port}/status") as status:
                    return page.status, await status.json()

        status, counts = asyncio.run(fetch())
        assert status == 200 and counts["clients"] == 0
        messages = asyncio.run(_read(f"http://127.0.0.1:{port}/", 2))
        assert messages[0]["title"] == "exchange" and messages[1]["type"] == "frame"
    finally:
        viewer.terminate()
        _, err = viewer.communicate(timeout=30)
    assert viewer.returncode == 128 + 15 and "stopped by SIGTERM; the view was closed" in err
