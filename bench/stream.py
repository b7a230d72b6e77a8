"""The body stream's cost: 50 creatures (exchange bodies, 19 joints each) streamed at 60
frames a second as OSC to a loopback socket, through the live path (snapshots on the calling
thread, a sender thread encoding and sending).

Measured as CPU time of the whole process (both threads) per second of stream: 60 frames'
worth of snapshots, encoding and ``sendto`` calls, as a share of one core. Target ≤ 10 %
(issue 19). Beside it, the same frames encoded with python-osc's builders (what
``midi.osc`` uses for notes): the ratio says what building the messages from parts made once
(:mod:`creatures.runtime.osc_wire`) saves (conservatively: the python-osc side is the
encoding alone, ours snapshots and sends too).
"""

from __future__ import annotations

import socket
import tempfile
import time
from pathlib import Path

from pythonosc.osc_bundle_builder import IMMEDIATELY, OscBundleBuilder
from pythonosc.osc_message_builder import OscMessageBuilder

from bench import Row
from creatures.clock import SimulatedClock
from creatures.events import EventLog
from creatures.runtime.body_stream import BodyStream, Frame, snapshot
from creatures.runtime.schema import load_installation
from creatures.runtime.session import Session
from creatures.runtime.stream_sinks import OscStreamSink
from midi.sinks import MemorySink

CREATURES = 50
RATE = 60.0


def _colony(directory: Path) -> Session:
    config = directory / "fifty.toml"
    config.write_text('title = "fifty"\ntick = 0.02\n' + "".join(
        f'[[creature]]\nname = "c{i}"\nkind = "exchange"\n' for i in range(CREATURES)))
    clock = SimulatedClock()
    session = Session(load_installation(config), clock, EventLog(keep_in_memory=0), MemorySink())
    for step in range(1, 26):  # half a second: every body posed, moving
        clock.advance_to(step * 0.02)
        session.step(step * 0.02, 441, None, audio=False)
    return session


def _python_osc(frame: Frame) -> int:
    """The frame's per-creature bundles built with python-osc (pose, rotation, effector, drives,
    action): the same content, the builders' way."""
    size = 0
    for pose in frame.poses:
        bundle = OscBundleBuilder(IMMEDIATELY)
        for address, args in ((f"/body/{pose.creature}/pose", [frame.time, *pose.positions.ravel().tolist()]),
                              (f"/body/{pose.creature}/rotation", pose.rotations.ravel().tolist()),
                              (f"/body/{pose.creature}/effector", pose.effector.tolist()),
                              (f"/body/{pose.creature}/drives", pose.drives.tolist()),
                              (f"/body/{pose.creature}/action", [pose.action])):
            builder = OscMessageBuilder(address)
            for arg in args:
                builder.add_arg(arg)
            bundle.add_content(builder.build())
        size += len(bundle.build().dgram)
    return size


def run(quick: bool) -> list[Row]:
    seconds = 2.0 if quick else 10.0
    frames = int(seconds * RATE)
    with tempfile.TemporaryDirectory() as tmp:
        session = _colony(Path(tmp))
    receiver = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)  # bound, never read: the kernel drops
    receiver.bind(("127.0.0.1", 0))
    stream = BodyStream(session.world, RATE, start=0.0, queue_size=frames + 1)
    sink = OscStreamSink([receiver.getsockname()])
    stream.subscribe(sink)
    cpu0 = time.process_time()
    for k in range(frames):
        stream.advance(k / RATE)
    stream.close()  # the sender thread drains the queue
    cpu = time.process_time() - cpu0
    assert stream.frames == frames and stream.dropped == 0, stream.counts()
    share = cpu / seconds
    # The baseline: the last frame encoded by python-osc as many times, on this thread.
    last = Frame(0, 0.0, tuple(snapshot(c) for c in session.creatures))
    cpu0 = time.process_time()
    for _ in range(frames):
        _python_osc(last)
    theirs = (time.process_time() - cpu0) / seconds
    receiver.close()
    return [Row(f"body stream of {CREATURES} creatures at {RATE:g} Hz (snapshot, encode, send)", 100 * share,
                "% of a core", target=10.0, higher_is_better=False, baseline="python-osc builders",
                ratio=theirs / share)]
