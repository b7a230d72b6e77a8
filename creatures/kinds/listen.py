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
* **The population** (:class:`ModelPopulation`) is the percept-tree fission/fusion analogue
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
  :data:`FORGOTTEN` retire, as does the least useful while the population exceeds
  ``max_models``. Each state keeps only its last :data:`NOTES_KEPT` note references.
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
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from pydantic import Field, model_validator

from creatures.behaviour.action_group import ActionGroup
from creatures.behaviour.action_tuple import Action, ActionTuple, DoUntil
from creatures.behaviour.models.gaussian import GaussianModel
from creatures.behaviour.motivation import Motivation
from creatures.behaviour.percept import FunctionPercept, WhateverPercept
from creatures.kinds import register
from creatures.kinds.base import CreatureKind, CreatureSpec
from creatures.kinds.moves import Rest, head_for
from creatures.kinds.parts import Body, Voice, VoiceSpec
from creatures.kinds.report_parts import report_values, selection_logger
from creatures.motor.gesture import GestureModel, Observation
from creatures.motor.note_space import NotePlacement
from midi.notes import NoteEvent

FLOOR = 1e-3
"""Probability GestureModel.log_likelihood gives a transition the model has never seen."""

FORGOTTEN = 0.01
"""Usefulness below which a model that is not the best match retires."""

NOTES_KEPT = 8
"""Heard notes a model state keeps a reference to (their mean velocity sets predicted notes')."""

REPORT_EVERY = 0.5
"""Seconds between the values/motivation/percepts/motor snapshots in the events log."""


class ListenSpec(CreatureSpec):
    kind: Literal["listen"]
    hears_input: bool = Field(True, description="hear notes from outside the colony (else only other creatures)")
    memory: int = Field(16, ge=3, le=256, description="notes in the running memory buffer models are matched against")
    analysis_every: float = Field(0.5, gt=0, le=10, description="seconds between analyses of the model population "
                                                                 "(matching, learning, maintenance)")
    context: int = Field(4, ge=1, le=32, description="already-learnt notes put in front of new notes when a model "
                                                     "learns them, so it can find where they go")
    known: float = Field(0.2, ge=0, le=1, description="fraction of the arriving notes' transitions a model must "
                                                      "already explain to learn them (else a growing model extends "
                                                      "itself, or a new model is spawned)")
    max_models: int = Field(6, ge=1, le=64, description="most models in the population; the least useful retires")
    max_states: int = Field(96, ge=8, le=4096, description="states a model may grow to before it is distilled "
                                                           "to its core")
    forget: float = Field(120.0, gt=0, description="time constant (s) of a model's usefulness; unused models retire")
    continuation: int = Field(8, ge=0, le=256, description="predicted notes played when the music stops")
    predict_velocity: float = Field(0.4, gt=0, le=1, description="velocity of a predicted note, relative to the "
                                                                  "notes it was learnt from")
    patience: float = Field(2.0, gt=1, le=10, description="silence, in multiples of the expected gap, before the "
                                                          "creature starts anticipating")
    excitement: float = Field(0.3, ge=0, le=2, description="excitement added by each heard note")
    calm: float = Field(0.4, ge=0, description="rate (1/s) at which excitement decays")
    temperature: float | None = Field(None, gt=0, description="Boltzmann temperature of action selection")
    voice: VoiceSpec = VoiceSpec(voices=4)

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
        self.nodes = {int(p): int(n) for p, n in data.items()}
        self.pitches = {}
        for p, n in self.nodes.items():
            self.pitches.setdefault(n, p)


# --- the population of models -------------------------------------------------------------


@dataclass
class Member:
    """One model of the population, with what maintenance needs to know about it."""

    id: int
    model: GestureModel
    born: float
    usefulness: float = 0.0


