"""*Duncan*: the thesis's clicker-trained terrier ("Isle of man's best friend"; thesis
"clicker training", "simple shaping", "credit assignment", "percept trees").

A trainer speaks cues and clicks; the dog learns which cue means which trick, and begs higher
when higher begs are what gets clicked. Design decisions:

* **Hearing a cue.** Sound from the input audio is cut into utterances (the ear of
  *soundcreatures*, :class:`~creatures.kinds.hearing_parts.Ear`). Each utterance joins the
  nearest sound class of the "heard" utterance percept (a child within the cluster radius
  of its medoid) or, if none is that close, starts a new class. A cue is such a class: the
  dog never knows the word, only that this sound is not that one. The radius is the ear's
  shipped one (:data:`audio.utterance.DEFAULT_RADIUS`, 0.36): one espeak-ng voice saying
  "sit", "down" or "beg" at pitches 40–60 and speeds 140–175 lies within 0.20 of itself and
  at least 0.73 from the other words (measured for tests/test_duncan.py), so a trainer's
  varied "sit" stays one cue. A cue's percept then judges a sound by ``2 ** (−d / sharpness)``
  with d its distance to the nearest exemplar (1 for the sound just heard, which has joined
  its class): at sharpness 0.09 a "sit" triggers the "down" tuples 2 ** (−0.73 / 0.09) ≈
  0.4 % (at the radius it would be 24 %, and every click on a sit would also teach
  "down | sit"). (With the MFCC analysis before, the same held at radius 400 and sharpness
  100: distances 258 and 864.)
* **New hypotheses.** A new sound class is a new distinction, and the action-group gets a new
  tuple for every trick on it ("heard/1 | sit", "heard/1 | lie down", …; thesis "percept
  trees": a new percept lets the group try new action-tuples); they start a little above
  standing about, so an untried hypothesis gets tried. "whatever | stand" (non-plastic)
  grounds every value: a trick nobody clicks is blended toward β × the value of what follows.
* **Tricks offered unbidden are innate.** "quiet | trick" (nothing heard within the
  hearing's memory; "quiet" is the sibling of "heard" in the percept tree) has a fixed value
  below standing about, so the dog offers tricks now and then (and the trainer sees its
  repertoire) without learning to do them unbidden (as test_clicker's idle repertoire).
  Measured alternatives: plastic "whatever | trick" takes a share of every cue's click in
  full (its trigger is 1) and the dog sat unbidden in 60 % of silent probes; plastic
  "quiet | trick" is credited by value chaining whenever a cue interrupts it with the same
  trick (it was already lying when "down" came), and the dog lay down unbidden most of the
  time. The issue asks for ≤ 30 %.
* **The click is a reward from outside.** An ``[[input]]`` table with ``to = "reward"``
  (OSC, MIDI, a rehearsal file offline, or the simulated trainer's clicks offline:
  :mod:`creatures.runtime.trainer`, which watches :meth:`Duncan.holding`) credits the tuples active in its window, each in
  proportion to its trigger when it began (:meth:`ActionGroup.reward`): the cue's own tuple
  takes the credit when the cue was heard, an unbidden trick's none.
* **Tricks are places on the motor graph.** A trick is a label of the dog's body (sit, lie
  down, beg, roll over); doing it is an A* course to the nearest such pose, held there for
  ``hold`` seconds.
* **Shaping the beg** (thesis "simple shaping"). The beg clip rises from a low beg to a high
  one, every frame labelled "beg", so the graph holds a continuum of heights. An *Ac* percept
  — a rolling Gaussian model with a prior (:class:`~creatures.behaviour.models.gaussian.GaussianModel`)
  over the beg height ĥ in [0, 1] — is sampled when a beg starts; the dog goes to the beg
  pose nearest ĥ; a click that credits the beg feeds ĥ back into the model. Clicking only
  the higher begs moves the model, and the begs, up.

* **Tricks sound.** A trick the body gets to plays its note on the creature's voice (scanned
  strings pushed by its nose) and MIDI channel, a beg up to ``beg_notes`` semitones higher
  the higher it is: training the dog is playing it (thesis "'shaping' and music").

Events logged: ``cue`` (an utterance heard and the class it joined), ``hypothesis`` (a new
class and its tuples), ``trick`` (a trick started: name, tuple, beg height sampled) and
``trick held`` (the body got there: at what time, and the front paws' height for a beg),
``trick refused`` (no path on the motor graph reaches the trick's pose from where the body is), and
the group's ``selection``/``values``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, ClassVar, Literal

import numpy as np
from pydantic import BaseModel, Field, model_validator

from audio.utterance import Utterance, UtterancePercept
from creatures.behaviour.action_group import ActionGroup
from creatures.behaviour.action_tuple import Action, ActionTuple, DoUntil
from creatures.behaviour.models.gaussian import GaussianModel
from creatures.behaviour.percept import FunctionPercept, WhateverPercept
from creatures.behaviour.value import ScalarValue
from creatures.bounds import FINITE, LARGEST_RATE
from creatures.kinds import register
from creatures.kinds.base import CreatureKind, CreatureSpec, Holding, built_once
from creatures.kinds.figures import FigureBodySpec, figure_graph
from creatures.kinds.hearing_parts import Ear, HearingSpec, tree_from_state, tree_state
from creatures.kinds.moves import head_for
from creatures.kinds.parts import VOICE_READ_ONCE, Body, Voice, VoiceSpec, couple_to_hands
from creatures.kinds.report_parts import MotorTrail, report_values, selection_logger
from midi.notes import NoteEvent

if TYPE_CHECKING:
    from creatures.runtime.world import World

REPORT_EVERY = 5.0
"""Seconds between two ``values`` snapshots in the events log."""


class BegSpec(BaseModel):
    """``[creature.beg]``: the *Ac* percept of the beg's height ĥ (0 the lowest beg, 1 the highest)."""

    model_config = FINITE

    label: str = Field("beg", description="the body's label on every beg pose (of every height)")
    paw: str = Field("front_paw_l", description="the joint whose height is the beg's height")
    prior_mean: float = Field(0.2, ge=0, le=1, description="the beg height the dog tends to offer untrained")
    prior_std: float = Field(0.25, gt=0, le=1, description="how widely it varies its begs untrained")
    size: int = Field(6, ge=2, le=1024, description="clicked begs remembered (the rolling buffer: its plasticity)")
    prior_weight: float = Field(0.1, gt=0, le=1, description="pull of the prior on the model (never collapses)")


