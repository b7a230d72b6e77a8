"""*exchange*: a colony that places every note it hears in space and plays what it strikes
(thesis, "exchange (installation)" and "musical worlds").

The two rules of the game:

* every time a creature hears a note, it places a copy of that note in space
  (:class:`~creatures.motor.note_space.NotePlacement`: pitch → height and azimuth, velocity →
  distance, fitted to where its hand can reach);
* every time a creature strikes a note in space, the note plays — and the other creatures
  hear it, so passages pass between creatures.

A slow wander around the motor graph is enough to make music; a *hunger* for notes, fed by
*boredom* (time without hearing anything), sends the body straight to the nearest note
(one A* search whose goals are the poses putting the hand on any note). Traversal in space
reorders what was heard (retrogrades, swapped sub-segments); copying is imperfect: with
probability ``mutation`` a placed copy moves a fourth, fifth or octave (circle-of-fifths
neighbours), so passages mutate as they travel. Notes older than ``note_lifetime`` fade from
space, which keeps a weeks-long run bounded. With ``answer`` a creature may also strike a note
the moment it lands (call and response: live, within a millisecond of hearing it, not at the
next behaviour tick), within the same limits as the hand.
"""

from __future__ import annotations

from typing import Any, Literal

import numpy as np
from pydantic import Field

from creatures.behaviour.action_group import ActionGroup
from creatures.behaviour.action_tuple import Action, ActionTuple, DoUntil
from creatures.behaviour.models.gaussian import GaussianModel
from creatures.behaviour.motivation import Motivation
from creatures.behaviour.percept import FunctionPercept, WhateverPercept
from creatures.kinds import register
from creatures.bounds import LARGEST_RATE, LONGEST_SECONDS
from creatures.kinds.base import CreatureKind, CreatureSpec
from creatures.kinds.moves import Rest, head_for
from creatures.kinds.layers import BodySpec
from creatures.kinds.parts import Body, Voice, VoiceSpec
from creatures.kinds.report_parts import MotorTrail, report_values, selection_logger
from creatures.motor.note_space import NotePlacement, nearest_note
from creatures.motor.search import NoPath
from creatures.runtime.pulse import PulseDuration
from midi.note_objects import NoteObject, NoteSpace
from midi.notes import NoteEvent

MUTATIONS = np.array([-12, -7, -5, 5, 7, 12])
"""Transpositions a copied note may undergo: octave, fifth and fourth, up or down."""

REPORT_EVERY = 0.5
"""Seconds between the value/motivation/motor snapshots written to the events log."""


class ExchangeSpec(CreatureSpec):
    kind: Literal["exchange"]
    strike_radius: float = Field(0.15, gt=0, le=1.0, description="how close the hand must pass to strike a note (m)")
    note_lifetime: float = Field(45.0, gt=0, le=LONGEST_SECONDS, description="seconds a placed note stays in space")
    max_notes: int = Field(48, ge=1, le=4096, description="most notes in space; the oldest fade first")
    refractory: float = Field(20.0, ge=0, le=LONGEST_SECONDS, description="seconds before the same note is struck again")
    strike_interval: float = Field(0.25, ge=0, le=3600, description="shortest time between two strikes while wandering (s)")
    mutation: float = Field(0.08, ge=0, le=1, description="chance a placed copy is transposed")
    answer: float = Field(0.0, ge=0, le=1, description="chance of striking a heard note the moment it lands in "
                                                        "space (a reflex answer), within strike_interval and refractory")
    boredom_rate: float = Field(0.08, ge=0, le=LARGEST_RATE, description="boredom growth per second without notes")
    relief: float = Field(0.3, ge=0, le=LARGEST_RATE, description="boredom removed by each heard note")
    appetite: float = Field(0.08, ge=0, le=LARGEST_RATE, description="hunger for notes gained per second")
    hunger_gain: float = Field(0.1, ge=0, le=LARGEST_RATE, description="extra hunger per second per unit of boredom")
    satiation: float = Field(0.25, ge=0, le=LARGEST_RATE, description="hunger removed by each struck note")
    temperature: float | None = Field(None, gt=0, le=1e3, description="Boltzmann temperature of action selection")
    ratio_metric: bool = Field(False, description="move on a motor graph whose time metric favours low-integer "
                                                    "ratios of the source animation length (the thesis's twist)")
    rests_in_time: bool = Field(False, description="rest for two durations of the rhythm the colony hears "
                                                     "(its low-integer-ratio pulse) instead of 2 ± 0.5 s")
    graded_du: bool = Field(False, description="wandering and resting lose expected value as their planned time "
                                               "runs out (a graded Du), so hunger interrupts them more easily "
                                               "near their end")
    voice: VoiceSpec = VoiceSpec()
    body: BodySpec = BodySpec()


