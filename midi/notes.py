"""Note events: the labelled notes creatures hear and play (thesis, "listen": "labelled note
events (time, pitch, volume)").

MIDI speaks in note-on/note-off pairs; creatures speak in whole notes. This module is the one
place that converts between the two, so nothing else has to pair note-offs (including the
velocity-0 note-on that most keyboards send instead of a note-off).
"""

from __future__ import annotations

from collections import defaultdict, deque
from dataclasses import dataclass
from typing import Iterable, TypeVar

import mido

from creatures.bounds import LATEST_TIME

LONGEST_NOTE = 3600.0
"""Seconds: the longest a note may sound (an hour's drone). A :class:`NoteEvent` refuses a
longer duration, so no door (OSC, a creature) lets in a note no clock reaches the end of,
and :class:`NotePairer` holds a note whose note-off comes later (a stuck key, a damaged
file) for this long."""

TimedMessage = tuple[float, mido.Message]
"""A MIDI message with the time (seconds on the run's clock) at which it happens."""

T = TypeVar("T", int, float)


@dataclass(frozen=True, slots=True)
class NoteEvent:
    """One note: starts at ``time`` seconds, sounds for ``duration`` seconds.

    ``velocity`` is 1..127: a velocity-0 note-on means "note off" in MIDI, so it can never be
    the loudness of a note that sounds.
    """

    time: float
    pitch: int
    velocity: int = 100
    channel: int = 0
    duration: float = 0.25

    def __post_init__(self) -> None:
        # Written out rather than looped: files of 100,000 notes make this a hot path.
        if type(self.pitch) is not int or not 0 <= self.pitch <= 127:
            _refuse("pitch", "an int in 0..127", self.pitch)
        if type(self.velocity) is not int or not 1 <= self.velocity <= 127:
            _refuse("velocity", "an int in 1..127", self.velocity)
        if type(self.channel) is not int or not 0 <= self.channel <= 15:
            _refuse("channel", "an int in 0..15", self.channel)
        if not isinstance(self.time, (int, float)) or not 0 <= self.time <= LATEST_TIME:
            _refuse("time", f"a finite number >= 0 and <= {LATEST_TIME:g}", self.time)
        if not isinstance(self.duration, (int, float)) or not 0 <= self.duration <= LONGEST_NOTE:
            _refuse("duration", f"a finite number >= 0 and <= {LONGEST_NOTE:g} (seconds)", self.duration)

    @property
    def end(self) -> float:
        return self.time + self.duration

    def note_on(self) -> mido.Message:
        return mido.Message("note_on", note=self.pitch, velocity=self.velocity, channel=self.channel)

    def note_off(self) -> mido.Message:
        return mido.Message("note_off", note=self.pitch, velocity=0, channel=self.channel)


def _refuse(name: str, expected: str, value: object) -> None:
    raise ValueError(f"NoteEvent {name} must be {expected}, got {value!r}")


def is_note_off(msg: mido.Message) -> bool:
    """True for a note-off, including the velocity-0 note-on that stands for one."""
    return msg.type == "note_off" or (msg.type == "note_on" and msg.velocity == 0)


def to_messages(notes: Iterable[NoteEvent]) -> list[TimedMessage]:
    """Note-on/note-off pairs for ``notes``, sorted by time.

    At equal times note-offs come first, so a note that ends exactly where another of the same
    pitch starts does not cut the new one short; a zero-length note keeps its on before its off.
    """
    keyed = []
    for i, note in enumerate(notes):
        keyed.append(((note.time, 1, i), note.note_on()))
        keyed.append(((note.end, 0 if note.duration > 0 else 2, i), note.note_off()))
    keyed.sort(key=lambda pair: pair[0])
    return [(key[0], msg) for key, msg in keyed]


