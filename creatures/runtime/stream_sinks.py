"""Where the body stream goes (:mod:`creatures.runtime.body_stream`): OSC to renderers, a file
of JSON lines (offline runs: ``stream.jsonl``), or memory (tests, a live view in-process).

The OSC address space is documented in ``docs/stream.md``; every creature's frame is one
bundle (one datagram: a renderer takes a body in whole), the colony's frame marker and notes
another, and the skeletons are said again every :data:`HELLO_EVERY` seconds of stream time so
a renderer started late learns them without asking.
"""

from __future__ import annotations

import json
import os
import socket
import struct
from pathlib import Path

import numpy as np

from creatures.runtime.body_stream import Frame, Hello, Pose
from creatures.runtime.osc_wire import bundle, floats, head, message, osc_string

HELLO_EVERY = 1.0
"""Seconds of stream time between two sayings of the skeletons (and at the first frame)."""

FRAME = head("/colony/frame", "id")

INDEX_WRAP = 2**31
"""The frame index is an OSC int32: it wraps to 0 here (after 103 days at 240 frames a second,
414 at 60) rather than stopping the stream; the frame's time goes on."""

MARK = np.dtype([("x", ">f4"), ("y", ">f4"), ("z", ">f4"), ("pitch", ">i4")])


class MemoryStreamSink:
    """Keeps every frame (and the hellos) in lists: tests, and a view in the same process."""

    def __init__(self) -> None:
        self.hellos: list[Hello] = []
        self.rate = 0.0
        self.frames: list[Frame] = []

    def hello(self, hellos: list[Hello], rate: float) -> None:
        self.hellos, self.rate = list(hellos), rate

    def frame(self, frame: Frame) -> None:
        self.frames.append(frame)

    def close(self) -> None:
        pass


def _array(values: np.ndarray | None) -> list | None:
    return None if values is None else values.tolist()


def pose_json(pose: Pose, drives: tuple[str, ...]) -> dict:
    """A pose as JSON-able data (floats kept exactly: JSON writes a float64 in full)."""
    return {"creature": pose.creature, "positions": _array(pose.positions), "rotations": _array(pose.rotations),
            "effector": _array(pose.effector), "marks": [list(m) for m in pose.marks],
            "drives": dict(zip(drives, pose.drives.tolist())), "action": pose.action}


