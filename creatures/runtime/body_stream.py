"""The body stream: every creature's body and inner state, frame by frame, for any renderer.

DESIGN.md says a renderer is just another OSC client; IViHumans keeps its graphics and its
minds in separate processes for the same reason (a picture must never hold up a mind). So
the colony does not draw here: at a chosen frame rate it takes a *snapshot* of each creature
— the joint positions :meth:`~creatures.kinds.base.CreatureKind.shown` draws (in a room, where
it stands there), the joints' local rotations, the end-effector, the note objects in space, the
drives, what it is doing —
and the notes played and heard since the last frame, and hands the :class:`Frame` to
*sinks*: an OSC sender (:class:`~creatures.runtime.stream_sinks.OscStreamSink`, the address
space in ``docs/stream.md``), a file of JSON lines (offline), memory (tests), or a live view
that :meth:`BodyStream.subscribe` s.

On the creature's thread only the snapshot happens (copies of a few small arrays; the
drives as of the last tick, not integrated again). Live, frames go into a bounded queue and a
sender thread of the stream's own encodes and sends them; a frame that finds the queue full
is dropped and counted (:attr:`BodyStream.dropped`), and when the loop was busy past several
frame times only the latest is taken (the others counted as :attr:`BodyStream.skipped`): the
creatures never wait for a renderer. Offline, sinks are called in place, every frame time
taken (time waits for the run there).

Frame ``k`` falls at ``start + k / rate`` on the run's clock. Bodies move only when their
creature ticks, so the body at a frame time is the one its last tick left: offline, frames
that fall before a tick are taken before it (:meth:`BodyStream.advance` with ``before``).
"""

from __future__ import annotations

import math
import queue
import threading
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Protocol

import numpy as np

from creatures.behaviour.motivation import Motivation
from creatures.room.stage import MARKER_JOINTS
from creatures.runtime.network import doing

if TYPE_CHECKING:
    from creatures.kinds.base import CreatureKind
    from creatures.runtime.world import World
    from midi.notes import NoteEvent

NOTES_PER_FRAME = 64
"""Notes played (and notes heard) kept per frame; more between two frames are counted, not sent."""

MARKS_PER_FRAME = 64
"""Note objects in space sent per creature per frame (the nearest renderer needs no more)."""


@dataclass(frozen=True)
class Hello:
    """What a renderer needs once per creature: the skeleton (joint names, parents and offsets
    from the parent, in the order of every pose: with a pose's rotations and its root,
    ``positions[0] - offsets[0]``, forward kinematics gives its positions) and the names of
    the drives (in the order of every frame's)."""

    creature: str
    index: int  # the creature's place in the colony (renderers may space bodies by it, as bodies.py does)
    joints: tuple[str, ...]
    parents: tuple[int, ...]
    drives: tuple[str, ...]
    offsets: tuple[tuple[float, float, float], ...] = ()  # () when the body has no skeleton of its own


@dataclass(frozen=True)
class Pose:
    """One creature at one frame. ``positions`` ``(J, 3)`` are exactly what ``shown()``
    returned; ``rotations`` ``(J, 4)`` the joints' local unit quaternions ``(w, x, y, z)``
    (None for a body without them, and in a room, where the joints are turned to the heading
    and a gait replaces the course: forward kinematics from them would not give the pose);
    ``drives`` as of the creature's last tick."""

    creature: str
    positions: np.ndarray | None
    rotations: np.ndarray | None
    effector: np.ndarray | None
    marks: tuple[tuple[float, float, float, int], ...]
    drives: np.ndarray
    action: str


@dataclass(frozen=True)
class Frame:
    """Every creature at frame ``index`` (clock time ``time``), and the notes since the last."""

    index: int
    time: float
    poses: tuple[Pose, ...]
    played: tuple[tuple[str, int, int, float], ...] = ()  # (creature, pitch, velocity, duration)
    heard: tuple[tuple[str, int, int, float], ...] = ()  # (source, pitch, velocity, duration)


