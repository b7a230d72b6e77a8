"""Sending notes at their due time, and never leaving one hanging.

A creature decides now what should sound later (a phrase, a held note, an echo), so notes go
into a heap keyed by due time and :meth:`NoteScheduler.pump` sends whatever has fallen due by
the clock's present. A sounding note's note-off is always kept: it can be moved later
(:meth:`NoteScheduler.extend`, how a note object is perturbed instead of re-struck — thesis,
"musical worlds") but never dropped, and :meth:`NoteScheduler.all_notes_off` — run on exit
from a ``with`` block, however it exits — silences every sounding note explicitly and sends
CC 123 (All Notes Off) on every channel used.

MIDI has one key per pitch and channel: a second note-on of a sounding key, then the first
note's note-off, silences the key while the second note should still sound (a synth hears
on, on, off and stops; a repeated pitch in a phrase lost its tail). So a note that starts on
a sounding key re-strikes it: the earlier note's note-off goes out just before the new
note-on, its own later note-off is dropped, and the key sounds until the later of the two
ends, except that a held (stuck) earlier note ends with the new one: the new note's owner
holds no handle to release a key held for good. Every re-strike is counted
(:attr:`NoteScheduler.restruck`) and said at the end of a run.
"""

from __future__ import annotations

import heapq
import itertools
from dataclasses import dataclass

import mido

from creatures.clock import Clock
from midi.notes import NoteEvent
from midi.sinks import NoteSink

# Order at equal times: offs first, so a repeated pitch is not cut short by the previous
# note's off; a zero-length note's own off comes after its on.
_OFF, _OTHER, _ON, _OFF_AFTER_ON = 0, 1, 2, 3


@dataclass(frozen=True, slots=True)
class NoteHandle:
    """Names one scheduled note, so it can be extended or released early."""

    id: int
    channel: int
    pitch: int
    time: float = 0.0  # when it starts: with channel and pitch, which played note it is


