"""One room across processes (issue 21): four live processes of 50 creatures each share one
room on loopback, found by mDNS (zeroconf) with no peer configured, on one Ableton Link beat;
one is SIGKILLed and started again, and its creatures resume where they stood.

Multicast (mDNS, Link) runs only inside a network namespace this test creates and deletes
(../shared/ENVIRONMENT.md: never on the machine's own interfaces), so it needs root and
``ip``. The processes run in real time, so the test is ``realtime``: run alone (the README's
second test command), as the JACK tests are.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
import uuid
from pathlib import Path

import numpy as np
import pytest

from bench.room import SINGER
from creatures.runtime.live import HOUSEKEEPING_EVERY

pytestmark = [pytest.mark.realtime, pytest.mark.slow]

PROCESSES = 4
EACH = 50
TICK = 0.04
MAX_SPEED = 1.0
TRAVEL = MAX_SPEED * TICK
"""One tick's travel: the bound on how far a process's view of another's creature may be from
where that creature stands."""
STEADY = 4.0
"""Seconds the whole room runs before the kill (the window positions are compared in)."""
TIMEOUT = 2.0
SAVE_EVERY = 3.0

CONFIG = """
title = "shared room {k}"
seed = {seed}
tick = {tick}
save_every = {save_every}
[audio]
output = false
sample_rate = 22050
[input]
generate = "none"
[output]
frames = false
[room]
width = 20.0
depth = 20.0
report_every = 0.08
share = {{ room = "gallery", link = true, tempo = 100.0, timeout = {timeout} }}
"""


def _namespace_or_skip() -> str:
    if os.geteuid() != 0 or shutil.which("ip") is None:
        pytest.skip("needs root and iproute2's ip to make a network namespace for multicast")
    name = f"creatures-{uuid.uuid4().hex[:8]}"
    try:
        for command in (["netns", "add", name], ["-n", name, "link", "set", "lo", "up"],
                        ["-n", name, "link", "set", "lo", "multicast", "on"],
                        ["-n", name, "route", "add", "224.0.0.0/4", "dev", "lo"]):
            subprocess.run(["ip", *command], check=True, capture_output=True, timeout=10)
    except (subprocess.CalledProcessError, subprocess.TimeoutExpired) as exc:
        subprocess.run(["ip", "netns", "del", name], capture_output=True)
        pytest.skip(f"cannot make a network namespace here ({exc})")
    return name


def _start(namespace: str, config: Path, log: Path, state: Path) -> subprocess.Popen:
    with open(log.with_suffix(".out"), "a") as out:  # what it printed, read when it fails
        return subprocess.Popen(["ip", "netns", "exec", namespace, sys.executable, "-X", "faulthandler", "-c",
                                 "import sys; from creatures.cli import main; sys.exit(main(sys.argv[1:]))",
                                 "run", str(config), "--log", str(log), "--state", str(state)],
                                stdout=out, stderr=subprocess.STDOUT, env={**os.environ, "PYTHONUNBUFFERED": "1"})


def _events(path: Path) -> list[dict]:
    """The events written so far (a line still being written is not one yet)."""
    text = path.read_text()
    return [json.loads(line) for line in text[:text.rfind("\n") + 1].splitlines() if line.strip()]


def _wait(what: str, ready, limit: float = 90.0) -> None:
    """Poll the logs (flushed each second) until ``ready()``: the scene moves on when the room
    is in the state it needs, not after a guessed time."""
    deadline = time.monotonic() + limit
    while not ready():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out waiting until {what}")
        time.sleep(0.2)


def _last_room(path: Path) -> dict | None:
    if not path.exists():
        return None
    rooms = [e for e in _events(path) if e["kind"] == "room"]
    return rooms[-1] if rooms else None


def _all_seen(paths: list[Path]) -> bool:
    last = [_last_room(p) for p in paths]
    return all(e is not None and len(e["others"]) == (PROCESSES - 1) * EACH for e in last)


@pytest.fixture(scope="module")
def room(tmp_path_factory):
    """The scene: four processes until each sees all 200, STEADY s more, the fourth SIGKILLed,
    its creatures gone from the others' rooms, then started again until all see all 200 again."""
    root = tmp_path_factory.mktemp("shared")
    namespace = _namespace_or_skip()
    logs = [root / f"p{k}.jsonl" for k in range(PROCESSES)]
    runs: list[subprocess.Popen] = []
    try:
        configs = []
        for k in range(PROCESSES):
            path = root / f"p{k}.toml"
            path.write_text(CONFIG.format(k=k, seed=k + 1, tick=TICK, save_every=SAVE_EVERY, timeout=TIMEOUT)
                            + SINGER.format(name=f"p{k}", n=EACH, max_speed=MAX_SPEED, pitch=60 + 3 * k))
            configs.append(path)
        runs = [_start(namespace, configs[k], logs[k], root / f"state{k}") for k in range(PROCESSES)]
        _wait("every process sees the other 150", lambda: _all_seen(logs))
        time.sleep(STEADY)  # the scene's length, not a measurement: the test reads the logs
        runs[-1].send_signal(signal.SIGKILL)
        runs[-1].wait(10)
        killed_at = time.time()
        saved = root / "saved"
        shutil.copytree(root / f"state{PROCESSES - 1}", saved)  # what the restart will resume from
        _wait("the survivors saw the killed process leave", lambda: all(
            any(e["kind"] == "room peer left" for e in _events(path) if e["t"] > 0) for path in logs[:-1]))
        shutil.move(logs[-1], root / "killed.jsonl")
        runs[-1] = _start(namespace, configs[-1], logs[-1], root / f"state{PROCESSES - 1}")
        _wait("every process sees all 200 again", lambda: _all_seen(logs))
        time.sleep(1.0)
        for run in runs:
            run.send_signal(signal.SIGTERM)
        for run in runs:
            run.wait(60)
        outputs = [path.with_suffix(".out").read_text() for path in logs]
    finally:
        for run in runs:
            if run.poll() is None:
                run.kill()
        subprocess.run(["ip", "netns", "del", namespace], capture_output=True)
    assert [run.returncode for run in runs] == [0] * PROCESSES, outputs
    return {"logs": [_events(path) for path in logs], "saved": saved, "killed_at": killed_at, "outputs": outputs}


