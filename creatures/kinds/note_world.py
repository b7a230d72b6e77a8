"""Heard notes placed in space, struck by a hand (thesis: "musical worlds", "exchange
(installation)"): the part *exchange* and authored creatures with a ``[creature.space]``
share.

* every heard note is copied into space (:class:`~creatures.motor.note_space.NotePlacement`:
  pitch → height and azimuth, velocity → distance, snapped to where the hand actually passes);
  with probability ``mutation`` the copy moves a fourth, fifth or octave (circle-of-fifths
  neighbours, folded back into the placement's register), so passages mutate as they travel;
  hearing a pitch already in space renews that note instead of stacking a duplicate;
* a struck note plays (and the colony hears it); no note is struck within ``strike_interval``
  of the last strike, and none the hand passes or hunger seeks within ``refractory`` seconds of
  its own last strike (a variation plays its passage whole);
* notes placed (or renewed) more than ``note_lifetime`` ago fade, and at most ``max_notes``
  stay (the one placed or renewed longest ago goes first);
* with ``answer`` a note may be struck the moment it lands (a reflex, within the same limits);
* the space remembers what it heard as passages (:meth:`NoteWorld.passages`): each player's
  notes, as the note objects they landed on, until ``passage_gap`` of silence from that player.
  :class:`Vary` walks the hand through one of them in retrograde, or with two of its
  sub-segments swapped: the distortions the thesis hears in exchange ("retrograde variations,
  repeated subsegments are swapped back and forth in an accidental recombinant evolution").
"""

from __future__ import annotations

import operator
from collections import deque
from typing import TYPE_CHECKING, Callable, Literal, NamedTuple, TypeVar

import numpy as np
from pydantic import BaseModel, Field

from creatures.behaviour.action_tuple import Action, ActionTuple
from creatures.bounds import FINITE, LONGEST_SECONDS
from creatures.kinds.moves import head_for
from creatures.motor.note_space import NotePlacement, nearest_note
from creatures.motor.search import NoPath
from midi.note_objects import NoteObject, NoteSpace
from midi.notes import NoteEvent

if TYPE_CHECKING:
    from creatures.kinds.base import CreatureKind
    from creatures.kinds.parts import Body

MUTATIONS = np.array([-12, -7, -5, 5, 7, 12])
"""Transpositions a copied note may undergo: octave, fifth and fourth, up or down."""


class SpaceSpec(BaseModel):
    """``[creature.space]`` — heard notes placed in space for the hand to strike ("musical worlds")."""

    model_config = FINITE

    strike_radius: float = Field(0.15, gt=0, le=1.0, description="how close the hand must pass to strike a note (m)")
    note_lifetime: float = Field(45.0, gt=0, le=LONGEST_SECONDS, description="seconds a placed note stays in space")
    max_notes: int = Field(48, ge=1, le=4096, description="most notes in space; the oldest (placed or renewed longest ago) "
                                                                 "fade first")
    refractory: float = Field(20.0, ge=0, le=LONGEST_SECONDS,
                              description="seconds before the same note is struck again in passing or sought again "
                                          "(a variation plays its passage whole)")
    strike_interval: float = Field(0.25, ge=0, le=3600, description="shortest time between two strikes (s)")
    mutation: float = Field(0.08, ge=0, le=1, description="chance a placed copy is transposed")
    answer: float = Field(0.0, ge=0, le=1, description="chance of striking a heard note the moment it lands in "
                                                        "space (a reflex answer), within strike_interval and refractory")
    passage_gap: float = Field(2.0, gt=0, le=LONGEST_SECONDS, description="seconds of silence from one player that "
                                                                           "end a passage (what 'vary' plays)")


class Heard(NamedTuple):
    """One heard note as the space remembers it: when, from whom, and the note object it
    landed on (placed, or renewed)."""

    time: float
    source: str
    note: NoteObject


