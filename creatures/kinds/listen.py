"""*listen*: a creature that dances to what it hears by modelling it (thesis "listen
(installation)"; the models are those of "gesture graph generation", figure 32).

"While active the bulk of the creature's computation is spent maintaining a *population* of
percepts modelling sequences and timings of notes. These models are nothing other than the
gesture recognition models from the graph-based motor system." Design decisions:

* **Notes as body poses.** Every pitch heard is given its own motor-graph node — the pose
  whose hand is nearest the place :class:`~creatures.motor.note_space.NotePlacement` gives
  that pitch, taking a free node so the mapping is one-to-one (:class:`NotePoses`; "use the
  body representations to represent music, and musical ideas to represent space"). A model
  state is then a :class:`~creatures.motor.gesture.GestureNode` whose ``node`` is that
  BodyPose reference and whose ``notes`` are the heard notes, exactly as the thesis
  repurposes them; models match on node identity (pointer comparison in the thesis).
* **The running memory** is a deque of :class:`~creatures.motor.gesture.Observation` of the
  last ``memory`` notes (not a ``BodyMemory``: that drops a repeated node, but a repeated
  note is a new musical event).
* **The population** (:class:`~creatures.kinds.model_population.ModelPopulation`) is the percept-tree fission/fusion analogue
  for models "that themselves have no idea how to split": every ``analysis_every`` seconds
  (its own rate, with a random phase) the notes heard since the last analysis, behind
  ``context`` already-learnt notes that let a model find where they go ("23456 is explained
  by 2345, so only 6 is added"), are learnt by the model that best explains their
  transitions (at least ``known`` of them), else by a model still growing at that point,
  else — once ``context`` transitions in a row are unexplained — by a newly spawned model
  (fission; a single odd transition between two known phrases spawns nothing). Models
  whose cores are the same cycle are fused (the less useful retires); a model grown past
  ``max_states`` is distilled to its core; usefulness (how often a model was the best
  match) decays with time constant ``forget`` and models that fall below
  :data:`~creatures.kinds.model_population.FORGOTTEN` retire, as does the least useful while the population exceeds
  ``max_models``. Each state keeps only its last :data:`~creatures.kinds.model_population.NOTES_KEPT` note references.
* **Dancing.** The model with the highest mean log-likelihood of the whole memory buffer is
  the one played out. Each heard note is located among that model's states (preferring a
  successor of the current state) and the body sets off, by A* through the motor graph,
  towards the pose of the *predicted next* state — reactive in when it moves, predictive in
  where. When the music stops, the *anticipate* action keeps stepping through the model at
  the timing stored in its states (``dwell``) and plays what it predicts, quietly
  (``predict_velocity``), for at most ``continuation`` notes; then the creature rests.
  Steps are timed by the music (or the model's learnt timing), not by a
  :class:`~creatures.motor.programs.MotorProgram`'s arrivals, so the dance keeps the
  phrase's period even when a path takes longer than a note: the course is re-aimed.
* **Behaviour.** An :class:`ActionGroup` chooses between *dance* (triggered by the
  *excitement* drive that each heard note raises), *anticipate* (triggered by silence while
  the model still predicts notes) and *rest* (go to a low-energy pose).
* **Expecting the match** (thesis "expectations about value"). How well the best model
  predicted the notes heard since the last analysis (the mean log-probability of their
  transitions, before they are learnt) is itself modelled by a
  :class:`~creatures.behaviour.value.GaussianValue`, taught at every analysis that follows
  new notes. A repeated phrase makes it *confident* (its expectation keeps being met); new
  material is *surprising* (the match falls far below what it expects) until a model of it
  has formed and become the best; a long silence lets the confidence fade. Both are logged with the percepts and
  the expectation is saved with the creature, so the inspector can show them.
"""

from __future__ import annotations

import math
from collections import deque
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from pydantic import Field, model_validator