class JsonLinesStreamSink:
    """The stream as JSON lines: a ``hello`` line, then one ``frame`` line per frame."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.file = path.open("w", encoding="utf-8")
        self.drives: dict[str, tuple[str, ...]] = {}

    def hello(self, hellos: list[Hello], rate: float) -> None:
        self.drives = {h.creature: h.drives for h in hellos}
        self._write({"kind": "hello", "rate": rate, "creatures": [
            {"creature": h.creature, "index": h.index, "joints": list(h.joints), "parents": list(h.parents),
             "offsets": [list(o) for o in h.offsets], "drives": list(h.drives)} for h in hellos]})

    def frame(self, frame: Frame) -> None:
        self._write({"kind": "frame", "index": frame.index, "time": frame.time,
                     "poses": [pose_json(p, self.drives.get(p.creature, ())) for p in frame.poses],
                     "played": [list(n) for n in frame.played], "heard": [list(n) for n in frame.heard]})

    def _write(self, record: dict) -> None:
        self.file.write(json.dumps(record, allow_nan=False) + "\n")

    def close(self) -> None:
        self.file.close()


def read_stream(path: str | os.PathLike) -> tuple[dict, list[dict]]:
    """A ``stream.jsonl``: its hello, and its frames in order (the path as a user types it, or a Path)."""
    hello: dict = {}
    frames = []
    with Path(path).open(encoding="utf-8") as lines:
        for line in lines:
            record = json.loads(line)
            if record["kind"] == "hello":
                hello = record
            else:
                frames.append(record)
    return hello, frames


class _Heads:
    """One creature's message heads, made once (the address and type tags never change; a
    head whose tags depend on a count is made the first time that count is seen)."""

    def __init__(self, hello: Hello) -> None:
        base = f"/body/{hello.creature}/"
        joints = len(hello.joints)
        self.base = base
        self.pose = head(base + "pose", "d" + "f" * 3 * joints)
        self.rotation = head(base + "rotation", "f" * 4 * joints)
        self.effector = head(base + "effector", "fff")
        self.drives = head(base + "drives", "f" * len(hello.drives)) if hello.drives else None
        self.action = head(base + "action", "s")
        self.played = head(base + "played", "iif")
        self._marks: dict[int, bytes] = {}
        self._actions: dict[str, bytes] = {}
        skeleton = [message(base + "skeleton", *[x for name, parent in zip(hello.joints, hello.parents)
                                                 for x in (name, parent)])]
        if hello.offsets:
            skeleton.append(head(base + "offsets", "f" * 3 * joints) + floats(np.array(hello.offsets)))
        if hello.drives:
            skeleton.append(message(base + "drive_names", *hello.drives))
        self.hello = bundle(skeleton)

    def marks(self, count: int) -> bytes:
        if count not in self._marks:
            self._marks[count] = head(self.base + "marks", "fffi" * count)
        return self._marks[count]

    def action_of(self, action: str) -> bytes:
        if action not in self._actions:
            if len(self._actions) > 256:  # names come from the creature's own tuples: a few dozen
                self._actions.clear()
            self._actions[action] = self.action + osc_string(action)
        return self._actions[action]


class OscStreamSink:
    """Sends every frame as OSC to ``targets`` (``(host, port)``), UDP, never blocking: a send
    the kernel refuses (its buffer full, nobody listening) is counted in :attr:`send_errors`."""

    def __init__(self, targets: list[tuple[str, int]]) -> None:
        self.targets = targets
        self.socket = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.socket.setblocking(False)
        self.heads: dict[str, _Heads] = {}
        self.colony_hello = b""
        self.next_hello = -float("inf")
        self.sent_bytes = 0
        self.send_errors = 0

    def hello(self, hellos: list[Hello], rate: float) -> None:
        self.heads = {h.creature: _Heads(h) for h in hellos}
        self.colony_hello = message("/colony/hello", float(rate), len(hellos), *[h.creature for h in hellos])

    def frame(self, frame: Frame) -> None:
        if frame.time >= self.next_hello:
            self.next_hello = frame.time + HELLO_EVERY
            self._send(self.colony_hello)
            for heads in self.heads.values():
                self._send(heads.hello)
        colony = [FRAME + struct.pack(">id", frame.index % INDEX_WRAP, frame.time)]
        colony += [message("/colony/heard", source, pitch, velocity, duration)
                   for source, pitch, velocity, duration in frame.heard]
        played: dict[str, list[bytes]] = {}
        for creature, pitch, velocity, duration in frame.played:
            heads = self.heads.get(creature)
            if heads is not None:
                played.setdefault(creature, []).append(heads.played + struct.pack(">iif", pitch, velocity, duration))
        self._send(bundle(colony))
        for pose in frame.poses:
            heads = self.heads.get(pose.creature)
            if heads is not None:
                self._send(bundle(self.encode(heads, pose, frame.time) + played.get(pose.creature, [])))

    @staticmethod
    def encode(heads: _Heads, pose: Pose, t: float) -> list[bytes]:
        """One creature's messages for a frame at ``t``."""
        messages = []
        if pose.positions is not None:
            messages.append(heads.pose + struct.pack(">d", t) + floats(pose.positions))
        if pose.rotations is not None:
            messages.append(heads.rotation + floats(pose.rotations))
        if pose.effector is not None:
            messages.append(heads.effector + floats(pose.effector))
        if pose.marks:
            messages.append(heads.marks(len(pose.marks)) + np.array(pose.marks, dtype=MARK).tobytes())
        if heads.drives is not None and len(pose.drives):
            messages.append(heads.drives + floats(pose.drives))
        messages.append(heads.action_of(pose.action))
        return messages

    def _send(self, dgram: bytes) -> None:
        for target in self.targets:
            try:
                self.sent_bytes += self.socket.sendto(dgram, target)
            except OSError:  # full buffer, nobody there (ICMP refused): the next frame tries again
                self.send_errors += 1

    def close(self) -> None:
        self.socket.close()