class NoteWorld:
    """One creature's notes in space, its hand's limits, and how heard notes get there.

    ``emit`` logs a ``placed`` event; ``on_strike(t)`` is told of every strike (exchange's
    satiation). Random draws come from the creature's ``rng`` in a fixed order, so a seeded
    run is reproducible.
    """

    def __init__(self, spec: SpaceSpec, creature: "CreatureKind", body: "Body", rng: np.random.Generator, *,
                 on_strike: Callable[[float], None] | None = None) -> None:
        self.spec = spec
        self.creature = creature
        self.body = body
        self.rng = rng
        self.on_strike = on_strike
        world = creature.world
        self._reach = body.reach()
        self.placement = NotePlacement.around(self._reach)
        self.space = NoteSpace(world.scheduler_for(creature), world.clock)
        self.placed_at: dict[int, float] = {}
        self.heard: deque[Heard] = deque(maxlen=spec.max_notes)  # no more heard notes than the space holds
        self._struck_at: dict[int, float] = {}
        self._last_strike = -np.inf
        self._passages: tuple[Heard | None, tuple[NoteObject, ...], list[list[NoteObject]]] | None = None

    def hear(self, t: float, note: NoteEvent, source: str) -> None:
        """Place a copy of a heard note (or renew the note of its pitch), remember it in its
        passage, then maybe answer it."""
        pitch = note.pitch
        if self.rng.random() < self.spec.mutation:
            pitch = self._in_register(pitch + int(self.rng.choice(MUTATIONS)))
        # Note objects are not independent (thesis "musical worlds"): hearing a pitch already
        # in space renews that note rather than stacking a duplicate, so no single pitch can
        # crowd the space however often the colony plays it.
        obj = next((same for same in self.space.objects if same.pitch == pitch), None)
        if obj is None:
            position = self.place(pitch, note.velocity)
            copy = NoteEvent(note.time, pitch, note.velocity, self.creature.spec.channel, min(note.duration, 2.0))
            obj = self.space.place(copy, position)
            self.creature.world.emit("placed", creature=self.creature.name, pitch=pitch, source=source,
                                     heard=note.pitch, position=obj.position)
        self.placed_at[id(obj)] = t
        # The oldest goes first counting from when a note was placed or last renewed, as it fades
        # (a renewed note forgotten by its first placing left the passage it was just heard in).
        while len(self.space) > self.spec.max_notes:
            self._forget(min(self.space.objects, key=lambda o: self.placed_at[id(o)]))
        self.heard.append(Heard(t, source, obj))
        self._answer(t, obj)

    def _answer(self, t: float, obj: NoteObject) -> None:
        """The reflex: strike the note just heard where it landed, at once (with chance
        ``answer``), if the hand's own limits allow."""
        if not self.spec.answer or self.rng.random() >= self.spec.answer:
            return  # no random draw at all when answering is off: seeded runs stay as they were
        if self.ready(t) and t - self._struck_at.get(id(obj), -np.inf) >= self.spec.refractory:
            self.strike(t, obj, 1.0)

    def place(self, pitch: int, velocity: int) -> np.ndarray:
        """Where a note goes: the pitch/velocity place, snapped to the nearest point the hand
        actually passes in the source material, so every note in space can be struck."""
        wanted = self.placement.place(pitch, velocity)
        return self._reach[int(np.argmin(np.sum((self._reach - wanted) ** 2, axis=1)))].copy()

    def unstruck(self, t: float) -> list[NoteObject]:
        """Notes not struck for ``refractory`` seconds: a hungry creature looks for notes it
        has not just eaten, so its hand travels the whole space (and reorders it)."""
        return [o for o in self.space.objects
                if t - self._struck_at.get(id(o), -np.inf) >= self.spec.refractory]

    def _in_register(self, pitch: int) -> int:
        """Fold a pitch by octaves into the placement's range, so copies of copies cannot
        drift out of the space the body reaches."""
        low, high = self.placement.pitch_range
        while pitch < low:
            pitch += 12
        while pitch > high:
            pitch -= 12
        return pitch

    def ready(self, t: float) -> bool:
        """The hand may strike again: ``strike_interval`` has passed since its last strike."""
        return t - self._last_strike >= self.spec.strike_interval

    def strike(self, t: float, obj: NoteObject, strength: float) -> None:
        self._struck_at[id(obj)] = self._last_strike = t
        self.space.strike(obj, strength)
        if self.on_strike is not None:
            self.on_strike(t)

    def strike_nearby(self, t: float) -> None:
        """Strike the nearest note a striking joint passes through (the hand; every effector of
        a body that names several), not one struck within ``refractory``, and no more often than
        ``strike_interval``: one note at a time."""
        if not self.ready(t):
            return
        for striker in self.body.strikers_in_place():
            for obj in self.space.within(striker, self.spec.strike_radius):
                if t - self._struck_at.get(id(obj), -np.inf) >= self.spec.refractory:
                    self.strike(t, obj, 0.8)
                    return

    def reach(self, t: float, candidates: list[NoteObject]) -> NoteObject | None:
        """Set the hand off for the nearest of ``candidates`` (one A* search over the poses that
        put it on any of them); the note it heads for, or None when none can be reached."""
        body = self.body
        try:
            target, path = nearest_note(body.finder, body.motor.position(t), body.effector, candidates,
                                        tolerance=self.spec.strike_radius)
        except NoPath:
            return None
        head_for(body, t, path)
        return target

    def passages(self) -> list[list[NoteObject]]:
        """What the creature heard, as passages: each one player's notes with no more than
        ``passage_gap`` seconds between them (another player's notes in between belong to that
        player's passage: two players heard at once are two passages, not one interleaved), as
        the note objects they landed on that are still in space, the latest heard last.

        Kept until what it depends on changes (the newest heard entry, the objects in space:
        both compared by identity, and held so no id is reused): a percept asks every tick
        (exchange's ``passage``), a note is heard less often."""
        newest, objects = self.heard[-1] if self.heard else None, tuple(self.space.objects)
        cached = self._passages
        if not (cached is not None and cached[0] is newest and len(cached[1]) == len(objects)
                and all(map(operator.is_, cached[1], objects))):
            cached = self._passages = (newest, objects, self._find_passages())
        return [list(p) for p in cached[2]]

    def _find_passages(self) -> list[list[NoteObject]]:
        live = {id(obj) for obj in self.space.objects}
        notes: list[list[NoteObject]] = []  # in the order the passages began
        last: list[float] = []  # when each was last heard
        current: dict[str, int] = {}  # each player's passage still going on
        for time, source, obj in self.heard:
            k = current.get(source)
            if k is None or time - last[k] > self.spec.passage_gap:
                current[source] = k = len(notes)
                notes.append([])
                last.append(time)
            last[k] = time
            if id(obj) in live:
                notes[k].append(obj)
        return [notes[k] for k in sorted(range(len(notes)), key=last.__getitem__) if notes[k]]

    def _forget(self, obj: NoteObject) -> None:
        self.space.remove(obj)
        self.placed_at.pop(id(obj), None)
        self._struck_at.pop(id(obj), None)

    def fade(self, t: float) -> None:
        """Forget notes placed (or renewed) more than ``note_lifetime`` seconds ago."""
        for obj in [o for o in self.space.objects if t - self.placed_at.get(id(o), t) > self.spec.note_lifetime]:
            self._forget(obj)

    def remembered(self) -> int:
        """Entries of the placed and struck tables (bounded by the notes in space: a leak check)."""
        return len(self.placed_at) + len(self._struck_at)

    def marks(self) -> list[tuple[tuple[float, float, float], int]]:
        """Notes as drawn: a walking body's space goes with it (root motion moves its frame)."""
        return [(tuple(o.position + self.body.offset), o.pitch) for o in self.space.objects]