def _rooms(log: list[dict]) -> list[dict]:
    return [e for e in log if e["kind"] == "room"]


def _owner_track(log: list[dict]) -> tuple[list[str], np.ndarray, np.ndarray]:
    names = next(e for e in log if e["kind"] == "run")["creatures"]
    rooms = _rooms(log)
    return names, np.array([e["unix"] for e in rooms]), np.array([e["pos"] for e in rooms])


def test_every_process_sees_all_two_hundred(room):
    """Before the kill and at the end each process has the other 150 in its room, and they are
    the others' names exactly."""
    everyone = {f"p{k}-{i}" for k in range(PROCESSES) for i in range(EACH)}
    for k, log in enumerate(room["logs"][:-1]):
        mine = {f"p{k}-{i}" for i in range(EACH)}
        before = [e for e in _rooms(log) if e["unix"] < room["killed_at"] - 1.0]
        assert before and all(set(e["others"]) == everyone - mine for e in before[-5:]), k
        assert set(_rooms(log)[-3]["others"]) == everyone - mine, k
    last = room["logs"][-1]
    assert set(_rooms(last)[-3]["others"]) == everyone - {f"p3-{i}" for i in range(EACH)}


def test_every_process_hears_the_others_notes(room):
    """Notes cross processes too: each process hears notes from creatures of every other."""
    for k, log in enumerate(room["logs"][:-1]):
        heard = {e["source"].split("-")[0] for e in log if e["kind"] == "heard"}
        assert heard >= {f"p{j}" for j in range(PROCESSES) if j != k}, (k, heard)