class StreamSink(Protocol):
    """Where frames go. ``hello`` comes first (from the subscriber's thread), then every
    ``frame`` in order (live: on the stream's sender thread), then ``close``."""

    def hello(self, hellos: list[Hello], rate: float) -> None: ...

    def frame(self, frame: Frame) -> None: ...

    def close(self) -> None: ...


def _motivation(creature: "CreatureKind") -> Motivation | None:
    motivation = getattr(creature, "motivation", None)
    return motivation if isinstance(motivation, Motivation) else None


def hello_of(creature: "CreatureKind", index: int) -> Hello:
    """A creature's :class:`Hello`: its skeleton's names where its body has one that matches
    what it draws, a room's marker's for one without a body in a room, else ``j0``, ``j1``, …"""
    figure = creature.shown()
    motivation = _motivation(creature)
    drives = tuple(motivation.names) if motivation is not None else ()
    if figure is None:
        return Hello(creature.name, index, (), (), drives)
    positions, parents = figure
    skeleton = getattr(getattr(creature, "body", None), "skeleton", None)
    parents = tuple(int(p) for p in parents)
    if creature.figure() is None:  # drawn in a room as its marker
        return Hello(creature.name, index, MARKER_JOINTS, parents, drives)
    if skeleton is None or len(skeleton.names) != len(positions):
        return Hello(creature.name, index, tuple(f"j{j}" for j in range(len(positions))), parents, drives)
    offsets = tuple((float(x), float(y), float(z)) for x, y, z in skeleton.offsets)
    return Hello(creature.name, index, tuple(skeleton.names), parents, drives, offsets)


def snapshot(creature: "CreatureKind") -> Pose:
    """A creature as it is now, copied (the sender thread reads it while the creature moves on);
    in a room, where it stands there (:meth:`~creatures.kinds.base.CreatureKind.shown`)."""
    figure = creature.shown()
    positions = rotations = effector = None
    if figure is not None:
        positions = np.array(figure[0], dtype=float)
        pose = getattr(getattr(creature, "body", None), "pose", None)
        rotations = getattr(pose, "rotations", None)
        if rotations is not None and len(rotations) == len(positions) and creature.stage is None:
            rotations = np.array(rotations, dtype=float)
        else:
            rotations = None
        found = creature.effector_of(figure)
        effector = None if found is None else np.array(found, dtype=float)
    marks = tuple((float(p[0]), float(p[1]), float(p[2]), int(pitch))
                  for p, pitch in creature.shown_marks()[:MARKS_PER_FRAME])
    motivation = _motivation(creature)
    drives = motivation.levels.copy() if motivation is not None else np.zeros(0)
    return Pose(creature.name, positions, rotations, effector, marks, drives, doing(creature) or "none")


@dataclass
class _Notes:
    """Notes between two frames, at most :data:`NOTES_PER_FRAME` of each; the rest counted."""

    played: list[tuple[str, int, int, float]] = field(default_factory=list)
    heard: list[tuple[str, int, int, float]] = field(default_factory=list)
    unsent: int = 0

    def add(self, into: list, who: str, note: "NoteEvent") -> None:
        if len(into) < NOTES_PER_FRAME:
            into.append((who, int(note.pitch), int(note.velocity), float(note.duration)))
        else:
            self.unsent += 1


