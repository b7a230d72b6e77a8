"""The shared world of a colony: one clock, one events log, one note bus.

Creatures in one process hear each other through the same channel a performer uses (thesis,
*three creatures*: "equivalent communication between creatures"): a note a creature plays is
scheduled to the MIDI output and, when it starts, delivered to every other creature's ear.
Notes from outside (files, ports, OSC) enter the same bus with their source's name, and
teach the colony's :class:`HeardPulse` when they start: the creatures keep the time of the
music they hear, not of their own wandering. A creature whose spec says ``hears_input =
false`` hears none of them (MIDI, OSC, transcribed audio, the input map's notes), only other
creatures. Sensors (``[[input]]`` with ``to = "sensor"``) are the world's too: named
:class:`StateObject` flows any creature may model as a percept.
"""

from __future__ import annotations

import dataclasses
import heapq
import itertools
from collections import deque
from typing import TYPE_CHECKING, Callable

from creatures.behaviour.state_object import StateObject
from creatures.clock import Clock
from creatures.events import EventLog
from creatures.runtime.measures import SOUNDS
from creatures.runtime.pulse import HeardPulse
from creatures.temporal.transitions import Succession
from midi.notes import NoteEvent
from midi.scheduler import NoteHandle, NoteScheduler

if TYPE_CHECKING:
    from creatures.kinds.base import CreatureKind
    from creatures.room.stage import Stage

INPUT = "input"
"""The source name of notes that come from outside the colony."""

TEMPO_STEP = 0.02
"""Relative change of the heard tempo that is logged as a new tempo (and a tempo change in out.mid)."""