class ModelPopulation:
    """Gesture models of heard notes: spawned, taught, fused, distilled and retired.

    ``on_event(kind, **fields)`` is told of every birth and retirement. Time only enters
    through the ``t`` arguments (usefulness decays by elapsed time, never by call count).
    """

    def __init__(self, *, known: float, evidence: int, max_models: int, max_states: int, forget: float,
                 on_event=None) -> None:
        self.members: list[Member] = []
        self.known = known
        self.evidence = evidence
        self.max_models = max_models
        self.max_states = max_states
        self.forget = forget
        self.best: Member | None = None
        self.best_score = -math.inf
        self._next_id = 0
        self._time = 0.0
        self._on_event = on_event or (lambda kind, **fields: None)

    @property
    def threshold(self) -> float:
        """Lowest mean log-likelihood of a window that a model may learn: that of a window
        with ``known`` of its transitions certain and the rest never heard."""
        return (1.0 - self.known) * math.log(FLOOR)

    def _spawn(self, t: float) -> Member:
        member = Member(self._next_id, GestureModel(), t)
        self._next_id += 1
        self.members.append(member)
        self._on_event("model", action="spawn", model=member.id)
        return member

    def _retire(self, member: Member, reason: str) -> None:
        self.members.remove(member)
        if self.best is member:
            self.best, self.best_score = None, -math.inf
        self._on_event("model", action="retire", model=member.id, reason=reason,
                       states=len(member.model.states))

    def learn(self, t: float, context: list[Observation], new: list[Observation]) -> Member | None:
        """Teach ``context + new`` to a model, spawn one for it, or wait for more evidence.

        In order: the model that best explains the transitions into and within the ``new``
        notes learns them; else a model still growing at that point (its state for the last
        context note leads nowhere yet) that explains the context extends itself; else, once
        at least ``evidence`` transitions are unexplained, a new model is spawned (fission).
        Returns None while waiting: the caller keeps the notes and asks again later.
        """
        arriving = context[-1:] + new
        window = context + new
        if self.members and len(arriving) >= 2:
            scores = [m.model.log_likelihood(arriving, floor=FLOOR) for m in self.members]
            if max(scores) >= self.threshold:
                return self._teach(self.members[int(np.argmax(scores))], window)
        growing = [m for m in self.members if context and _grows_from(m.model, context, self.threshold)]
        if growing:
            return self._teach(max(growing, key=lambda m: m.usefulness), window)
        if len(arriving) - 1 >= self.evidence:
            return self._teach(self._spawn(t), window)
        return None

    @staticmethod
    def _teach(member: Member, window: list[Observation]) -> Member:
        for state in member.model.learn(window):
            notes = member.model.states[state].notes
            del notes[:-NOTES_KEPT]
        return member

    def match(self, t: float, memory: list[Observation]) -> Member | None:
        """Choose the model that best explains ``memory``; it gains usefulness."""
        self._decay(t)
        if not self.members or len(memory) < 2:
            return self.best
        scores = np.array([m.model.log_likelihood(memory, floor=FLOOR) for m in self.members])
        k = int(np.argmax(scores))
        self.best, self.best_score = self.members[k], float(scores[k])
        self.best.usefulness += 1.0
        return self.best

    def _decay(self, t: float) -> None:
        factor = math.exp(-max(t - self._time, 0.0) / self.forget)
        self._time = max(t, self._time)
        for m in self.members:
            m.usefulness *= factor

    def maintain(self, t: float) -> None:
        """Fusion, distillation and retirement (the population stays bounded)."""
        for member in list(self.members):
            if len(member.model.states) > self.max_states:
                self._distil(member)
        cores: dict[tuple[int, ...], Member] = {}
        for member in sorted(self.members, key=lambda m: -m.usefulness):
            key = _cycle_key(member.model)
            if key is None:
                continue
            if key in cores:
                cores[key].usefulness += member.usefulness
                self._retire(member, "fused with model %d" % cores[key].id)
            else:
                cores[key] = member
        for member in [m for m in self.members if m is not self.best and m.usefulness < FORGOTTEN
                       and t - m.born > self.forget]:
            self._retire(member, "forgotten")
        while len(self.members) > self.max_models:
            spare = [m for m in self.members if m is not self.best]
            self._retire(min(spare, key=lambda m: (m.usefulness, -m.id)), "population full")

    def _distil(self, member: Member) -> None:
        """Replace a model overgrown with noise by one learnt from its core alone."""
        old = member.model
        core = old.core()
        fresh = GestureModel(entropy_weight=old.entropy_weight, threshold=old.threshold)
        times = np.concatenate(([0.0], np.cumsum([old.states[s].dwell for s in core[:-1]])))
        fresh.learn([Observation(old.states[s].node, float(u)) for s, u in zip(core, times)])
        if len(core) > 1 and core[0] in old.states[core[-1]].out:  # the core is a cycle: close it
            fresh.learn([Observation(old.states[core[-1]].node, 0.0),
                         Observation(old.states[core[0]].node, old.states[core[-1]].dwell)])
        self._on_event("model", action="distil", model=member.id, states=len(old.states), core=len(core))
        member.model = fresh

    def to_dict(self) -> dict[str, Any]:
        return {"next_id": self._next_id, "time": self._time,
                "best": None if self.best is None else self.best.id,
                "members": [{"id": m.id, "born": m.born, "usefulness": m.usefulness, "model": m.model.to_dict()}
                            for m in self.members]}

    def restore(self, data: dict[str, Any]) -> None:
        self._next_id, self._time = int(data["next_id"]), float(data["time"])
        self.members = [Member(int(m["id"]), GestureModel.from_dict(m["model"]), float(m["born"]),
                               float(m["usefulness"])) for m in data["members"]]
        self.best = next((m for m in self.members if m.id == data["best"]), None)