class _Wander(Action):
    """A slow progression around the graph, striking whatever notes the hand passes."""

    def __init__(self, creature: "Exchange") -> None:
        super().__init__("wander")
        self.creature = creature

    def start(self, t: float, tuple_: ActionTuple) -> None:
        body = self.creature.body
        head_for(body, t, [int(self.creature.rng.integers(len(body.graph)))])

    def update(self, t: float) -> None:
        self.creature.strike_nearby(t)


class _SeekNote(Action):
    """Hunger for notes: go to the nearest note object and strike it."""

    def __init__(self, creature: "Exchange") -> None:
        super().__init__("seek note")
        self.creature = creature
        self.target: NoteObject | None = None

    def start(self, t: float, tuple_: ActionTuple) -> None:
        c = self.creature
        self.target = None
        fresh = c.unstruck(t)
        try:
            self.target, path = nearest_note(c.body.finder, c.body.motor.position(t), c.body.effector,
                                             fresh, tolerance=c.spec.strike_radius)
        except NoPath:
            return
        head_for(c.body, t, path)

    def update(self, t: float) -> None:
        if self.target is not None and self.creature.body.motor.arrived(t):
            if self.target in self.creature.space.objects:
                self.creature.strike(t, self.target, 1.0)
            self.target = None

    def done(self, t: float) -> float:
        return 1.0 if self.target is None else 0.0