class DuncanSpec(CreatureSpec):
    kind: Literal["duncan"]
    body: FigureBodySpec = FigureBodySpec(figure="dog")
    tricks: list[str] = Field(["sit", "lie down", "beg", "roll over"], min_length=1, max_length=32,
                              description="the tricks, by the body's motor labels")
    offers: list[str] = Field(["sit", "lie down", "beg"], max_length=32,
                              description="tricks it offers unbidden now and then (its innate repertoire; not a "
                                          "roll over, which takes the longest to come out of when a cue comes; the default's "
                                          "tricks the dog lacks are dropped)")
    rest: str = Field("stand", description="the body's label for standing about (the grounding idle tuple)")
    hold: float = Field(1.5, gt=0, le=60, description="seconds a trick is held once the body is there")
    patience: float = Field(6.0, gt=0, le=600, description="longest a trick lasts, getting there included")
    idle: float = Field(2.0, gt=0, le=600, description="seconds of standing about before choosing again")
    trick_value: float = Field(1.5, ge=0, le=LARGEST_RATE, description="starting V of every trick hypothesis "
                               "(above standing about: an untried hypothesis is worth trying)")
    idle_value: float = Field(1.0, gt=0, le=LARGEST_RATE, description="V of standing about (not plastic: it "
                                                                       "grounds every learnt value)")
    unbidden_value: float = Field(0.5, ge=0, le=LARGEST_RATE, description="V of a trick offered unbidden (not "
                                                                          "plastic: the innate repertoire)")
    temperature: float = Field(0.2, gt=0, le=1e3, description="Boltzmann temperature of selection")
    alpha: float = Field(0.15, ge=0, le=1, description="credit assignment rate α")
    discount: float = Field(0.4, ge=0, le=1, description="credit discount β")
    classes: int = Field(8, ge=1, le=64, description="most sound classes (cues) the dog tells apart")
    sharpness: float = Field(0.09, gt=0, le=1e5, description="cepstral distance at which a cue's percept says ½ "
                                                                "of a sound (a sound it has heard says 1)")
    hearing: HearingSpec = HearingSpec(half_duplex=False, memory=1.0)
    beg: BegSpec = BegSpec()
    notes: dict[str, int] = Field({"sit": 60, "lie down": 55, "beg": 64, "roll over": 67, "stand": 48},
                                  description="trick → the MIDI pitch it sounds when the body gets there (the default's "
                                              "pitches of tricks the dog lacks are dropped)")
    beg_notes: int = Field(7, ge=0, le=24, description="semitones a beg's pitch rises from the lowest beg to the "
                                                       "highest (shaping the beg shapes a melody)")
    velocity: int = Field(90, ge=1, le=127, description="velocity of its notes")
    voice: VoiceSpec = VoiceSpec()
    READ_ONCE: ClassVar[dict[str, str]] = {
        **CreatureSpec.READ_ONCE, **VOICE_READ_ONCE,
        **built_once("body", "offers", "rest", "idle", "idle_value", "unbidden_value", "temperature", "alpha",
                     "discount", "classes", "hearing", "beg")}
    """What :class:`Duncan` builds when it starts: its body, the tuples of standing about and of
    the tricks it offers, its action-group, its ear and its beg model, and its strings. What a
    new cue's hypotheses are made of (``tricks``, ``patience``, ``trick_value``, ``sharpness``)
    is read when a cue is first heard; the rest as it runs."""

    @model_validator(mode="after")
    def _labels_on_the_body(self) -> "DuncanSpec":
        figure = self.body.figure
        if figure == "stick" and not self.body.custom:
            raise ValueError("duncan needs a body with tricks: [creature.body] figure = \"dog\", or a body of "
                             "its own whose takes label them")
        if not self.body.custom:  # a body from files is checked once built (Duncan.body_problem)
            poses = figure_graph(figure).poses
            problem = self.missing(poses.every_label, poses.skeleton.names, f"the {figure}")
            if problem is not None:
                raise ValueError(problem)
        for key, names in (("tricks", self.tricks), ("offers", self.offers)):
            twice = next((name for i, name in enumerate(names) if name in names[:i]), None)
            if twice is not None:  # one name, two tuples: twice the chance of it, one saved value
                raise ValueError(f"{key}: {twice!r} is named twice")
        # The defaults name the shipped tricks: their entries for tricks this dog lacks are not its own.
        # Set here, they stay unwritten: a live change of tricks (spec_keys.with_key validates
        # what was written) must filter them again, not take the defaults' "roll over" as the author's.
        if "offers" not in self.model_fields_set:
            self.offers = [offer for offer in self.offers if offer in self.tricks]
            self.model_fields_set.discard("offers")
        if "notes" not in self.model_fields_set:
            self.notes = {trick: pitch for trick, pitch in self.notes.items() if trick in [*self.tricks, self.rest]}
            self.model_fields_set.discard("notes")
        for offer in self.offers:
            if offer not in self.tricks:
                raise ValueError(f"offers: {offer!r} is not one of the tricks {self.tricks}")
        for trick, pitch in self.notes.items():
            if trick not in [*self.tricks, self.rest] or not 0 <= pitch + (self.beg_notes if trick == self.beg.label
                                                                             else 0) <= 127:
                raise ValueError(f"notes: {trick!r} = {pitch} must name a trick (or {self.rest!r}) and stay "
                                 f"within MIDI pitches 0..127")
        return self


    def missing(self, labels: frozenset[str], joints: tuple[str, ...], body: str) -> str | None:
        """What of the tricks, the rest and the beg ``body`` (its motor labels and joints) lacks."""
        for label in [*self.tricks, self.rest, self.beg.label]:
            if label not in labels:
                return f"{body} has no motor label {label!r} (labels: {sorted(labels)})"
        if self.beg.paw not in joints:
            return f"{body} has no joint {self.beg.paw!r} (the beg's paw)"
        return None