from creatures.behaviour.action_group import ActionGroup
from creatures.behaviour.action_tuple import Action, ActionTuple, DoUntil
from creatures.behaviour.models.gaussian import GaussianModel
from creatures.behaviour.motivation import Motivation
from creatures.behaviour.percept import FunctionPercept, WhateverPercept
from creatures.behaviour.value import GaussianValue, ScalarValue
from creatures.kinds import register
from creatures import bounds
from creatures.bounds import LARGEST_RATE, LONGEST_SECONDS
from creatures.kinds.base import CreatureKind, CreatureSpec
from creatures.kinds.model_population import FLOOR, MOST_MODELS, MOST_STATES, Member, ModelPopulation
from creatures.kinds.moves import Rest, head_for
from creatures.kinds.layers import BodySpec
from creatures.kinds.parts import Body, Voice, VoiceSpec
from creatures.kinds.report_parts import MotorTrail, report_values, selection_logger
from creatures.motor.gesture import GestureModel, Observation
from creatures.motor.note_space import NotePlacement
from midi.notes import NoteEvent

if TYPE_CHECKING:
    from creatures.runtime.world import World

REPORT_EVERY = 0.5
"""Seconds between the values/motivation/percepts/motor snapshots in the events log."""

MATCH_RATE = 0.3
"""How far each analysis moves the expected match towards the match found (the blend's α)."""


class ListenSpec(CreatureSpec):
    kind: Literal["listen"]
    memory: int = Field(16, ge=3, le=256, description="notes in the running memory buffer models are matched against")
    analysis_every: float = Field(0.5, gt=0, le=10, description="seconds between analyses of the model population "
                                                                 "(matching, learning, maintenance)")
    context: int = Field(4, ge=1, le=32, description="already-learnt notes put in front of new notes when a model "
                                                     "learns them, so it can find where they go")
    known: float = Field(0.2, ge=0, le=1, description="fraction of the arriving notes' transitions a model must "
                                                      "already explain to learn them (else a growing model extends "
                                                      "itself, or a new model is spawned)")
    max_models: int = Field(6, ge=1, le=MOST_MODELS, description="most models in the population; the least useful retires")
    max_states: int = Field(96, ge=8, le=MOST_STATES, description="states a model may grow to before it is distilled "
                                                           "to its core")
    forget: float = Field(120.0, gt=0, le=LONGEST_SECONDS, description="time constant (s) of a model's usefulness; unused models retire")
    continuation: int = Field(8, ge=0, le=256, description="predicted notes played when the music stops")
    predict_velocity: float = Field(0.4, gt=0, le=1, description="velocity of a predicted note, relative to the "
                                                                  "notes it was learnt from")
    patience: float = Field(2.0, gt=1, le=10, description="silence, in multiples of the expected gap, before the "
                                                          "creature starts anticipating")
    excitement: float = Field(0.3, ge=0, le=2, description="excitement added by each heard note")
    calm: float = Field(0.4, ge=0, le=LARGEST_RATE, description="rate (1/s) at which excitement decays")
    temperature: float | None = Field(None, gt=0, le=1e3, description="Boltzmann temperature of action selection")
    voice: VoiceSpec = VoiceSpec(voices=4)
    body: BodySpec = BodySpec()

    @model_validator(mode="after")
    def _context_fits(self) -> "ListenSpec":
        if self.context >= self.memory:
            raise ValueError(f"context ({self.context}) must be smaller than memory ({self.memory}): "
                             "the memory holds the context and the new notes")
        return self


# --- notes as poses -----------------------------------------------------------------------


class NotePoses:
    """Pitch → the motor-graph node (BodyPose) that pitch is danced with, one node per pitch.

    The node is the free one whose hand is nearest the pitch's place in space
    (:class:`NotePlacement`, at a middle key velocity so loudness does not change identity).
    Once every node is taken (more pitches than poses) pitches share their nearest node.
    """

    VELOCITY = 64

    def __init__(self, reach: np.ndarray) -> None:
        self.reach = np.asarray(reach, dtype=float)
        self.placement = NotePlacement.around(self.reach)
        self.nodes: dict[int, int] = {}
        self.pitches: dict[int, int] = {}

    def node(self, pitch: int) -> int:
        if pitch not in self.nodes:
            gap = np.linalg.norm(self.reach - self.placement.place(pitch, self.VELOCITY), axis=1)
            if len(self.pitches) < len(gap):
                gap[list(self.pitches)] = np.inf
            node = int(np.argmin(gap))
            self.nodes[pitch] = node
            self.pitches.setdefault(node, pitch)
        return self.nodes[pitch]

    def pitch(self, node: int) -> int | None:
        return self.pitches.get(node)

    def to_dict(self) -> dict[str, int]:
        return {str(p): n for p, n in self.nodes.items()}

    def restore(self, data: dict[str, int]) -> None:
        """Take back pitch → node; a pitch outside MIDI or a node outside the graph is refused."""
        saved = bounds.table(data, "poses")
        if not all(key.isdigit() for key in saved):
            raise ValueError("poses: keys must be MIDI pitches")
        self.nodes = {bounds.count(int(p), "poses", high=127): bounds.count(n, f"poses.{p}", high=len(self.reach) - 1)
                      for p, n in saved.items()}
        self.pitches = {}
        for p, n in self.nodes.items():
            self.pitches.setdefault(n, p)