@register("exchange")
class Exchange(CreatureKind):
    Spec = ExchangeSpec
    DRIVES = ("boredom", "hunger")

    def __init__(self, spec: ExchangeSpec, world, rng: np.random.Generator) -> None:
        super().__init__(spec, world, rng)
        self.body = Body(rng, ratios=spec.ratio_metric, spec=spec.body)
        self.trail = MotorTrail(world, self.name, self.body)
        self._reach = self.body.reach()
        self.placement = NotePlacement.around(self._reach)
        self.space = NoteSpace(world.scheduler_for(self), world.clock)
        self.placed_at: dict[int, float] = {}
        self.voice: Voice | None = None
        self._struck_at: dict[int, float] = {}
        self._last_strike = -np.inf
        self.motivation = Motivation(
            {"boredom": 0.2, "hunger": 0.0},
            growth={"boredom": spec.boredom_rate, "hunger": spec.appetite},
            decay={"hunger": 0.05},
            equilibrium={"hunger": 0.0},
            coupling={("hunger", "boredom"): spec.hunger_gain},
            ceiling=2.0,
        )
        root = WhateverPercept()
        hungry = FunctionPercept("hungry", self._hunger_for_fresh_notes, parent=root)
        self.seek = _SeekNote(self)
        arrived = FunctionPercept("arrived", lambda t: 1.0 if self.body.motor.arrived(t) else 0.0)
        found = FunctionPercept("struck", self.seek.done)
        # An authored creature, not a trained one: nothing here is a consummatory reward that
        # could ground learnt values (with credit assignment but no reward, every value would
        # only leak away by the discount), so values stay as authored (alpha = 0) and the
        # motivations do the modulating, as in the thesis's description of exchange.
        rest = GaussianModel(2.0, 0.5)
        if spec.rests_in_time:
            rest = PulseDuration(world.pulse, rest)
        self.group = ActionGroup(
            f"{self.name}", rng=rng, alpha=0.0, temperature=spec.temperature,
            on_event=selection_logger(world, self.name),
            tuples=[
                ActionTuple("wander", root, _Wander(self),
                            DoUntil(GaussianModel(4.0, 1.0), until=arrived, graded=spec.graded_du), 1.0),
                ActionTuple("seek note", hungry, self.seek, DoUntil(8.0, until=found), 3.0),
                ActionTuple("rest", root, Rest(self.body), DoUntil(rest, graded=spec.graded_du), 0.4),
            ],
        )
        self._next_report = 0.0

    # -- hearing and playing ------------------------------------------------------------
    def hear(self, note: NoteEvent, source: str) -> None:
        t = self.world.clock.now()
        self.motivation.perturb(t, "boredom", -self.spec.relief)
        pitch = note.pitch
        if self.rng.random() < self.spec.mutation:
            pitch = self._in_register(pitch + int(self.rng.choice(MUTATIONS)))
        for same in self.space.objects:
            if same.pitch == pitch:
                # Note objects are not independent (thesis "musical worlds"): hearing a pitch
                # already in space renews that note rather than stacking a duplicate, so no
                # single pitch can crowd the space however often the colony plays it.
                self.placed_at[id(same)] = t
                self._answer(t, same)
                return
        position = self.place(pitch, note.velocity)
        copy = NoteEvent(note.time, pitch, note.velocity, self.spec.channel, min(note.duration, 2.0))
        obj = self.space.place(copy, position)
        self.placed_at[id(obj)] = t
        self.world.emit("placed", creature=self.name, pitch=pitch, source=source, heard=note.pitch,
                        position=obj.position)
        while len(self.space) > self.spec.max_notes:
            self._forget(self.space.objects[0])
        self._answer(t, obj)

    def _answer(self, t: float, obj: NoteObject) -> None:
        """The reflex: strike the note just heard where it landed, at once (with chance
        ``answer``), if the hand's own limits allow: ``strike_interval`` since the last
        strike, ``refractory`` since this note was last struck."""
        if not self.spec.answer or self.rng.random() >= self.spec.answer:
            return  # no random draw at all when answering is off: seeded runs stay as they were
        if (t - self._last_strike >= self.spec.strike_interval
                and t - self._struck_at.get(id(obj), -np.inf) >= self.spec.refractory):
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

    def _hunger_for_fresh_notes(self, t: float) -> float:
        """Hunger matters only when there is something to eat."""
        return self.motivation.level("hunger", t) if self.unstruck(t) else 0.0

    def strike(self, t: float, obj: NoteObject, strength: float) -> None:
        self._struck_at[id(obj)] = self._last_strike = t
        self.space.strike(obj, strength)
        self.motivation.perturb(t, "hunger", -self.spec.satiation)

    def strike_nearby(self, t: float) -> None:
        """Strike the nearest note the hand passes through (not one struck within
        ``refractory``, and no more often than ``strike_interval``: one note at a time)."""
        if t - self._last_strike < self.spec.strike_interval:
            return
        for obj in self.space.within(self.body.hand(), self.spec.strike_radius):
            if t - self._struck_at.get(id(obj), -np.inf) >= self.spec.refractory:
                self.strike(t, obj, 0.8)
                return

    def played(self, note: NoteEvent) -> None:
        if self.voice is not None:
            self.voice.play(note.pitch, note.velocity, note.end)

    def _forget(self, obj: NoteObject) -> None:
        self.space.remove(obj)
        self.placed_at.pop(id(obj), None)
        self._struck_at.pop(id(obj), None)

    # -- the tick ----------------------------------------------------------------------
    def tick(self, t: float) -> None:
        self.motivation.advance(t)
        for obj in [o for o in self.space.objects if t - self.placed_at.get(id(o), t) > self.spec.note_lifetime]:
            self._forget(obj)
        self.trail.follow(t)
        pose = self.body.update(t)
        self.group.tick(t)
        self.space.tick()
        if self.voice is not None:
            self.voice.feel(pose)
        if t >= self._next_report:
            self._next_report = t + REPORT_EVERY
            self._report(t)

    def _report(self, t: float) -> None:
        report_values(self.world, t, self.name, self.group, self.motivation)
        self.trail.report(t)
        self.world.log.emit(t, "percepts", creature=self.name, sizes={"notes in space": len(self.space)})

    # -- outputs -----------------------------------------------------------------------
    def sound(self, out: np.ndarray, sample_rate: int) -> None:
        if self.voice is None:
            self.voice = Voice(self.spec.voice, sample_rate)
            reach = self.body.reach()
            low, high = reach.min(axis=0), reach.max(axis=0)
            line = np.linspace(0.0, 1.0, self.spec.voice.masses)[:, None]
            self.voice.couple(low + line * (high - low), [self.body.skeleton.names.index("hand_l"),
                                                          self.body.effector_index])
        self.voice.render(out, self.world.clock.now())

    def figure(self) -> tuple[np.ndarray, np.ndarray] | None:
        return self.body.pose.positions, np.asarray(self.body.skeleton.parents)

    def marks(self) -> list[tuple[tuple[float, float, float], int]]:
        return [(tuple(o.position), o.pitch) for o in self.space.objects]

    # -- persistence -------------------------------------------------------------------
    def state(self) -> dict[str, Any]:
        return {"values": self.group.value_state(), "motivation": self.motivation.to_dict()}

    def restore(self, state: dict[str, Any]) -> None:
        self.group.restore_values(state.get("values", {}))
        if "motivation" in state:
            self.motivation.restore(state["motivation"], now=self.world.clock.now())