class Trick(Action):
    """Get the body to the nearest pose with a label and hold it (a beg: the pose of height ĥ).

    A pose no path reaches from where the body is (an edited graph, a body from files whose
    clip no edge enters) refuses the trick: it is logged (``trick refused``), the body carries
    on with what it was doing (:func:`~creatures.kinds.moves.head_for`) and the trick is never
    held, so no note sounds and no click can shape a beg it did not make; its tuple lasts its
    patience, as an unfinished trick does (ended at once, the group could choose it again on the
    next tick while its trigger holds: a trained cue's tuple, the most valued, refused tick after
    tick for as long as the cue is remembered)."""

    def __init__(self, dog: "Duncan", label: str) -> None:
        super().__init__(label)
        self.dog = dog
        self.nodes = dog.body.graph.poses.labelled(label)
        self.held_from: float | None = None
        self.height: float | None = None
        self.paw: float | None = None  # a beg's paw height once held, metres
        self.refused = False

    def start(self, t: float, tuple_: ActionTuple) -> None:
        targets = self.nodes
        self.height = None
        if self.name == self.dog.spec.beg.label:
            self.height = float(np.clip(self.dog.beg_height.sample(self.dog.rng), 0.0, 1.0))
            targets = [self.dog.beg_node(self.height)]
        self.held_from = None
        self.paw = None
        self.refused = not head_for(self.dog.body, t, list(targets))
        if self.refused:
            self.dog.trick_refused(t, self, tuple_)
        else:
            self.dog.trick_started(t, self, tuple_)

    def update(self, t: float) -> None:
        if self.held_from is None and not self.refused and self.dog.body.motor.arrived(t):
            self.held_from = t
            self.dog.trick_held(t, self)

    def done(self, t: float) -> float:
        return 1.0 if self.held_from is not None and t - self.held_from >= self.dog.spec.hold else 0.0