def _grows_from(model: GestureModel, context: list[Observation], threshold: float) -> bool:
    """Whether ``model`` explains ``context`` and its state for the last context note has no
    way on yet: new notes there extend the model rather than depart from it."""
    last = context[-1].node
    if not any(g.node == last and not g.out for g in model.states):
        return False
    return len(context) < 2 or model.log_likelihood(context, floor=FLOOR) >= threshold


def _cycle_key(model: GestureModel) -> tuple[int, ...] | None:
    """A model's core as a rotation-free key (the rotation starting at its smallest node)."""
    nodes = model.core_nodes()
    if len(nodes) < 3:
        return None
    k = int(np.argmin(nodes))
    return tuple(nodes[k:] + nodes[:k])


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
        candidates = [s for s, g in enumerate(states) if g.node == node]
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
    DEFAULT_GAP = 0.5
    """Seconds assumed between notes before any timing has been learnt."""

    def __init__(self, spec: ListenSpec, world, rng: np.random.Generator) -> None:
        super().__init__(spec, world, rng)
        self.body = Body(rng)
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
        root = WhateverPercept()
        music = FunctionPercept("music", lambda t: min(self.motivation.level("excitement", t), 1.0)
                                * (1.0 - self.silence(t)), parent=root)
        silence = FunctionPercept("silence", self.silence, parent=root)
        expecting = FunctionPercept("expecting", self.expecting, parent=silence)
        expected_all = FunctionPercept("expected all", lambda t: 1.0 - self.expecting(t))
        self.group = ActionGroup(
            self.name, rng=rng, temperature=spec.temperature, on_event=selection_logger(world, self.name),
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
        if source == "input" and not self.spec.hears_input:
            return
        observation = Observation(self.poses.node(note.pitch), float(note.time), note)
        self.memory.append(observation)
        self.heard.append(observation)
        self.unlearnt += 1
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
                        match=None if best is None else self.population.best_score, core=core)
        hand = self.body.hand()
        self.world.emit("motor", creature=self.name, node=self.body.motor.position(t).node,
                        position={"x": hand[0], "y": hand[1], "z": hand[2]})

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
        }

    def restore(self, state: dict[str, Any]) -> None:
        self.group.restore_values(state.get("values", {}))
        if "motivation" in state:
            self.motivation = Motivation.from_dict(state["motivation"], now=self.world.clock.now())
        if "poses" in state:
            self.poses.restore(state["poses"])
        if "population" in state:
            self.population.restore(state["population"])
            self.dance.follow(self.population.best)