# --- the dance ----------------------------------------------------------------------------


class Dance:
    """Where in the played-out model the creature is, and where its body is heading."""

    def __init__(self) -> None:
        self.model: GestureModel | None = None
        self.state: int | None = None
        self.at: float = 0.0

    def follow(self, member: Member | None) -> None:
        """Play out ``member`` from now on (or its distilled model), re-locating the
        current note in it."""
        model = None if member is None else member.model
        if model is self.model:
            return
        node = None if self.model is None or self.state is None else self.model.states[self.state].node
        self.model, self.state = model, None
        self.state = None if node is None else self.locate(node)

    def locate(self, node: int) -> int | None:
        """The model state standing for ``node``: a successor of the current state if one
        is, else the most visited state of that node, else None (an unheard-of note)."""
        if self.model is None:
            return None
        states = self.model.states
        if self.state is not None:
            following = [s for s in states[self.state].out if states[s].node == node]
            if following:
                return max(following, key=states[self.state].out.get)
        candidates = self.model.states_of(node)
        return max(candidates, key=lambda s: states[s].visits) if candidates else None

    def predicted(self) -> int | None:
        """The most probable next state."""
        if self.model is None or self.state is None:
            return None
        out = self.model.states[self.state].out
        return max(out, key=out.get) if out else None

    def gap(self, default: float) -> float:
        """Expected seconds until the next note (the state's learnt dwell)."""
        if self.model is None or self.state is None:
            return default
        dwell = self.model.states[self.state].dwell
        return dwell if dwell > 0 else default


# --- actions ------------------------------------------------------------------------------


class _Dance(Action):
    """Dance to the music: every heard note sends the body towards the predicted next pose."""

    def __init__(self, creature: "Listen") -> None:
        super().__init__("dance")
        self.creature = creature

    def update(self, t: float) -> None:
        self.creature.step_with_music(t)


class _Anticipate(Action):
    """The music stopped: carry on through the model at its own timing, playing quietly."""

    def __init__(self, creature: "Listen") -> None:
        super().__init__("anticipate")
        self.creature = creature

    def start(self, t: float, tuple_: ActionTuple) -> None:
        self.creature.dance.at = t

    def update(self, t: float) -> None:
        self.creature.step_alone(t)


# --- the creature -------------------------------------------------------------------------