class Stand(Trick):
    """Standing about: to the nearest rest pose, then stay (Du is the idle time)."""

    def done(self, t: float) -> float:
        return 0.0


@register("duncan")
class Duncan(CreatureKind):
    """The clicker-trained dog (see the module docstring)."""

    Spec = DuncanSpec

    @classmethod
    def body_problem(cls, spec: DuncanSpec, labels: frozenset[str], joints: tuple[str, ...]) -> str | None:
        return spec.missing(labels, joints, "the body")

    def __init__(self, spec: DuncanSpec, world: "World", rng: np.random.Generator) -> None:
        super().__init__(spec, world, rng)
        self.body = Body(rng, spec=spec.body, figure=spec.body.figure)
        self.trail = MotorTrail(world, self.name, self.body)  # the path its body took (export-motion reads it)
        self.ear = Ear(spec.hearing)
        self.heard = UtterancePercept("heard", radius=spec.hearing.radius, memory=spec.hearing.memory,
                                      max_children=spec.classes, max_members=spec.hearing.keep,
                                      max_classes=spec.hearing.classes)
        b = spec.beg
        self.beg_height = GaussianModel(b.prior_mean, b.prior_std, size=b.size, prior_weight=b.prior_weight)
        beg_nodes = self.body.graph.poses.labelled(b.label)
        paw = self.body.skeleton.index(b.paw)
        heights = self.body.graph.poses.positions[beg_nodes, paw, 1]
        low, high = float(heights.min()), float(heights.max())
        self._beg_nodes, self._beg_heights = beg_nodes, (heights - low) / max(high - low, 1e-9)
        self._paw, self._paw_span = paw, (low, high)
        whatever = WhateverPercept()
        quiet = FunctionPercept("quiet", lambda t: 0.0 if self.heard.heard(t) is not None else 1.0)
        whatever.add_child(self.heard)
        whatever.add_child(quiet)
        standing = ActionTuple(f"whatever|{spec.rest}", whatever, Stand(self, spec.rest), DoUntil(spec.idle),
                               ScalarValue(spec.idle_value, plasticity=0.0))
        tuples = [standing] + [self._hypothesis(quiet, trick, ScalarValue(spec.unbidden_value, plasticity=0.0))
                               for trick in spec.offers]
        self.group = ActionGroup("duncan", tuples, rng=rng, alpha=spec.alpha, discount=spec.discount,
                                 temperature=spec.temperature, on_event=selection_logger(world, self.name))
        self.doing: Trick | None = None
        self.voice: Voice | None = None
        self._next_report = 0.0

    def _hypothesis(self, trigger, trick: str, value: ScalarValue | None = None) -> ActionTuple:
        action = Trick(self, trick)
        stop = FunctionPercept(f"{trick} held", action.done)
        return ActionTuple(f"{trigger.name}|{trick}", trigger, action, DoUntil(self.spec.patience, until=stop),
                           value or ScalarValue(self.spec.trick_value))

    @classmethod
    def tricks(cls, spec: DuncanSpec) -> tuple[str, ...]:
        return tuple(spec.tricks)

    @classmethod
    def graded_tricks(cls, spec: DuncanSpec) -> tuple[str, ...]:
        return (spec.beg.label,) if spec.beg.label in spec.tricks else ()

    def holding(self) -> Holding | None:
        """The trick held now (standing about is none), a beg with its paw's height: what the
        in-run trainer (:mod:`creatures.runtime.trainer`) sees, as a person would."""
        trick = self.doing
        if trick is None or trick.held_from is None or isinstance(trick, Stand):
            return None
        return Holding(trick.name, trick.held_from, trick.paw)

    def beg_node(self, height: float) -> int:
        """The beg pose whose paw height (0 the lowest beg, 1 the highest) is nearest ``height``."""
        return int(self._beg_nodes[int(np.argmin(np.abs(self._beg_heights - height)))])

    # -- hearing ----------------------------------------------------------------------------
    def listen(self, t: float, block: np.ndarray, sample_rate: int) -> None:
        for utterance in self.ear.listen(t, block, sample_rate):
            self.heard.hear(utterance)
            self._classify(utterance)

    def _classify(self, utterance: Utterance) -> None:
        """Add ``utterance`` to the nearest sound class within the radius, or start a class."""
        classes = self.heard.utterance_children()
        if classes:
            d = self.heard.distances_from(utterance, [c.medoid for c in classes])
            nearest = int(np.argmin(d))
            if d[nearest] <= self.heard.radius:
                cls = classes[nearest]
                cls.members = (cls.members + [utterance])[: cls.max_members]
                cls._similarity = None
                self.world.emit("cue", creature=self.name, sound=cls.name, distance=float(d[nearest]))
                return
        if len(classes) >= self.heard.max_children:
            self.world.emit("cue", creature=self.name, sound=None, distance=None)
            return
        cls = self.heard._new_child()
        cls.radius = self.spec.sharpness  # how it judges sounds; joining a class is by the hearing's radius
        cls.members = [utterance]
        names = [self.group.add(self._hypothesis(cls, trick)).name for trick in self.spec.tricks]
        self.world.emit("cue", creature=self.name, sound=cls.name, distance=0.0)
        self.world.emit("hypothesis", creature=self.name, percept=cls.name, tuples=names)

    # -- the body doing tricks ------------------------------------------------------------------
    def trick_started(self, t: float, trick: Trick, tuple_: ActionTuple) -> None:
        self.doing = trick
        self.world.emit("trick", creature=self.name, trick=trick.name, tuple=tuple_.name, height=trick.height)

    def trick_refused(self, t: float, trick: Trick, tuple_: ActionTuple) -> None:
        """No path reaches the trick's pose from where the body is: said, and nothing is under way."""
        self.doing = None
        self.world.emit("trick refused", creature=self.name, trick=trick.name, tuple=tuple_.name, height=trick.height,
                        why="no path on the motor graph from where the body is to the trick's pose")

    def trick_held(self, t: float, trick: Trick) -> None:
        """The body got there: log it and sound the trick's note (a beg's higher the higher it is)."""
        paw = float(self.body.pose.positions[self._paw, 1]) if trick.height is not None else None
        trick.paw = paw
        self.world.emit("trick held", creature=self.name, trick=trick.name, paw=paw)
        pitch = self.spec.notes.get(trick.name)
        if pitch is not None:
            rise = 0 if trick.height is None else round(trick.height * self.spec.beg_notes)
            note = NoteEvent(round(t, 6), pitch + rise, self.spec.velocity, self.spec.channel, self.spec.hold)
            self.world.play(self, note)
            if self.voice is not None:
                self.voice.play(note.pitch, note.velocity, note.end)

    def sound(self, out: np.ndarray, sample_rate: int) -> None:
        if self.voice is None:
            self.voice = Voice(self.spec.voice, sample_rate)
            couple_to_hands(self.voice, self.body)  # the nose pushes the strings
        self.voice.render(out, self.world.clock.now(), gain=self.spec.voice.gain)

    def reward(self, amount: float, t: float, window: float, rate: float) -> list[str]:
        """The click: credit assignment as for any reward (:meth:`CreatureKind.reward`), and a
        beg it credits feeds its height into the beg model (thesis "simple shaping")."""
        credited = super().reward(amount, t, window, rate)
        trick = self.doing
        if amount > 0 and trick is not None and trick.height is not None and any(
                name.endswith(f"|{trick.name}") for name in credited):
            self.beg_height.update(trick.height)
            self.world.emit("shaped", creature=self.name, height=trick.height, mean=self.beg_height.mean)
        return credited

    def tick(self, t: float) -> None:
        self.trail.follow(t)
        pose = self.body.update(t)
        if self.voice is not None:
            self.voice.feel(pose)
        self.group.tick(t)
        if t >= self._next_report:
            self._next_report = t + REPORT_EVERY
            report_values(self.world, t, self.name, self.group)
            self.trail.report(t)

    def figure(self) -> tuple[np.ndarray, np.ndarray] | None:
        return self.body.pose.positions, np.asarray(self.body.skeleton.parents)

    # -- persistence ----------------------------------------------------------------------
    def state(self) -> dict[str, Any]:
        return {"values": self.unplaced_parts.carry("values", self.group.value_state()), "beg": self.beg_height.to_dict(), "tree": tree_state(self.heard)}

    def restore(self, state: dict[str, Any]) -> None:
        """Values, the sound classes and the beg model's samples come back. A cue's tuples
        ("heard/k | trick") exist only while its class does, so the classes (their exemplars,
        :func:`tree_state`) are taken back first, in place (the percept tree holds the root),
        each judging sounds at the config's sharpness, and every one gets its hypotheses again
        for the values to land on (thesis "percept trees": the learnt distinctions are what the
        dog was trained on; without them a restarted dog forgot every cue). The beg model's
        prior and size are settings (thesis "simple shaping": the prior is the authored
        expectation), so the config's win: the saved samples, oldest first, are pushed into a
        model of the config's own (a smaller one keeps the newest)."""
        if "tree" in state:  # a state saved before the classes were kept has none
            tree = tree_from_state(state["tree"], like=self.heard)
            for cls in tree.utterance_children():
                self.heard.add_child(cls)
                cls.radius = self.spec.sharpness
                for trick in self.spec.tricks:
                    self.group.add(self._hypothesis(cls, trick))
            self.heard._born = tree._born  # a class formed from now on takes a new name
        if "values" in state:  # a trick's tuples the config no longer has (its trick renamed or removed): kept
            self.group.restore_values(self.unplaced_parts.place("values", state["values"],
                                                                {tp.name for tp in self.group.tuples},
                                                                what="value", of="tuple"))
        if "beg" in state:
            saved = GaussianModel.from_dict(state["beg"])  # checks every number
            b = self.spec.beg
            self.beg_height = GaussianModel(b.prior_mean, b.prior_std, size=b.size, prior_weight=b.prior_weight)
            for x, weight in saved.observations():
                self.beg_height.update(x, weight)