def _late_spans(log: list[dict]) -> np.ndarray:
    """(n, 2) Unix times between which the process had ticks begin late: each ``timing`` record
    whose count of late ticks grew covers the housekeeping second before it (and a tick)."""
    rooms = _rooms(log)
    epoch = float(np.median([e["unix"] - e["t"] for e in rooms if "unix" in e]))
    spans, seen = [], 0
    for e in log:
        if e["kind"] == "timing" and e["late_ticks"] > seen:
            seen = e["late_ticks"]
            spans.append((epoch + e["t"] - HOUSEKEEPING_EVERY - TICK, epoch + e["t"] + TICK))
    return np.array(spans).reshape(-1, 2)


def _within(u: float, spans: np.ndarray) -> bool:
    return bool(np.any((spans[:, 0] <= u) & (u <= spans[:, 1])))


def test_positions_agree_within_one_ticks_travel(room):
    """Where a process sees another's creature is where that creature stands (the owner's own
    record at the same Unix time), before the kill and after the restart, the restarted process
    seeing and seen too: every view within one tick's travel (max_speed × tick), after each
    process's first two seconds (start-up compiles make its first ticks late), while both
    processes keep time. A process whose ticks begin late publishes (or looks) as late: on a
    loaded two-core machine one run had ticks up to 125 ms late (p99) and views 75 mm off then,
    so the seconds either logged late ticks in are left out of the bound — and all views, those
    seconds too, must still hold it at the 99th percentile. Measured with the compiled crowd:
    74,650 views, p99 2.6 mm, worst 14.9 mm of the 40 mm; on the loaded machine p99 14.5 mm."""
    errors, on_time = [], []
    tracks = [_owner_track(log) for log in room["logs"]]
    late = [_late_spans(log) for log in room["logs"]]
    for k, log in enumerate(room["logs"]):
        for j, (names, unix, pos) in enumerate(tracks):
            if j == k:
                continue
            index = {n: i for i, n in enumerate(names)}
            for e in _rooms(log):
                u = e["unix"]
                if e["t"] < 2.0 or not unix[0] + 2.0 < u < unix[-1]:
                    continue
                kept = not _within(u, late[k]) and not _within(u, late[j])
                for name, (x, y) in e["others"].items():
                    if name in index:
                        i = index[name]
                        errors.append(np.hypot(x - np.interp(u, unix, pos[:, i, 0]), y - np.interp(u, unix, pos[:, i, 1])))
                        on_time.append(kept)
    errors, on_time = np.array(errors), np.array(on_time)
    assert on_time.sum() > 10_000
    print(f"{len(errors)} views ({on_time.sum()} while both kept time): p50 {np.median(errors) * 1e3:.2f} mm, "
          f"p99 {np.percentile(errors, 99) * 1e3:.2f} mm, worst {errors.max() * 1e3:.2f} mm, "
          f"worst on time {errors[on_time].max() * 1e3:.2f} mm (one tick's travel {TRAVEL * 1e3:.0f} mm)")
    assert np.percentile(errors, 99) <= TRAVEL
    assert errors[on_time].max() <= TRAVEL


def test_a_killed_process_leaves_and_rejoins(room):
    """The survivors see the killed process's creatures leave after the timeout (no bye: it
    was SIGKILLed), and come back when it starts again, under a new owner."""
    victims = {f"p3-{i}" for i in range(EACH)}
    for log in room["logs"][:-1]:
        left = [e for e in log if e["kind"] == "room peer left"]
        assert [e["why"] for e in left][:1] == ["silent"]
        gone = left[0]["t"]
        during = [e for e in _rooms(log) if gone < e["t"] < gone + 1.0]
        assert during and all(not victims & set(e["others"]) for e in during)
        joins = [e for e in log if e["kind"] == "room peer" and e["t"] > gone]
        assert joins and joins[0]["owner"] != left[0]["owner"]
        assert victims <= set(_rooms(log)[-3]["others"])