class Wander(Action):
    """A slow progression around the graph (to a random node), striking whatever notes the hand passes."""

    def __init__(self, notes: NoteWorld, name: str = "wander") -> None:
        super().__init__(name)
        self.notes = notes

    def start(self, t: float, tuple_: ActionTuple) -> None:
        body = self.notes.body
        head_for(body, t, [int(self.notes.rng.integers(len(body.graph)))])

    def update(self, t: float) -> None:
        self.notes.strike_nearby(t)


class StrikeCourse(Action):
    """The hand heads for note objects one after another and strikes each as it arrives
    (thesis "exchange (installation)": "having answered, the motor system knows how to take us
    there"), though never sooner than ``strike_interval`` after the last strike; ``done`` once
    there is no note left to head for. ``first`` and ``following`` say which notes, in which
    order."""

    def __init__(self, notes: NoteWorld, name: str) -> None:
        super().__init__(name)
        self.notes = notes
        self.target: NoteObject | None = None

    def first(self, t: float) -> NoteObject | None:
        """The note to head for when the course starts (none: nothing to do)."""
        raise NotImplementedError

    def following(self, t: float) -> NoteObject | None:
        """The note to head for once the target is struck (none: the course is over)."""
        return None

    def start(self, t: float, tuple_: ActionTuple) -> None:
        self.target = self.first(t)

    def update(self, t: float) -> None:
        if self.target is not None and self.notes.body.motor.arrived(t) and self.notes.ready(t):
            if self.target in self.notes.space.objects:
                self.notes.strike(t, self.target, 1.0)
            self.target = self.following(t)

    def done(self, t: float) -> float:
        return 1.0 if self.target is None else 0.0