def restrike(events: Iterable[tuple[T, mido.Message]]) -> list[tuple[T, mido.Message]]:
    """``events`` (in time order) with one key (channel and pitch) sounding at a time: a note-on
    of a key still sounding is preceded, at its own time, by a note-off of that key, and the
    note-offs of the notes it cut short are dropped while the key sounds on, so the key is
    released at the last of the overlapping notes' ends.

    MIDI has one key per channel and pitch: on, on, off, off (a key struck again before its
    first note ended) is played by most synths and sequencers as a second note ending at the
    first note-off, or as a hanging note. Re-striking is what
    :class:`midi.scheduler.NoteScheduler` sends live; written files (:mod:`midi.files`) say the
    same, so ``out.mid`` plays as the run sounded. Read back (FIFO pairing), the notes keep
    their onsets and pitches; the earlier of two overlapping notes ends at the re-strike and
    the later one sounds to the later end. Messages other than notes, and a note-off of a key
    not sounding, pass unchanged. ``T`` is whatever the times are (seconds, file ticks)."""
    sounding: dict[tuple[int, int], int] = {}  # key -> note-ons not yet ended on it
    out: list[tuple[T, mido.Message]] = []
    for time, msg in events:
        if msg.type not in ("note_on", "note_off"):
            out.append((time, msg))
            continue
        key = (msg.channel, msg.note)
        depth = sounding.get(key, 0)
        if is_note_off(msg):
            if depth > 1:  # an earlier note's end: the key rings on for a later one
                sounding[key] = depth - 1
                continue
            sounding.pop(key, None)
        elif depth:
            out.append((time, mido.Message("note_off", note=msg.note, channel=msg.channel)))
            sounding[key] = depth + 1
        else:
            sounding[key] = 1
        out.append((time, msg))
    return out


class NotePairer:
    """Turns a stream of timed messages into :class:`NoteEvent` s as their note-offs arrive.

    Overlapping notes of the same pitch and channel are paired first-in first-out: the first
    note-off ends the earliest sounding note. Messages other than notes are ignored.
    """

    def __init__(self) -> None:
        self._sounding: defaultdict[tuple[int, int], deque[tuple[float, int]]] = defaultdict(deque)
        self.unmatched_offs = 0

    def feed(self, time: float, msg: mido.Message) -> NoteEvent | None:
        """Take one message; return the note it completes, if any."""
        if msg.type not in ("note_on", "note_off"):
            return None
        key = (msg.channel, msg.note)
        if not is_note_off(msg):
            self._sounding[key].append((time, msg.velocity))
            return None
        queue = self._sounding.get(key)
        if not queue:
            self.unmatched_offs += 1
            return None
        start, velocity = queue.popleft()
        return NoteEvent(start, msg.note, velocity, msg.channel, _held(start, time))

    @property
    def sounding(self) -> int:
        """How many notes have started and not yet ended."""
        return sum(len(q) for q in self._sounding.values())

    def flush(self, time: float) -> list[NoteEvent]:
        """End every sounding note at ``time`` (end of file, port closed) and return them."""
        notes = [
            NoteEvent(start, pitch, velocity, channel, _held(start, time))
            for (channel, pitch), queue in self._sounding.items()
            for start, velocity in queue
        ]
        self._sounding.clear()
        return sorted(notes, key=lambda n: (n.time, n.channel, n.pitch))


def _held(start: float, end: float) -> float:
    """How long a note from ``start`` to ``end`` sounds: at most :data:`LONGEST_NOTE`."""
    return min(max(0.0, end - start), LONGEST_NOTE)


def from_messages(timed: Iterable[TimedMessage], *, end: float | None = None) -> list[NoteEvent]:
    """Pair the note-ons and note-offs of ``timed`` into notes sorted by start time.

    Notes still sounding at the end are closed at ``end`` (default: the last message's time).
    """
    pairer = NotePairer()
    notes = []
    last = 0.0
    for time, msg in timed:
        last = time
        note = pairer.feed(time, msg)
        if note is not None:
            notes.append(note)
    notes.extend(pairer.flush(last if end is None else end))
    notes.sort(key=lambda n: (n.time, n.channel, n.pitch))
    return notes