class BodyStream:
    """Frames of ``world``'s creatures at ``rate`` per second from clock time ``start``.

    ``threaded``: live, a sender thread takes frames from a queue of ``queue_size``;
    otherwise (offline) each frame goes to the sinks at once and every frame time is taken.
    """

    def __init__(self, world: "World", rate: float, *, start: float = 0.0, threaded: bool = True,
                 queue_size: int = 64) -> None:
        if not (math.isfinite(rate) and rate > 0):
            raise ValueError(f"stream rate must be a positive number, got {rate!r}")
        self.world = world
        self.rate = float(rate)
        self.start = float(start)
        self.hellos = [hello_of(c, i) for i, c in enumerate(world.creatures)]
        self.sinks: list[StreamSink] = []
        self.next_index = 0  # the first frame not yet taken
        self.frames = 0  # frames taken
        self.dropped = 0  # frames that found the sender's queue full
        self.skipped = 0  # frame times passed while the loop was busy (live: only the latest is taken)
        self.sink_errors = 0  # frames a sink raised on (the others still got them)
        self._notes = _Notes()
        world.listeners.append(lambda creature, note: self._notes.add(self._notes.played, creature, note))
        world.hearing.append(lambda source, note: self._notes.add(self._notes.heard, source, note))
        self._queue: queue.Queue[Frame | None] | None = None
        self._thread: threading.Thread | None = None
        if threaded:
            self._queue = queue.Queue(queue_size)
            self._thread = threading.Thread(target=self._send, name="body stream", daemon=True)
            self._thread.start()

    def begin(self, start: float) -> None:
        """Frames count from clock time ``start`` (a live run's first tick: setting up took time)."""
        self.start, self.next_index = float(start), 0

    def subscribe(self, sink: StreamSink) -> None:
        """``sink`` gets the skeletons now and every frame from the next on."""
        sink.hello(self.hellos, self.rate)
        self.sinks = [*self.sinks, sink]  # replaced, not changed: the sender thread iterates the old list

    @property
    def notes_unsent(self) -> int:
        return self._notes.unsent

    def last_due(self, t: float, *, before: bool = False) -> int:
        """The index of the last frame at or before ``t`` (strictly before, with ``before``)."""
        x = (t - self.start) * self.rate
        return math.ceil(x - 1e-9) - 1 if before else math.floor(x + 1e-9)

    def advance(self, t: float, *, before: bool = False) -> int:
        """Take every frame due by clock time ``t`` (on the creature's thread); how many were
        taken. ``before``: only those strictly before ``t`` (offline, ahead of the tick at ``t``)."""
        last = self.last_due(t, before=before)
        if last < self.next_index:
            return 0
        if self._queue is not None and last > self.next_index:  # live: the latest pose only
            self.skipped += last - self.next_index
            self.next_index = last
        poses = tuple(snapshot(c) for c in self.world.creatures)
        notes, self._notes = self._notes, _Notes(unsent=self._notes.unsent)
        taken = 0
        for index in range(self.next_index, last + 1):
            frame = Frame(index, self.start + index / self.rate, poses, tuple(notes.played), tuple(notes.heard))
            notes = _Notes()  # the notes go with the first of frames taken together
            self._hand_over(frame)
            taken += 1
        self.next_index = last + 1
        self.frames += taken
        return taken

    def _hand_over(self, frame: Frame) -> None:
        if self._queue is None:
            self._deliver(frame)
            return
        try:
            self._queue.put_nowait(frame)
        except queue.Full:
            self.dropped += 1

    def _deliver(self, frame: Frame) -> None:
        for sink in self.sinks:
            try:
                sink.frame(frame)
            except Exception:  # one renderer's failure must not starve the others
                self.sink_errors += 1

    def _send(self) -> None:
        assert self._queue is not None
        while (frame := self._queue.get()) is not None:
            self._deliver(frame)

    def counts(self) -> dict[str, int]:
        """What was taken, dropped (queue full), skipped (loop busy) and not sent (notes, sink errors)."""
        return {"frames": self.frames, "dropped": self.dropped, "skipped": self.skipped,
                "notes_unsent": self.notes_unsent, "sink_errors": self.sink_errors}

    def close(self) -> None:
        """The frames queued are sent (bounded wait), then every sink is closed."""
        if self._queue is not None and self._thread is not None:
            try:
                self._queue.put(None, timeout=5)
            except queue.Full:
                pass
            self._thread.join(5)
        for sink in self.sinks:
            sink.close()
