"""What a live run hands the view: snapshots taken on the creature's thread, cheaply.

The creature's thread does only this (``[view] fps`` times a second, on a
:class:`~creatures.body.frames.FrameClock`): copy every figure and note object into a
:func:`~creatures.view.snapshot.frame` and put it into a bounded queue without waiting. The
records the page shows reach it through the events log's tap (:attr:`EventLog.taps`), into a
bounded deque. Encoding, websockets and every browser live on the view's own thread
(:mod:`creatures.view.server`), which sends only the latest frame it finds (with every record
since); if that thread falls behind, a full queue drops the frame and counts it
(:attr:`Feed.dropped`), a full deque drops the oldest record and counts it
(:attr:`Feed.events_dropped`): the creatures never wait for a browser.
"""

from __future__ import annotations

import collections
import queue
from typing import Any

import orjson

from creatures.body.frames import FrameClock
from creatures.clock import Clock
from creatures.events import EventLog
from creatures.kinds.base import CreatureKind
from creatures.view.snapshot import SHOWN, Message, bodies, frame, hello

QUEUED_FRAMES = 32
"""Frames waiting for the view's thread (about a second at 30 a second: a loaded machine left
that thread without the CPU for a quarter of a second at a time); one more is dropped and counted."""

QUEUED_EVENTS = 2048
"""Shown records waiting for the view's thread; beyond, the oldest are dropped and counted."""

STATE_EVERY = 2.0
"""Clock seconds between copies of the creatures' learned state (their percept trees, as the
inspector reads them from a saved state): encoding it is the save's instant on the creature's
thread (~0.1 ms for a colony), walking it is the view thread's work."""


class Feed:
    """Snapshots of ``creatures`` for the view, at ``fps`` on ``clock``; ``log``'s shown records."""

    def __init__(self, title: str, creatures: list[CreatureKind], log: EventLog, clock: Clock, fps: float,
                 **status: Any) -> None:
        self.creatures = creatures
        self.hello = hello(title, "live", bodies(creatures), **status)
        self.frames: queue.Queue[Message] = queue.Queue(QUEUED_FRAMES)
        self.events: collections.deque[Message] = collections.deque(maxlen=QUEUED_EVENTS)
        self.clock = FrameClock(fps, clock)
        self.dropped = 0
        self.superseded = 0  # frames the view's thread found older than another waiting
        self.events_dropped = 0
        self.states: tuple[float, list[tuple[str, str, bytes]]] | None = None
        """The latest learned state: its clock time and ``(name, kind, JSON)`` per creature."""
        self._next_state = clock.now()
        self._log = log
        log.taps.append(self.tap)

    def tap(self, record: Message) -> None:
        """An events-log record, on the emitting thread: kept if the page shows its kind."""
        if record["kind"] in SHOWN:
            if len(self.events) == QUEUED_EVENTS:  # a full deque drops its oldest as it appends
                self.events_dropped += 1
            self.events.append(record)

    def offer(self) -> None:
        """A frame, if one fell due, into the queue (dropped and counted when it is full); the
        learned state every :data:`STATE_EVERY` seconds, encoded now (one consistent instant;
        the view's thread reads only bytes)."""
        now = self.clock.clock.now()
        if now >= self._next_state:
            self._next_state = now + STATE_EVERY
            self.states = (now, [(c.name, c.spec.kind, orjson.dumps(c.state(), option=orjson.OPT_SERIALIZE_NUMPY))
                                 for c in self.creatures])
        if not self.clock.due():
            return
        try:
            self.frames.put_nowait(frame(now, self.creatures))
        except queue.Full:
            self.dropped += 1

    def take(self) -> Message | None:
        """On the view's thread: the latest frame waiting (the bodies of older ones are out of
        date: they are skipped and counted in :attr:`superseded`, never sent), carrying every
        shown record since the last take; None when no frame is waiting."""
        latest, waiting = None, 0
        while True:
            try:
                latest = self.frames.get_nowait()
            except queue.Empty:
                break
            waiting += 1
        if latest is None:
            return None
        self.superseded += waiting - 1
        events = []
        while True:  # popleft, never a length check first: the creature's thread appends meanwhile
            try:
                events.append(self.events.popleft())
            except IndexError:
                break
        latest["events"] = events
        latest["status"] = {"dropped": self.dropped, "superseded": self.superseded,
                            "events_dropped": self.events_dropped}
        return latest

    def close(self) -> None:
        if self.tap in self._log.taps:
            self._log.taps.remove(self.tap)