@register("listen")
class Listen(CreatureKind):
    Spec = ListenSpec
    DRIVES = ("excitement",)
    DEFAULT_GAP = 0.5
    """Seconds assumed between notes before any timing has been learnt."""

    def __init__(self, spec: ListenSpec, world: "World", rng: np.random.Generator) -> None:
        super().__init__(spec, world, rng)
        self.body = Body(rng, spec=spec.body)
        self.trail = MotorTrail(world, self.name, self.body)
        self.poses = NotePoses(self.body.reach())
        self.memory: deque[Observation] = deque(maxlen=spec.memory)
        self.unlearnt = 0
        self.heard: deque[Observation] = deque()  # heard since the last dance step
        self.last_heard = -math.inf
        self.population = ModelPopulation(known=spec.known, evidence=spec.context, max_models=spec.max_models,
                                          max_states=spec.max_states, forget=spec.forget,
                                          on_event=lambda kind, **f: self.world.emit(kind, creature=self.name, **f))
        self.dance = Dance()
        self.voice: Voice | None = None
        self.motivation = Motivation({"excitement": 0.0}, decay={"excitement": spec.calm},
                                     equilibrium={"excitement": 0.0}, ceiling=2.0)
        self.continued = 0  # notes played since the music stopped
        # Expects a perfect match (0 nats), give or take one, until the music says otherwise.
        self.expected_match = GaussianValue(0.0, spread=1.0, clock=world.clock)
        self.surprise = 0.0  # how surprising the last match was (0: as expected)
        self._new_notes = 0  # heard since the last analysis
        root = WhateverPercept()
        music = FunctionPercept("music", lambda t: min(self.motivation.level("excitement", t), 1.0)
                                * (1.0 - self.silence(t)), parent=root)
        silence = FunctionPercept("silence", self.silence, parent=root)
        expecting = FunctionPercept("expecting", self.expecting, parent=silence)
        expected_all = FunctionPercept("expected all", lambda t: 1.0 - self.expecting(t))
        # Values as authored (alpha = 0), as in exchange: nothing here is a consummatory reward,
        # so credit assignment would only shrink every value by the discount at each
        # selection (one simulated hour took 3.0/2.0/0.3 to ~1e-7; ActionGroup now refuses it).
        self.group = ActionGroup(
            self.name, rng=rng, alpha=0.0, temperature=spec.temperature,
            on_event=selection_logger(world, self.name),
            tuples=[
                ActionTuple("dance", music, _Dance(self), DoUntil(GaussianModel(6.0, 2.0), until=silence), 3.0),
                ActionTuple("anticipate", expecting, _Anticipate(self),
                            DoUntil(20.0, until=expected_all), 2.0),
                ActionTuple("rest", root, Rest(self.body), DoUntil(GaussianModel(3.0, 1.0)), 0.3),
            ],
        )
        self._next_analysis = float(rng.uniform(0.0, spec.analysis_every))  # random phase
        self._next_report = 0.0

    # -- hearing -------------------------------------------------------------------------
    def hear(self, note: NoteEvent, source: str) -> None:
        observation = Observation(self.poses.node(note.pitch), float(note.time), note)
        self.memory.append(observation)
        self.heard.append(observation)
        self.unlearnt += 1
        self._new_notes += 1
        self.continued = 0
        self.last_heard = max(self.last_heard, float(note.time))
        self.motivation.perturb(self.world.clock.now(), "excitement", self.spec.excitement)

    def silence(self, t: float) -> float:
        """1 once the music has been quiet for ``patience`` expected gaps (after some music)."""
        if not self.memory:
            return 0.0
        return 1.0 if t - self.last_heard > self.spec.patience * self.dance.gap(self.DEFAULT_GAP) else 0.0

    def expecting(self, t: float) -> float:
        """1 while, in a silence, the model still predicts notes the creature may play."""
        ready = self.continued < self.spec.continuation and self.dance.predicted() is not None
        return self.silence(t) if ready else 0.0

    # -- analysis (its own, slower rate) ---------------------------------------------------
    def analyse(self, t: float) -> None:
        memory = list(self.memory)
        self._expect(memory)
        if self.unlearnt:
            split = len(memory) - min(self.unlearnt, len(memory))
            context = memory[max(split - self.spec.context, 0):split]
            if self.population.learn(t, context, memory[split:]) is not None:
                self.unlearnt = 0
            else:
                self.unlearnt = min(self.unlearnt, self.spec.memory - self.spec.context)
        self.population.match(t, memory)
        self.population.maintain(t)
        self.dance.follow(self.population.best)

    def _expect(self, memory: list[Observation]) -> None:
        """How well the best model predicted the notes heard since the last analysis (before
        anything learns them): how surprising that is, then the expectation learns it."""
        new = min(self._new_notes, len(memory) - 1)
        self._new_notes = 0
        best = self.population.best
        if best is None or new < 1:
            return
        match = best.model.log_likelihood(memory[-(new + 1):], floor=FLOOR)
        self.surprise = self.expected_match.surprise(match)
        self.expected_match.blend_to(ScalarValue(match), MATCH_RATE)

    # -- dancing -----------------------------------------------------------------------------
    def step_with_music(self, t: float) -> None:
        """Each note heard since the last step moves the dance on; the body heads for the
        pose of the note the model predicts next (or of the note itself, if none)."""
        while self.heard:
            observation = self.heard.popleft()
            self.dance.state = self.dance.locate(observation.node)
            self.dance.at = t
            self._move_on(t, observation.node)

    def step_alone(self, t: float) -> bool:
        """Without music: move to the predicted state when its time comes and play its note
        quietly. Returns True when a note was played."""
        nxt = self.dance.predicted()
        if nxt is None or t - self.dance.at < self.dance.gap(self.DEFAULT_GAP):
            return False
        self.dance.state, self.dance.at = nxt, t
        state = self.dance.model.states[nxt]
        self._move_on(t, state.node)
        pitch = self.poses.pitch(state.node)
        if pitch is None:
            return False
        velocity = np.mean([n.velocity for n in state.notes]) if state.notes else 90
        duration = min(max(state.dwell, 0.1), 2.0)
        self.continued += 1
        self.world.play(self, NoteEvent(t, pitch, max(1, int(velocity * self.spec.predict_velocity)),
                                        self.spec.channel, duration))
        return True

    def _move_on(self, t: float, node: int) -> None:
        """Head for the pose of the state predicted after the current one (else of ``node``)."""
        nxt = self.dance.predicted()
        head_for(self.body, t, [self.dance.model.states[nxt].node if nxt is not None else node])

    # -- the tick ------------------------------------------------------------------------------
    def tick(self, t: float) -> None:
        self.motivation.advance(t)
        if t >= self._next_analysis:
            self._next_analysis = t + self.spec.analysis_every
            self.analyse(t)
        self.trail.follow(t)
        self.body.update(t)
        self.group.tick(t)
        if not any(tp.name == "dance" for tp in self.group.active):
            self.heard.clear()  # notes heard while not dancing are remembered, not danced
        if t >= self._next_report:
            self._next_report = t + REPORT_EVERY
            self._report(t)

    def _report(self, t: float) -> None:
        report_values(self.world, t, self.name, self.group, self.motivation)
        best = self.population.best
        core = [] if best is None else [self.poses.pitch(n) for n in best.model.core_nodes()]
        self.world.emit("percepts", creature=self.name,
                        sizes={"models": len(self.population.members), "memory": len(self.memory),
                               "states of best": 0 if best is None else len(best.model.states)},
                        best=None if best is None else best.id,
                        match=None if best is None else self.population.best_score, core=core,
                        expected_match=self.expected_match.to_float(), surprise=self.surprise,
                        confidence=self.expected_match.confidence())
        self.trail.report(t)

    # -- outputs -------------------------------------------------------------------------------
    def played(self, note: NoteEvent) -> None:
        if self.voice is not None:
            self.voice.play(note.pitch, note.velocity, note.end)

    def sound(self, out: np.ndarray, sample_rate: int) -> None:
        if self.voice is None:
            self.voice = Voice(self.spec.voice, sample_rate)
        self.voice.render(out, self.world.clock.now())

    def figure(self) -> tuple[np.ndarray, np.ndarray] | None:
        return self.body.pose.positions, np.asarray(self.body.skeleton.parents)

    # -- persistence ---------------------------------------------------------------------------
    def state(self) -> dict[str, Any]:
        return {
            "values": self.group.value_state(),
            "motivation": self.motivation.to_dict(),
            "poses": self.poses.to_dict(),
            "population": self.population.to_dict(),
            "expected match": self.expected_match.to_dict(),
        }

    def restore(self, state: dict[str, Any]) -> None:
        # Values are authored (alpha = 0): the config is their truth, and a state saved while
        # credit assignment still decayed them must not carry the decay into this run.
        if "motivation" in state:
            self.motivation.restore(state["motivation"], now=self.world.clock.now())
        if "poses" in state:
            self.poses.restore(state["poses"])
        if "population" in state:
            self.population.restore(state["population"], nodes=len(self.body.graph))
            self.dance.follow(self.population.best)
        if "expected match" in state:
            self.expected_match.restore(state["expected match"])