class NoteScheduler:
    """A heap of timed messages sent to ``sink`` when due on ``clock``."""

    def __init__(self, sink: NoteSink, clock: Clock) -> None:
        self.sink = sink
        self.clock = clock
        self._heap: list[tuple[float, int, int, mido.Message, int | None]] = []
        self._seq = itertools.count()
        self._ends: dict[int, float] = {}  # note id -> its current note-off time
        self._handles: dict[int, NoteHandle] = {}  # note id -> handle, until its note-off went
        self._sounding: dict[int, NoteHandle] = {}  # the subset whose note-on went out
        self._channels: set[int] = set()
        self._keys: dict[tuple[int, int], int] = {}  # (channel, pitch) -> the note sounding it
        self.restruck = 0
        """Notes that started on a key still sounding, cutting the earlier note short there."""

    def play(self, note: NoteEvent, *, hold: bool = False) -> NoteHandle:
        """Schedule ``note`` (its ``time`` is clock time); ``hold`` leaves it sounding until
        :meth:`release` — a "stuck" note."""
        handle = NoteHandle(next(self._seq), note.channel, note.pitch, note.time)
        self._push(note.time, _ON, note.note_on(), handle.id)
        self._channels.add(note.channel)
        if not hold:
            self._ends[handle.id] = note.end
            self._push(note.end, _OFF if note.duration > 0 else _OFF_AFTER_ON, note.note_off(), handle.id)
        else:
            self._ends[handle.id] = float("inf")
        self._handles[handle.id] = handle
        return handle

    def send_at(self, time: float, msg: mido.Message) -> None:
        """Schedule any other message (control change, aftertouch, pitch bend)."""
        if hasattr(msg, "channel"):
            self._channels.add(msg.channel)
        self._push(time, _OTHER, msg, None)

    def extend(self, handle: NoteHandle, end: float) -> bool:
        """Move the note-off of a scheduled note to ``end`` (never earlier than now).

        Returns False when the note has already ended.
        """
        if handle.id not in self._ends:
            return False
        end = max(end, self.clock.now())
        self._ends[handle.id] = end
        self._push(end, _OFF, mido.Message("note_off", note=handle.pitch, channel=handle.channel), handle.id)
        return True

    def release(self, handle: NoteHandle) -> bool:
        """End a (held) note now."""
        if not self.extend(handle, self.clock.now()):
            return False
        self.pump()
        return True

    def end_of(self, handle: NoteHandle) -> float | None:
        """When the note's note-off is due (inf while held), or None once it has ended."""
        return self._ends.get(handle.id)

    def is_sounding(self, handle: NoteHandle) -> bool:
        return handle.id in self._sounding

    @property
    def sounding(self) -> list[NoteHandle]:
        return list(self._sounding.values())

    def next_due(self) -> float | None:
        """Clock time of the next message to send, or None when nothing is scheduled."""
        while self._heap and self._stale(self._heap[0]):
            heapq.heappop(self._heap)
        return self._heap[0][0] if self._heap else None

    def pump(self) -> int:
        """Send every message due by now, in time order; return how many went out."""
        now = self.clock.now()
        sent = 0
        while self._heap and self._heap[0][0] <= now:
            entry = heapq.heappop(self._heap)
            if self._stale(entry):
                continue
            time, order, _, msg, note_id = entry
            if order == _ON:
                handle = self._handles[note_id]
                if (earlier := self._keys.get((handle.channel, handle.pitch))) is not None:
                    self._restrike(time, earlier, handle)
                    sent += 1
                self._sounding[note_id] = handle
                self._keys[handle.channel, handle.pitch] = note_id
            elif order in (_OFF, _OFF_AFTER_ON):
                self._end(note_id)
            self.sink.send(time, msg)
            sent += 1
        return sent

    def _end(self, note_id: int) -> None:
        """Forget a note whose note-off is going out."""
        self._sounding.pop(note_id, None)
        self._ends.pop(note_id, None)
        handle = self._handles.pop(note_id, None)
        if handle is not None and self._keys.get((handle.channel, handle.pitch)) == note_id:
            del self._keys[handle.channel, handle.pitch]

    def _restrike(self, time: float, earlier: int, handle: NoteHandle) -> None:
        """End note ``earlier`` now, on the key ``handle``'s note-on is about to strike, and
        keep the key sounding until the later of the two notes' ends (a held earlier note
        ends with the new one: the new note has no handle its owner would release)."""
        end = self._ends[earlier]
        self._end(earlier)
        self.sink.send(time, mido.Message("note_off", note=handle.pitch, channel=handle.channel))
        self.restruck += 1
        if self._ends[handle.id] < end < float("inf"):
            self._ends[handle.id] = end
            self._push(end, _OFF, mido.Message("note_off", note=handle.pitch, channel=handle.channel), handle.id)

    def all_notes_off(self) -> None:
        """Silence everything now: explicit note-offs for sounding notes, then CC 123 on every
        channel used; notes not yet started are cancelled."""
        now = self.clock.now()
        silence = [mido.Message("note_off", note=h.pitch, channel=h.channel) for h in self._sounding.values()]
        silence += [mido.Message("control_change", channel=c, control=123, value=0) for c in sorted(self._channels)]
        self._heap.clear()
        self._ends.clear()
        self._sounding.clear()
        self._handles.clear()
        self._keys.clear()
        failed = None
        for msg in silence:  # one failing send must not keep the rest from going out
            try:
                self.sink.send(now, msg)
            except Exception as exc:
                failed = failed or exc
        if failed is not None:
            raise failed

    def __enter__(self) -> NoteScheduler:
        return self

    def __exit__(self, *exc: object) -> None:
        self.all_notes_off()

    def _push(self, time: float, order: int, msg: mido.Message, note_id: int | None) -> None:
        heapq.heappush(self._heap, (time, order, next(self._seq), msg, note_id))

    def _stale(self, entry: tuple) -> bool:
        """A note-off superseded by :meth:`extend`, or a note cancelled before it started."""
        time, order, _, _, note_id = entry
        if note_id is None:
            return False
        if order == _ON:
            return note_id not in self._handles
        return self._ends.get(note_id) != time