def test_the_restarted_creatures_resume_where_they_stood(room):
    """The restarted process restores every creature and puts each where its last saved state
    had it (within the first tick's travel), not at a fresh random place."""
    log = room["logs"][-1]
    names = next(e for e in log if e["kind"] == "run")["restored"]
    assert len(names) == EACH
    first = np.array(_rooms(log)[0]["pos"])
    saved = np.array([json.loads((room["saved"] / f"{name}.json").read_text())["place"]["at"] for name in names])
    moved = np.hypot(*(first - saved).T)
    assert moved.max() <= TRAVEL + 1e-6, moved.max()


def test_one_beat_across_the_room(room):
    """Every process's Link beat, read at the same Unix times, is in phase within 5 ms (Link
    shares tempo and phase; each process counts whole beats from its own start)."""
    fits = []
    for log in room["logs"][:-1]:
        rooms = [e for e in _rooms(log) if e["t"] > 3.0]
        unix, beat = np.array([e["unix"] for e in rooms]), np.array([e["beat"] for e in rooms])
        fits.append((unix, beat))
    common = np.linspace(max(u[0] for u, _ in fits), min(u[-1] for u, _ in fits), 50)
    beats = np.array([np.interp(common, u, b) for u, b in fits])
    phase = (beats - beats[0] + 0.5) % 1.0 - 0.5  # each against the first, in (-1/2, 1/2] of a beat
    spread = (phase.max(axis=0) - phase.min(axis=0)) * 60.0 / 100.0
    assert spread.max() <= 0.005, spread.max()


def test_notes_land_on_the_senders_beat(room):
    """A note crossing processes is placed by its Link beat (issue 21: "notes are time-tagged
    against it"): where each process heard another's note start (its "heard" event, on its own
    clock) is, on its own Link timeline, the phase of the beat the sender played it on (its
    "note" event, on the sender's clock and timeline) within 5 ms, for 95 % of the notes and
    within 20 ms for all of them. Each side's beat is read off its own track of (Unix time,
    beat) in its room events; each clock is put on Unix time by its run's epoch. (Here the
    processes share one machine's clock, so placing by Unix time would land there too; that
    the beat places a note when two machines' clocks disagree is tests/test_room_share.py's.)
    Measured: 775 notes, worst 0.03 ms."""
    def track(log: list[dict]) -> tuple[float, np.ndarray, np.ndarray]:
        epoch = next(e for e in log if e["kind"] == "run")["epoch"]
        rooms = [e for e in _rooms(log) if e["t"] > 3.0]
        return epoch, np.array([e["unix"] for e in rooms]), np.array([e["beat"] for e in rooms])

    tracks = [track(log) for log in room["logs"][:-1]]
    played: dict[str, list[tuple[float, float]]] = {}  # each creature's notes: (Unix time, beat) as sent
    for (epoch, unix, beat), log in zip(tracks, room["logs"][:-1]):
        for e in log:
            if e["kind"] == "note" and unix[0] < epoch + e["time"] < unix[-1]:
                u = epoch + e["time"]
                played.setdefault(e["creature"], []).append((u, np.interp(u, unix, beat)))
    offsets = []
    for (epoch, unix, beat), log in zip(tracks, room["logs"][:-1]):
        for e in log:
            u = epoch + e["time"] if e["kind"] == "heard" else None
            if u is None or not unix[0] < u < unix[-1] or e["source"] not in played:
                continue
            sent_at, sent_beat = min(played[e["source"]], key=lambda note: abs(note[0] - u))  # the note it is
            if abs(sent_at - u) > 0.25:  # not one the sender logged in its window
                continue
            phase = (sent_beat - np.interp(u, unix, beat) + 0.5) % 1.0 - 0.5  # beats
            offsets.append(abs(phase) * 60.0 / 100.0)  # seconds at the room's 100 BPM
    offsets = np.array(offsets)
    assert len(offsets) > 100
    print(f"{len(offsets)} notes: p50 {np.median(offsets) * 1e3:.2f} ms, p95 {np.percentile(offsets, 95) * 1e3:.2f} ms, "
          f"worst {offsets.max() * 1e3:.2f} ms")
    assert np.percentile(offsets, 95) <= 0.005
    assert offsets.max() <= 0.020