class SeekNote(StrikeCourse):
    """Hunger for notes: go to the nearest note not struck lately (one A* search over the poses
    that put the hand on any of them) and strike it. ``done`` once struck (or unreachable)."""

    def __init__(self, notes: NoteWorld, name: str = "seek note") -> None:
        super().__init__(notes, name)

    def first(self, t: float) -> NoteObject | None:
        return self.notes.reach(t, self.notes.unstruck(t))


Variation = Literal["retrograde", "swap"]
T = TypeVar("T")


def vary(passage: list[T], transform: Variation, cut: int = 0) -> list[T]:
    """A passage distorted as the thesis hears exchange distort them ("exchange (installation)":
    "retrograde variations, repeated subsegments are swapped back and forth"): ``retrograde``
    plays it backwards; ``swap`` plays the sub-segment from ``cut`` on before the one up to it."""
    if transform == "retrograde":
        return passage[::-1]
    return passage[cut:] + passage[:cut]


class Vary(StrikeCourse):
    """A pattern generator over the notes in space (thesis "(void *): a cast of characters":
    "pattern generators → motor programs"; "exchange (installation)"): the hand strikes a heard
    passage's note objects in a varied order, walking from each to the next by A*, and nothing
    it passes on the way. The passage is the latest, or the longest, of those long enough to vary
    (:meth:`NoteWorld.passages`); a swap's cut is drawn from the creature's generator so that
    each sub-segment has at least ``segment`` notes. Done when the last note is struck (notes
    that fade or cannot be reached on the way are skipped)."""

    def __init__(self, notes: NoteWorld, name: str, *, transform: Variation,
                 passage: Literal["latest", "longest"] = "latest", segment: int = 3) -> None:
        super().__init__(notes, name)
        self.transform = transform
        self.passage = passage
        self.segment = segment
        self.fewest = 2 if transform == "retrograde" else 2 * segment  # to reverse; to swap two sub-segments
        self.queue: deque[NoteObject] = deque()

    def first(self, t: float) -> NoteObject | None:
        fit = [p for p in self.notes.passages() if len(p) >= self.fewest]
        if not fit:
            return None
        heard = fit[-1] if self.passage == "latest" else max(reversed(fit), key=len)  # the latest of the longest
        cut = int(self.notes.rng.integers(self.segment, len(heard) - self.segment + 1)) if self.transform == "swap" else 0
        self.queue = deque(vary(heard, self.transform, cut))
        return self.following(t)

    def following(self, t: float) -> NoteObject | None:
        while self.queue:
            obj = self.queue.popleft()
            if obj in self.notes.space.objects and (target := self.notes.reach(t, [obj])) is not None:
                return target
        return None
