"""*soundcreatures*: creatures that hear sounds, keep them, and sing them back through their
bodies (thesis, "soundcreatures (installation)", "aural Ac percept trees", and "aural models
– cepstral models").

Design, following the thesis's "key elements of their behavior":

* **Sounds they hear get incorporated into their repertoire.** The :class:`Ear` cuts what
  the microphone hears into utterances (amplitude segmentation, cepstra). They go to one
  utterance percept tree rooted at "any sound". The root collects the utterances that led to
  rewarded tuples (``attend`` earns credit whenever another tuple follows it: the sound it
  attended is kept); when a tuple on a percept becomes valuable the percept clusters its
  exemplars into children (fission, :class:`AuralLearning`), children that stop being
  distinct fuse back.
* **One tree for Tr and Ac.** A child percept is a sound class a tuple can trigger on
  (``any sound/2 | attend``: new sounds become triggers) and a class it can sing
  (``repertoire | sing any sound/2``: an action singing exemplars drawn from the child). The
  singing tuples start at the top of the tree ("sing any sound" plays any heard sound) and
  refine through value into more specific material. Raw samples are kept with the cepstra
  because cepstra cannot be sung back.
* **The perception of sound rewards behaviour.** ``attend`` (Tr: any sound) has a high,
  non-plastic value — the primary reinforcer. A sound heard while a tuple is running (or in
  the ``answer_wait`` after its song) interrupts it, and credit assignment moves the
  interrupted tuple toward the discounted value of attending: creatures learn which songs
  are followed by sound.
* **A motivation to hear things** grows during silence and is relieved by attending. It
  raises the Boltzmann temperature of selection (``temperature × (1 + curiosity × level)``):
  a creature that has heard nothing for a while explores its repertoire rather than
  exploiting its best song.
* **StateObject processing filters out self-made sounds.** The mouth's singing flow
  inhibits the ear's hearing flow (half-duplex, ``[creature.hearing] half_duplex``), held
  ``release`` seconds after singing stops for the room's echo. With ``[audio] air = true``
  the creature's ear gets the room, its own voice included, one tick late.
* **Persistent aural models seed a creature** (``seed_model``): a tree saved by
  :func:`audio.utterance.save_aural_model` from one creature starts another's repertoire.
* **Sound through graphical movement.** The body wanders the shared motor graph while
  singing; its rib cage (elbow spread) sets the amplitude and its back angle the low-pass
  cutoff of the sampler (:class:`Mouth`).

Events logged: ``sound`` (an utterance heard: start, end, level), ``sing`` (what was sung:
percept, start, end, when it was heard), ``selection``/``credit``/``hypothesis``/``fission``/
``fusion``, and every ``REPORT_EVERY`` seconds ``values``, ``motivation``, ``percepts`` and
``voice`` (the rib cage, and the amplitude and cutoff the body gives the sampler).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from pydantic import Field

from audio.utterance import Utterance, UtterancePercept, load_aural_model
from creatures.behaviour.action_group import ActionGroup
from creatures.behaviour.action_tuple import Action, ActionTuple, DoUntil
from creatures.behaviour.models.gaussian import GaussianModel
from creatures.behaviour.motivation import Motivation
from creatures.behaviour.percept import FunctionPercept
from creatures.behaviour.value import ScalarValue, value_from_dict
from creatures.kinds import register
from creatures.bounds import LARGEST_RATE
from creatures.kinds.base import CreatureKind, CreatureSpec
from creatures.kinds.hearing_parts import (AuralLearning, Ear, HearingSpec, Mouth, MouthSpec, SeedModel,
                                           SingFrom, tree_from_state, tree_state)
from creatures.kinds.layers import BodySpec
from creatures.kinds.parts import Body
from creatures.kinds.report_parts import MotorTrail
from creatures.motor.search import NoPath

if TYPE_CHECKING:
    from creatures.runtime.world import World

REPORT_EVERY = 0.5
"""Seconds between the value/motivation/percept snapshots written to the events log."""


class SoundCreatureSpec(CreatureSpec):
    kind: Literal["soundcreature"]
    temperature: float = Field(0.3, gt=0, le=1e3, description="Boltzmann temperature of selection when content")
    curiosity: float = Field(2.0, ge=0, le=1e3, description="how much the motivation to hear raises the temperature")
    hear_growth: float = Field(0.1, ge=0, le=LARGEST_RATE, description="growth per second of the motivation to hear (in silence)")
    hear_relief: float = Field(0.5, ge=0, le=LARGEST_RATE, description="motivation to hear removed by each attended sound")
    answer_wait: float = Field(1.0, ge=0, le=10, description="seconds after a song in which a heard sound "
                                                             "still rewards it")
    attend_value: float = Field(3.0, gt=0, le=LARGEST_RATE, description="value of attending a sound (the primary reinforcer)")
    body_rate: float = Field(10.0, gt=0, le=100, description="body poses per second (forward kinematics is "
                                                            "the costliest per-tick work; the sound follows "
                                                            "the body at this rate)")
    innovation: float = Field(0.8, gt=0, le=1e3, description="value (× mean) above which a percept is clustered")
    seed_model: SeedModel = Field(None, description="aural model (save_aural_model JSON, absolute or relative "
                                                    "to the working directory) to start with instead of an "
                                                    "empty repertoire")
    hearing: HearingSpec = HearingSpec()
    mouth: MouthSpec = MouthSpec()
    body: BodySpec = BodySpec()


class _Attend(Action):
    """Turn to a heard sound: the consummatory act of the motivation to hear."""

    def __init__(self, creature: "SoundCreature") -> None:
        super().__init__("attend")
        self.creature = creature

    def start(self, t: float, tuple_: ActionTuple) -> None:
        c = self.creature
        c.motivation.perturb(t, "hear", -c.spec.hear_relief)
        # Attending is the rewarded act, so the sound attended joins the root's exemplars
        # now: by the time the credit of this activation is assigned (when the next tuple
        # starts) the root may already be hearing a newer sound.
        c.root.update(t, tuple_.value.to_float())
        heard = c.root.heard(t)
        c.world.emit("attend", creature=c.name, percept=tuple_.trigger.name,
                     heard_at=None if heard is None else heard.time)


class _Rest(Action):
    """Return to a low-energy pose and stay quiet a while (listening)."""

    def __init__(self, creature: "SoundCreature") -> None:
        super().__init__("rest")
        self.creature = creature

    def start(self, t: float, tuple_: ActionTuple) -> None:
        motor = self.creature.body.motor
        try:
            motor.set_course(t, motor.finder.to_rest(motor.position(t)))
        except NoPath:
            pass


@register("soundcreature")
class SoundCreature(CreatureKind):
    Spec = SoundCreatureSpec
    FIGURE_ONLY = "its mouth reads the shipped figure's rib cage and back (elbows, pelvis, chest, head)"
    DRIVES = ("hear",)

    def __init__(self, spec: SoundCreatureSpec, world: "World", rng: np.random.Generator) -> None:
        super().__init__(spec, world, rng)
        self.body = Body(rng, spec=spec.body)
        self.trail = MotorTrail(world, self.name, self.body)
        self.ear = Ear(spec.hearing)
        self.mouth = Mouth(spec.mouth, self.ear.singing)
        self.root = load_aural_model(spec.seed_model) if spec.seed_model else self._new_tree()
        self.motivation = Motivation({"hear": 0.2}, growth={"hear": spec.hear_growth}, ceiling=2.0)
        self._singers: dict[int, SingFrom] = {}
        self._build_group()
        self._next_report = 0.0
        self._next_pose = 0.0

    def _new_tree(self) -> UtterancePercept:
        h = self.spec.hearing
        return UtterancePercept("any sound", radius=h.radius, memory=h.memory, max_members=h.keep)

    def _build_group(self) -> None:
        spec = self.spec
        self.repertoire = FunctionPercept("repertoire", lambda t: 1.0 if self.root.members else 0.0)
        self.sung = FunctionPercept("sung", lambda t: 1.0 if t >= self.mouth.until + spec.answer_wait else 0.0)
        self.always = FunctionPercept("always", lambda t: 1.0)
        self.rest_duration = GaussianModel(2.0, 0.5)
        sing_any, attend, rest = self.sing_from(self.root), _Attend(self), _Rest(self)
        self.learning = AuralLearning(self.root, self.sing_from, statistics=0.5, innovation=spec.innovation,
                                      min_trigger=0.5, on_event=self._log_selection)
        self.group = ActionGroup(
            self.name, rng=self.rng, temperature=spec.temperature, on_event=self._log_selection,
            learning=self.learning,
            tuples=[
                ActionTuple("attend", self.root, attend, self._do_until(attend),
                            ScalarValue(spec.attend_value, plasticity=0.0)),
                ActionTuple("sing", self.repertoire, sing_any, self._do_until(sing_any), 1.0),
                ActionTuple("answer", self.root, sing_any, self._do_until(sing_any), 0.5),
                ActionTuple("rest", self.always, rest, self._do_until(rest), 0.5),
            ],
        )

    def _do_until(self, action: Action) -> DoUntil:
        """Du by kind of action: a song lasts until sung and answered, attending a moment,
        rest a learnt while (one shared duration model)."""
        if isinstance(action, SingFrom):
            return DoUntil(8.0, until=self.sung)
        if isinstance(action, _Attend):
            return DoUntil(0.3)
        return DoUntil(self.rest_duration)

    def sing_from(self, percept: UtterancePercept) -> SingFrom:
        """The one singing action of ``percept`` (shared by every tuple that sings it)."""
        if id(percept) not in self._singers:
            self._singers[id(percept)] = SingFrom(percept, self.rng, self._sing)
        return self._singers[id(percept)]

    def _sing(self, t: float, utterance: Utterance, percept: UtterancePercept) -> None:
        end = self.mouth.sing(t, utterance)
        body = self.body
        try:  # the body breathes the sound out: a movement across the graph while singing
            body.motor.set_course(t, body.motor.course(t, [int(self.rng.integers(len(body.graph)))]))
        except NoPath:
            pass
        self.world.emit("sing", creature=self.name, percept=percept.name, start=t, end=end,
                        heard_at=utterance.time)

    # -- hearing -------------------------------------------------------------------------
    def listen(self, t: float, block: np.ndarray, sample_rate: int) -> None:
        for utterance in self.ear.listen(t, block, sample_rate):
            self.root.hear(utterance)
            self.world.emit("sound", creature=self.name, start=utterance.time - len(utterance.samples) / sample_rate,
                            end=utterance.time, singing=self.mouth.sounding(t))

    # -- the tick ------------------------------------------------------------------------
    def tick(self, t: float) -> None:
        self.motivation.advance(t)
        self.group.temperature = self.spec.temperature * (1.0 + self.spec.curiosity * self.motivation.level("hear"))
        self.mouth.tick(t)
        if t >= self._next_pose:
            self._next_pose = t + 1.0 / self.spec.body_rate
            self.trail.follow(t)
            self.body.update(t)
        self.group.tick(t)
        if t >= self._next_report:
            self._next_report = t + REPORT_EVERY
            self._report(t)

    def _log_selection(self, event: dict[str, Any]) -> None:
        event = dict(event)
        kind, t = event.pop("event"), event.pop("t")
        event.pop("group", None)
        self.world.log.emit(t, kind, creature=self.name, **event)

    def _report(self, t: float) -> None:
        log = self.world.log
        log.emit(t, "values", creature=self.name, values={tp.name: tp.value.to_float() for tp in self.group.tuples})
        log.emit(t, "motivation", creature=self.name, drives={"hear": self.motivation.level("hear")},
                 temperature=self.group.temperature)
        log.emit(t, "percepts", creature=self.name,
                 sizes={p.name: len(p.members) for p in self.root.walk()})
        pose = self.body.pose  # what the body gives the voice (thesis: rib cage → amplitude)
        log.emit(t, "voice", creature=self.name, rib_cage=self.mouth.amplitude.feature(pose.positions),
                 amplitude=self.mouth.amplitude(pose), cutoff=self.mouth.cutoff(pose))
        self.trail.report(t)

    # -- outputs -------------------------------------------------------------------------
    def sound(self, out: np.ndarray, sample_rate: int) -> None:
        self.mouth.render(out, sample_rate, self.body.pose)

    def figure(self) -> tuple[np.ndarray, np.ndarray] | None:
        return self.body.pose.positions, np.asarray(self.body.skeleton.parents)

    # -- persistence ---------------------------------------------------------------------
    def state(self) -> dict[str, Any]:
        return {
            "tree": tree_state(self.root),
            "tuples": [[tp.trigger.name, tp.action.name, tp.name, tp.value.to_dict()] for tp in self.group.tuples],
            "motivation": self.motivation.to_dict(),
        }

    def restore(self, state: dict[str, Any]) -> None:
        """Rebuild the tree, then every tuple the state names (hypotheses too), with its value."""
        self.root = tree_from_state(state["tree"], like=self.root)
        self._singers.clear()
        self._build_group()
        percepts = {p.name: p for p in (*self.root.walk(), self.repertoire, self.always)}
        actions = {tp.action.name: tp.action for tp in self.group.tuples}
        try:
            for trigger, action, name, value in state["tuples"]:
                if name not in {tp.name for tp in self.group.tuples}:
                    act = (self.sing_from(percepts[action.removeprefix("sing ")]) if action.startswith("sing ")
                           else actions[action])
                    self.group.add(ActionTuple(name, percepts[trigger], act, self._do_until(act), 0.0))
                self.group.find(name).value = value_from_dict(value)
        except KeyError as exc:
            raise ValueError(f"{self.name}: saved tuples name an unknown percept or action {exc}") from None
        self.motivation.restore(state["motivation"], now=self.world.clock.now())