class World:
    """Routes notes between creatures and to the output; every note is logged."""

    def __init__(self, clock: Clock, log: EventLog, scheduler: NoteScheduler, pulse: HeardPulse | None = None) -> None:
        self.clock = clock
        self.log = log
        self.scheduler = scheduler
        self.creatures: list[CreatureKind] = []
        self._pending: list[tuple[float, int, NoteEvent, str, str | None]] = []
        """Notes until they start: (start, order, note, who played it, how it came in from
        outside — ``None`` for a creature's own)."""
        self.listeners: list[Callable[[str, NoteEvent], None]] = []  # e.g. OSC to other colonies
        self.hearing: list[Callable[[str, NoteEvent], None]] = []  # (source, note) from outside, as it starts: the body stream
        # What creatures of other colonies last said of themselves over OSC, by creature then
        # key (creatures.runtime.network): e.g. peers["bo"]["boredom"], peers["bo"]["action"].
        self.peers: dict[str, dict[str, int | float | str]] = {}
        self._seq = itertools.count()
        self.sensors: dict[str, StateObject] = {}  # by name, fed by the input map
        self.notes_played = 0
        self.sounds_made = 0  # sung sounds and read words (SOUNDS), the acts that are not notes
        self.pulse = pulse or HeardPulse()  # the rhythm of the notes heard from outside the colony ([pulse])
        # Forward transition models the colony shares by name ([creature.groups.NAME]
        # succession): what usually follows what, learnt and followed by several creatures.
        self.successions: dict[str, Succession] = {}
        self._metre: str | None = None  # the best reading last logged
        # A recording run (offline: out.mid) keeps every note heard from outside (the input
        # track) and every tempo change; a live run of weeks keeps only the latest tempo.
        self.recording = False
        # An offline run ends by asking each creature for its own outputs (Creature.finish:
        # ozymandias's EDL); a live run or a rehearsal never asks, so what only those outputs
        # hold is not kept for weeks (ozymandias's EDL grew ~8 entries a second, for good).
        self.writes_outputs = False
        self.heard: deque[NoteEvent] = deque()
        self.tempo: deque[tuple[float, float]] = deque()  # (time, bpm) whenever the heard tempo moved
        # With a [room] (creatures/room/stage.py), a note reaches each ear from where it was
        # played, late and attenuated by distance, unless masked; without one, every ear at once.
        self.room: Stage | None = None

    def add(self, creature: "CreatureKind") -> None:
        self.creatures.append(creature)

    def sensor(self, name: str) -> StateObject:
        """The sensor called ``name`` (KeyError naming those there are)."""
        try:
            return self.sensors[name]
        except KeyError:
            raise KeyError(f"no sensor named {name!r} (sensors: {sorted(self.sensors) or 'none'})") from None

    def emit(self, kind: str, **fields: object) -> None:
        """Log an event at the present clock time (a sound sung or a word read is counted: the
        acts of creatures that play no notes)."""
        if kind in SOUNDS:
            self.sounds_made += 1
        self.log.emit(self.clock.now(), kind, **fields)

    def play(self, creature: "CreatureKind", note: NoteEvent, *, hold: bool = False,
             channel: int | None = None) -> NoteHandle:
        """``creature`` plays ``note`` on its own channel (or ``channel``: a score's part); the
        others hear it when it starts.

        ``hold`` leaves it sounding until released (a stuck note object).
        """
        note = dataclasses.replace(note, channel=creature.spec.channel if channel is None else channel)
        handle = self.scheduler.play(note, hold=hold)
        creature.played(note)
        for listener in self.listeners:
            listener(creature.name, note)
        self.notes_played += 1
        self.log.emit(self.clock.now(), "note", creature=creature.name, time=note.time, pitch=note.pitch,
                      velocity=note.velocity, duration=note.duration, channel=note.channel)
        heapq.heappush(self._pending, (note.time, next(self._seq), note, creature.name, None))
        return handle

    def scheduler_for(self, creature: "CreatureKind") -> "CreatureScheduler":
        """The shared scheduler as ``creature`` sees it: what it plays, the others hear."""
        return CreatureScheduler(self, creature)

    def record(self, keep: int | None = None) -> None:
        """Keep from now on what out.mid needs: the notes heard from outside and every tempo
        change, the latest ``keep`` of each (a live run of weeks stays bounded)."""
        self.recording = True
        self.heard, self.tempo = deque(self.heard, maxlen=keep), deque(self.tempo, maxlen=keep)

    def inject(self, note: NoteEvent, source: str = INPUT, *, via: str | None = None) -> None:
        """A note from outside the colony, heard by every creature when it starts.

        ``source`` is who played it as the creatures see it (:data:`INPUT` for anything from
        outside the colony, else a remote creature's name); ``via`` names the channel it came
        through (``"midi"``, ``"audio"``) for the events log. The log's ``heard`` record is
        written when the creatures hear it (:meth:`deliver`), not now: a generated input's notes
        are injected ahead of time, and a replay showed them all heard at once at its start.
        """
        if self.recording:
            self.heard.append(note)
        heapq.heappush(self._pending, (note.time, next(self._seq), note, source, via or source))

    def forget(self, until: float) -> int:
        """Drop the notes that started before ``until`` and were never delivered (those heard
        while the colony was paused: on resume they are the past, not a burst to answer);
        how many."""
        kept = [entry for entry in self._pending if entry[0] >= until]
        dropped = len(self._pending) - len(kept)
        heapq.heapify(kept)
        self._pending = kept
        return dropped

    def outside(self, source: str) -> bool:
        """Whether a note from ``source`` comes from outside the colony (a visitor, another
        colony): what the pulse hears, not what a creature of this world played."""
        return not any(creature.name == source for creature in self.creatures)

    def deliver(self, t: float) -> int:
        """Give every note that has started by ``t`` to every creature but its player."""
        count = 0
        while self._pending and self._pending[0][0] <= t:
            _, _, note, source, via = heapq.heappop(self._pending)
            if via is not None:
                self.log.emit(t, "heard", source=via, time=note.time, pitch=note.pitch, velocity=note.velocity,
                              duration=note.duration)
            if self.outside(source):
                self.pulse.hear(note.time)  # the rhythm heard from outside, not the colony's own
                for listener in self.hearing:
                    listener(source, note)
            if self.room is not None:
                self.room.emit(note, source)
            else:
                for creature in self.creatures:
                    if creature.name != source and (source != INPUT or creature.spec.hears_input):
                        creature.hear(note, source)
            count += 1
        if self.room is not None:
            for i, heard, source in self.room.due(t):
                creature = self.creatures[i]
                if source != INPUT or creature.spec.hears_input:
                    creature.hear(heard, source)
        surprises = self.pulse.settle()
        if surprises and self.pulse.ready:  # the heard rhythm changed: an expectation violated
            self.log.emit(t, "surprise", percept="pulse", count=surprises, pulse=self.pulse.model.pulse)
        self._follow_tempo(t)
        metre = self.pulse.readings.best.metre
        if self.pulse.ready and metre != self._metre:  # a competing reading took over (or the first is trusted)
            self._metre = metre
            self.log.emit(t, "reading", metre=metre, pulse=self.pulse.model.pulse, scores=self.pulse.readings.scores())
        return count

    def _follow_tempo(self, t: float) -> None:
        """Log the heard tempo when it has moved by :data:`TEMPO_STEP` (the tempo map of
        ``out.mid``); only the last change is kept in a long live run."""
        bpm = self.pulse.bpm()
        if bpm is None or (self.tempo and abs(bpm / self.tempo[-1][1] - 1.0) < TEMPO_STEP):
            return
        if not self.recording:
            self.tempo.clear()
        self.tempo.append((t, bpm))
        self.emit("tempo", bpm=round(bpm, 3))


class CreatureScheduler:
    """A creature's view of the world's :class:`NoteScheduler` (for :class:`NoteSpace`).

    ``play`` goes through :meth:`World.play` so every note a creature strikes is logged and
    heard by the colony; everything else is the shared scheduler's own.
    """

    def __init__(self, world: World, creature: "CreatureKind") -> None:
        self._world = world
        self._creature = creature

    def play(self, note: NoteEvent, *, hold: bool = False) -> NoteHandle:
        return self._world.play(self._creature, note, hold=hold)

    def extend(self, handle: NoteHandle, end: float) -> bool:
        """Move a sounding note's end (struck again, it rings on), logged as ``rang_on``: the
        ``note`` record gave the length it was played with, and ``out.mid`` holds the longer."""
        return self._moved("rang_on", handle, self._world.scheduler.extend(handle, end))

    def release(self, handle: NoteHandle) -> bool:
        """End a (stuck) note now, logged as ``released``: a held note's ``note`` record gives
        no end."""
        return self._moved("released", handle, self._world.scheduler.release(handle))

    def _moved(self, kind: str, handle: NoteHandle, done: bool) -> bool:
        """Log where the note of ``handle`` now ends (if it was still sounding); ``done``."""
        if done:
            end = self._world.scheduler.end_of(handle)
            self._world.emit(kind, creature=self._creature.name, time=handle.time, pitch=handle.pitch,
                             channel=handle.channel, end=self._world.clock.now() if end is None else end)
        return done

    def __getattr__(self, name: str):
        return getattr(self._world.scheduler, name)
