"""Where creatures' notes go: a live port, a ``.mid`` file, or a list in memory.

Every sink has ``send(time, msg)``: the :class:`midi.scheduler.NoteScheduler` calls it when a
message falls due, with the clock time it was due at. The same creature can therefore play to
a synthesizer, record a ``.mid`` for a DAW, or be checked note by note in a test.
"""

from __future__ import annotations

import os
from typing import Protocol

import mido

from creatures.clock import Clock
from midi.files import TempoMap, write_messages
from midi.notes import NoteEvent, TimedMessage, from_messages
from midi.ports import ResilientPort


class NoteSink(Protocol):
    def send(self, time: float, msg: mido.Message) -> None: ...


class MemorySink:
    """Keeps every timed message it is sent, in order."""

    def __init__(self) -> None:
        self.messages: list[TimedMessage] = []

    def send(self, time: float, msg: mido.Message) -> None:
        self.messages.append((time, msg))

    def notes(self) -> list[NoteEvent]:
        return from_messages(self.messages)


LATE_NOTE = 0.010
"""Seconds after its due time past which a note-on reaching the port counts as late."""


class PortSink:
    """A live output port: an open mido port, or a :class:`ResilientPort` that drops (and
    counts) messages while its device is away.

    Given the ``clock`` the due times are on, each note-on's lateness at the port is measured:
    :attr:`late` counts those more than :data:`LATE_NOTE` late, :attr:`worst` keeps the most.
    """

    def __init__(self, port: mido.ports.BaseOutput | ResilientPort, clock: Clock | None = None) -> None:
        self.port = port
        self.clock = clock
        self.notes = 0
        self.late = 0
        self.worst = 0.0

    def send(self, time: float, msg: mido.Message) -> None:
        self.port.send(msg)
        if self.clock is not None and msg.type == "note_on" and msg.velocity > 0:
            lateness = self.clock.now() - time
            self.notes += 1
            self.late += lateness > LATE_NOTE
            self.worst = max(self.worst, lateness)

    def close(self) -> None:
        self.port.close()


class FileSink(MemorySink):
    """Records to a type 1 ``.mid`` file, written atomically on :meth:`close`."""

    def __init__(
        self, path: str | os.PathLike, *, tempo: TempoMap | None = None, split_channels: bool = True
    ) -> None:
        super().__init__()
        self.path = path
        self.tempo = tempo
        self.split_channels = split_channels

    def close(self) -> None:
        write_messages(self.path, self.messages, tempo=self.tempo, split_channels=self.split_channels)

    def __enter__(self) -> FileSink:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
