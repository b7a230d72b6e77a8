"""Note objects: notes placed in space, struck by creatures (thesis, "exchange" and "musical
worlds").

The exchange game has two rules: every time a creature hears a note it places a copy of that
note in space (:meth:`NoteSpace.place`); every time it strikes a note in space, the note plays
(:meth:`NoteSpace.strike`). Note objects shield the installation from MIDI's model, in which
every note is independent of every other, even of the same pitch: striking a note that is
still sounding *perturbs* it — it swells (polyphonic aftertouch) and rings on longer — rather
than blindly re-triggering it, and a "stuck" note, once struck, sounds until it is released.
The motor system asks "what is the closest note object?" (:meth:`NoteSpace.nearest`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import mido
import numpy as np

from creatures.clock import Clock
from midi.notes import NoteEvent
from midi.scheduler import NoteHandle, NoteScheduler


@dataclass(eq=False)
class NoteObject:
    """A note with a place: ``position`` (x, y, z), what it plays, and how it rings now.

    ``energy`` (0..1) is how hard and how recently it was struck; it decays with clock time
    and drives the perturbation of a sounding note.
    """

    position: np.ndarray
    pitch: int
    velocity: int = 100
    channel: int = 0
    duration: float = 0.5
    stuck: bool = False
    energy: float = 0.0
    handle: NoteHandle | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        self.position = np.asarray(self.position, dtype=np.float64).reshape(3)
        NoteEvent(0.0, self.pitch, self.velocity, self.channel, self.duration)  # validates


class NoteSpace:
    """The note objects of one world, playing through a :class:`NoteScheduler`.

    ``half_life``: seconds for a note's energy to halve. ``ring_on``: how much longer (as a
    fraction of its duration, scaled by strike strength) a struck sounding note keeps ringing.
    """

    def __init__(
        self, scheduler: NoteScheduler, clock: Clock, *, half_life: float = 1.0, ring_on: float = 0.5
    ) -> None:
        self.scheduler = scheduler
        self.clock = clock
        self.half_life = half_life
        self.ring_on = ring_on
        self.objects: list[NoteObject] = []
        self._positions = np.empty((0, 3))
        self._last_tick = clock.now()

    def __len__(self) -> int:
        return len(self.objects)

    def add(self, obj: NoteObject) -> NoteObject:
        self.objects.append(obj)
        self._positions = np.vstack([self._positions, obj.position])
        return obj

    def place(self, note: NoteEvent, position: np.ndarray, *, stuck: bool = False) -> NoteObject:
        """Rule one of exchange: a heard note, copied into space at ``position``."""
        return self.add(
            NoteObject(position, note.pitch, note.velocity, note.channel, note.duration, stuck)
        )

    def remove(self, obj: NoteObject) -> None:
        i = self.objects.index(obj)
        if obj.handle is not None:
            self.scheduler.release(obj.handle)
        del self.objects[i]
        self._positions = np.delete(self._positions, i, axis=0)

    def nearest(self, point: np.ndarray) -> NoteObject | None:
        """The note object closest to ``point`` (Euclidean), or None in an empty space."""
        if not self.objects:
            return None
        d2 = np.sum((self._positions - np.asarray(point, dtype=np.float64)) ** 2, axis=1)
        return self.objects[int(np.argmin(d2))]

    def within(self, point: np.ndarray, radius: float) -> list[NoteObject]:
        """Every note object within ``radius`` of ``point``, nearest first."""
        d2 = np.sum((self._positions - np.asarray(point, dtype=np.float64)) ** 2, axis=1)
        order = np.argsort(d2, kind="stable")
        return [self.objects[i] for i in order if d2[i] <= radius * radius]

    def is_sounding(self, obj: NoteObject) -> bool:
        return obj.handle is not None and self.scheduler.end_of(obj.handle) is not None

    def strike(self, obj: NoteObject, strength: float = 1.0) -> None:
        """Rule two of exchange: play the note — or, if it still sounds, perturb it."""
        strength = float(np.clip(strength, 0.0, 1.0))
        now = self.clock.now()
        obj.energy += strength * (1.0 - obj.energy)
        if self.is_sounding(obj):
            pressure = round(obj.velocity + (127 - obj.velocity) * obj.energy)
            self.scheduler.send_at(
                now, mido.Message("polytouch", channel=obj.channel, note=obj.pitch, value=pressure)
            )
            if not obj.stuck:
                end = self.scheduler.end_of(obj.handle)
                self.scheduler.extend(obj.handle, end + self.ring_on * obj.duration * strength)
            return
        velocity = max(1, min(127, round(obj.velocity * max(strength, 1e-9))))
        note = NoteEvent(now, obj.pitch, velocity, obj.channel, obj.duration)
        obj.handle = self.scheduler.play(note, hold=obj.stuck)

    def release(self, obj: NoteObject) -> None:
        """Let a stuck note go (or cut any sounding note short)."""
        if obj.handle is not None:
            self.scheduler.release(obj.handle)

    def tick(self) -> None:
        """Decay every note's energy by the clock time since the last tick, and send what the
        scheduler has due."""
        now = self.clock.now()
        decay = math.exp(-math.log(2.0) * (now - self._last_tick) / self.half_life)
        self._last_tick = now
        for obj in self.objects:
            obj.energy *= decay
        self.scheduler.pump()
        for obj in self.objects:
            if obj.handle is not None and not self.is_sounding(obj):
                obj.handle = None
