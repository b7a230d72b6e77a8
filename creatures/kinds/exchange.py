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
from creatures.behaviour.action_tuple import ActionTuple, DoUntil
from creatures.behaviour.models.gaussian import GaussianModel
from creatures.behaviour.motivation import Motivation
from creatures.behaviour.percept import FunctionPercept, WhateverPercept
from creatures.kinds import register
from creatures.bounds import LARGEST_RATE
from creatures.kinds.base import CreatureKind, CreatureSpec
from creatures.kinds.layers import BodySpec
from creatures.kinds.moves import Rest
from creatures.kinds.parts import Body, Voice, VoiceSpec, couple_to_hands
from creatures.kinds.report_parts import MotorTrail, report_values, selection_logger
from creatures.kinds.note_world import NoteWorld, SeekNote, SpaceSpec, Wander
from creatures.runtime.pulse import PulseDuration
from midi.notes import NoteEvent

REPORT_EVERY = 0.5
"""Seconds between the value/motivation/motor snapshots written to the events log."""


class ExchangeSpec(SpaceSpec, CreatureSpec):
    kind: Literal["exchange"]
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


@register("exchange")
class Exchange(CreatureKind):
    Spec = ExchangeSpec
    DRIVES = ("boredom", "hunger")

    def __init__(self, spec: ExchangeSpec, world, rng: np.random.Generator) -> None:
        super().__init__(spec, world, rng)
        self.body = Body(rng, ratios=spec.ratio_metric, spec=spec.body)
        self.trail = MotorTrail(world, self.name, self.body)
        self.notes = NoteWorld(spec, self, self.body, rng,
                               on_strike=lambda t: self.motivation.perturb(t, "hunger", -spec.satiation))
        self.space = self.notes.space
        self.voice: Voice | None = None
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
        self.seek = SeekNote(self.notes)
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
                ActionTuple("wander", root, Wander(self.notes),
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
        self.notes.hear(t, note, source)

    def _hunger_for_fresh_notes(self, t: float) -> float:
        """Hunger matters only when there is something to eat."""
        return self.motivation.level("hunger", t) if self.notes.unstruck(t) else 0.0

    def played(self, note: NoteEvent) -> None:
        if self.voice is not None:
            self.voice.play(note.pitch, note.velocity, note.end)

    # -- the tick ----------------------------------------------------------------------
    def tick(self, t: float) -> None:
        self.motivation.advance(t)
        self.notes.fade(t)
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
            couple_to_hands(self.voice, self.body)
        self.voice.render(out, self.world.clock.now())

    def figure(self) -> tuple[np.ndarray, np.ndarray] | None:
        return self.body.pose.positions, np.asarray(self.body.skeleton.parents)

    def marks(self) -> list[tuple[tuple[float, float, float], int]]:
        return self.notes.marks()

    # -- persistence -------------------------------------------------------------------
    def state(self) -> dict[str, Any]:
        return {"values": self.group.value_state(), "motivation": self.motivation.to_dict()}

    def restore(self, state: dict[str, Any]) -> None:
        self.group.restore_values(state.get("values", {}))
        if "motivation" in state:
            self.motivation.restore(state["motivation"], now=self.world.clock.now())
