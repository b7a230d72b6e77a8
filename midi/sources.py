"""Where creatures hear notes from: live ports, ``.mid`` files, raw byte streams, lists.

Every source has one method, ``poll()``: the timed messages that have arrived (or fallen due)
by the clock's present, oldest first, without ever blocking — a creature's ear is read once a
tick, like its other percepts. Times are seconds on the run's clock. Pair them into whole
notes with :class:`midi.notes.NotePairer` where a creature wants notes rather than onsets.

A file can play in real time against a :class:`~creatures.clock.WallClock`, or as fast as
possible against a :class:`~creatures.clock.SimulatedClock` by advancing the clock to
``next_due()``.
"""

from __future__ import annotations

import bisect
import os
from typing import Callable, Iterable, Protocol

import mido

from creatures.clock import Clock
from midi.files import read_messages
from midi.notes import NoteEvent, TimedMessage, to_messages
from midi.parser import StreamParser
from midi.ports import MidoInputs, PortFactory, ResilientPort


class NoteSource(Protocol):
    def poll(self) -> list[TimedMessage]:
        """Messages that arrived or fell due by now, oldest first; never blocks."""
        ...


class ListSource:
    """Timed messages (or notes) replayed against a clock, starting when the source is made.

    A message at time ``t`` in the list comes out once ``clock.now() >= start + t`` and is
    stamped ``start + t``.
    """

    def __init__(self, items: Iterable[TimedMessage] | Iterable[NoteEvent], clock: Clock) -> None:
        items = list(items)
        if items and isinstance(items[0], NoteEvent):
            items = to_messages(items)
        self.clock = clock
        self.start = clock.now()
        self._items: list[TimedMessage] = sorted(
            ((self.start + t, msg) for t, msg in items), key=lambda item: item[0]
        )
        self._times = [t for t, _ in self._items]
        self._next = 0

    def poll(self) -> list[TimedMessage]:
        stop = bisect.bisect_right(self._times, self.clock.now(), lo=self._next)
        due = self._items[self._next:stop]
        self._next = stop
        return due

    def next_due(self) -> float | None:
        """Clock time of the next message, or None when the list is played out."""
        return self._times[self._next] if self._next < len(self._times) else None

    @property
    def exhausted(self) -> bool:
        return self._next >= len(self._items)


class FileSource(ListSource):
    """A ``.mid`` file played against a clock (see :class:`ListSource`)."""

    def __init__(self, path: str | os.PathLike, clock: Clock) -> None:
        super().__init__(read_messages(path), clock)
        self.path = path


class PortSource:
    """A live MIDI input: an open port (e.g. :class:`midi.ports.MemoryInput`) or a device
    found by exact name or pattern and kept open across faults (:class:`ResilientPort`).

    ``virtual=True`` creates a port others connect to, where the backend allows it (JACK
    here; ALSA sequencer elsewhere); a virtual port cannot vanish, so it is opened directly.
    """

    def __init__(
        self,
        port: str | mido.ports.BaseInput,
        clock: Clock,
        *,
        virtual: bool = False,
        factory: PortFactory | None = None,
        retry_interval: float = 1.0,
    ) -> None:
        self.clock = clock
        factory = factory or MidoInputs()
        if isinstance(port, str) and not virtual:
            self.port: ResilientPort | mido.ports.BaseInput = ResilientPort(
                port, factory, clock, retry_interval=retry_interval
            )
        elif isinstance(port, str):
            self.port = factory.open(port, virtual=True)
        else:
            self.port = port

    def poll(self) -> list[TimedMessage]:
        now = self.clock.now()
        if isinstance(self.port, ResilientPort):
            return [(now, msg) for msg in self.port.pending()]
        return [(now, msg) for msg in self.port.iter_pending()]

    def close(self) -> None:
        self.port.close()


class ByteSource:
    """A raw MIDI byte stream, framed with running status by :class:`StreamParser`.

    Bytes come from ``feed()`` or from ``read``, a callable returning whatever bytes are
    available now (``b""`` for none) — e.g. a non-blocking socket or pipe read.
    """

    def __init__(self, clock: Clock, read: Callable[[], bytes] | None = None) -> None:
        self.clock = clock
        self.read = read
        self.parser = StreamParser()

    @property
    def malformed_bytes(self) -> int:
        return self.parser.malformed_bytes

    def feed(self, data: bytes) -> None:
        self.parser.feed(data)

    def poll(self) -> list[TimedMessage]:
        if self.read is not None:
            self.parser.feed(self.read())
        now = self.clock.now()
        return [(now, msg) for msg in self.parser.pending()]
