"""A population of sequence models kept in a percept, and a body that dances the best of
them (thesis "listen (installation)", figure 43 "keeping a model population in a percept";
the models are those of "gesture graph generation", figure 32).

"While active the bulk of the creature's computation is spent maintaining a *population* of
percepts modelling sequences and timings of notes. These models are nothing other than the
gesture recognition models from the graph-based motor system." The percept type
``population`` (:mod:`creatures.authored.percepts`) builds one :class:`Listening`; the
percepts ``lull`` and ``predicts`` and the actions ``dance`` and ``anticipate`` read it by
name. Design decisions, kept from the class-based *listen* this replaces:

* **Notes as body poses.** Every pitch heard is given its own motor-graph node — the pose
  whose hand is nearest the place :class:`~creatures.motor.note_space.NotePlacement` gives
  that pitch, taking a free node so the mapping is one-to-one (:class:`NotePoses`; "use the
  body representations to represent music, and musical ideas to represent space"). A model
  state is a :class:`~creatures.motor.gesture.GestureNode` whose ``node`` is that BodyPose
  reference and whose ``notes`` are the heard notes, as the thesis repurposes them.
* **The running memory** is a deque of :class:`~creatures.motor.gesture.Observation` of the
  last ``memory`` notes (a repeated note is a new musical event, so not a ``BodyMemory``).
* **The population** (:class:`~creatures.kinds.model_population.ModelPopulation`) is
  analysed every ``analysis_every`` seconds (its own rate, random phase): the notes heard
  since the last analysis, behind ``context`` already-learnt notes, are learnt by the model
  that best explains them, else by one still growing there, else by a newly spawned model
  (fission); same-cycle models fuse, overgrown ones are distilled, unused ones retire.
* **Dancing.** The model with the highest mean log-likelihood of the memory is played out:
  each heard note is located among its states and the body sets off, by A*, towards the pose
  of the *predicted next* state — reactive in when it moves, predictive in where. When the
  music stops, ``anticipate`` steps through the model at its learnt timing (``dwell``) and
  plays what it predicts quietly, for at most ``continuation`` notes. Steps are timed by the
  music, not by arrivals, so the dance keeps the phrase's period.
* **Expecting the match** (thesis "expectations about value"). How well the best model
  predicted the notes heard since the last analysis is modelled by a
  :class:`~creatures.behaviour.value.GaussianValue`: a repeated phrase makes it confident,
  new material surprising. Both are logged (``percepts`` events) and saved.
"""

from __future__ import annotations

import math
from collections import deque
from typing import TYPE_CHECKING, Any

import numpy as np

from creatures import bounds
from creatures.behaviour.percept import Percept
from creatures.behaviour.value import GaussianValue, ScalarValue
from creatures.kinds.model_population import FLOOR, Member, ModelPopulation
from creatures.kinds.moves import head_for
from creatures.motor.gesture import GestureModel, Observation
from creatures.motor.note_space import NotePlacement
from midi.notes import NoteEvent

if TYPE_CHECKING:
    from creatures.authored.creature import Authored
    from creatures.authored.maps import MusicPoseMaps

DEFAULT_GAP = 0.5
"""Seconds assumed between notes before any timing has been learnt."""

MATCH_RATE = 0.3
"""How far each analysis moves the expected match towards the match found (the blend's α)."""


# --- notes as poses -----------------------------------------------------------------------
class NotePoses:
    """Pitch → the motor-graph node (BodyPose) that pitch is danced with, one node per pitch.

    The node is the free one whose hand is nearest the pitch's place in space (at a middle
    key velocity, so loudness does not change identity). Once every node is taken (more
    pitches than poses) pitches share their nearest node.
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
        """Play out ``member`` from now on, re-locating the current note in it."""
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


# --- the percept that keeps the population --------------------------------------------------
class Listening(Percept):
    """The model population of one creature, kept in a percept (figure 43). Its saliency is
    how familiar the music is: ``exp`` of the best model's mean log-likelihood of the memory
    (1: every transition certain; 0 before any model). ``params`` are the ``population``
    percept's keys."""

    def __init__(self, name: str, creature: "Authored", params: Any) -> None:
        super().__init__(name)
        self.creature = creature
        self.params = params
        self.poses = NotePoses(creature.body.reach())
        self.memory: deque[Observation] = deque(maxlen=params.memory)
        self.unlearnt = 0
        self.heard: deque[tuple[float, Observation]] = deque()  # (arrival, note) heard since the last dance step
        self.last_heard = -math.inf
        self.population = ModelPopulation(known=params.known, evidence=params.context, max_models=params.max_models,
                                          max_states=params.max_states, forget=params.forget,
                                          on_event=lambda kind, **f: creature.world.emit(kind, creature=creature.name,
                                                                                        **f))
        self.dance = Dance()
        self.dancing = False  # the dance action is running (it consumes ``heard``)
        self.continued = 0  # notes played since the music stopped
        # Expects a perfect match (0 nats), give or take one, until the music says otherwise.
        self.expected_match = GaussianValue(0.0, spread=1.0, clock=creature.world.clock)
        self.surprise = 0.0
        self._new_notes = 0
        self._next_analysis = float(creature.rng.uniform(0.0, params.analysis_every))  # random phase
        self._last_tick = -math.inf
        creature.on_hear(self.hear)
        creature.each_tick(self.tick)
        creature.reporting(self.report)
        creature.keep("percepts", name, self.state, self.restore)

    def evaluate(self, t: float) -> float:
        return 0.0 if self.population.best is None else math.exp(self.population.best_score)

    # -- hearing ------------------------------------------------------------------------
    def hear(self, note: NoteEvent, source: str) -> None:
        observation = Observation(self.poses.node(note.pitch), float(note.time), note)
        self.memory.append(observation)
        self.heard.append((self.creature.now(), observation))
        self.unlearnt += 1
        self._new_notes += 1
        self.continued = 0
        self.last_heard = max(self.last_heard, float(note.time))

    def lull(self, t: float, patience: float) -> float:
        """1 once the music has been quiet for ``patience`` expected gaps (after some music)."""
        if not self.memory:
            return 0.0
        return 1.0 if t - self.last_heard > patience * self.dance.gap(DEFAULT_GAP) else 0.0

    def predicts(self) -> float:
        """1 while the played-out model predicts a next note and the creature may still play
        one (fewer than ``continuation`` since the music stopped)."""
        return 1.0 if self.continued < self.params.continuation and self.dance.predicted() is not None else 0.0

    # -- analysis (its own, slower rate) ---------------------------------------------------
    def tick(self, t: float) -> None:
        if not self.dancing:  # notes heard while not dancing are remembered, not danced
            while self.heard and self.heard[0][0] <= self._last_tick:
                self.heard.popleft()
        self._last_tick = t
        if t >= self._next_analysis:
            self._next_analysis = t + self.params.analysis_every
            self.analyse(t)

    def analyse(self, t: float) -> None:
        memory = list(self.memory)
        self._expect(memory)
        if self.unlearnt:
            split = len(memory) - min(self.unlearnt, len(memory))
            context = memory[max(split - self.params.context, 0):split]
            if self.population.learn(t, context, memory[split:]) is not None:
                self.unlearnt = 0
            else:
                self.unlearnt = min(self.unlearnt, self.params.memory - self.params.context)
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
    def step_with_music(self, t: float, maps: MusicPoseMaps | None = None) -> None:
        """Each note heard since the last step moves the dance on; the body heads for the
        pose of the note the model predicts after the last of them (or of that note itself,
        if none). One course a step: a course set for each note was replaced by the next
        within the same tick (a burst of 10,000 notes cost 10,000 A* searches)."""
        if not self.heard:
            return
        for _, observation in self.heard:
            self.dance.state = self.dance.locate(observation.node)
        self.heard.clear()
        self.dance.at = t
        self._move_on(t, observation.node, maps)

    def step_alone(self, t: float, velocity: float, maps: MusicPoseMaps | None = None) -> bool:
        """Without music: move to the predicted state when its time comes and play its note
        at ``velocity`` × the notes it was learnt from. Returns True when a note was played."""
        nxt = self.dance.predicted()
        if nxt is None or t - self.dance.at < self.dance.gap(DEFAULT_GAP):
            return False
        self.dance.state, self.dance.at = nxt, t
        state = self.dance.model.states[nxt]
        self._move_on(t, state.node, maps)
        pitch = self.poses.pitch(state.node)
        if pitch is None:
            return False
        heard = np.mean([n.velocity for n in state.notes]) if state.notes else 90
        self.continued += 1
        self.creature.play(pitch, max(1, int(heard * velocity)), min(max(state.dwell, 0.1), 2.0), at=t)
        return True

    def _move_on(self, t: float, node: int, maps: MusicPoseMaps | None) -> None:
        """Head for the pose of the state predicted after the current one (else of ``node``):
        the pitch's own pose, or with ``maps`` the pose the maps tie that note to."""
        nxt = self.dance.predicted()
        goal = self.dance.model.states[nxt].node if nxt is not None else node
        pitch = self.poses.pitch(goal)
        if maps is not None and pitch is not None:
            goal = maps.node_for(pitch, self.poses.pitch(node), self.dance.gap(DEFAULT_GAP))
        head_for(self.creature.body, t, [goal])

    # -- what it shows and keeps ---------------------------------------------------------------
    def core(self) -> list[int | None]:
        """The pitches of the best model's core cycle (what the creature thinks the music is)."""
        best = self.population.best
        return [] if best is None else [self.poses.pitch(n) for n in best.model.core_nodes()]

    def report(self, t: float) -> None:
        best = self.population.best
        self.creature.world.emit("percepts", creature=self.creature.name,
                                 sizes={"models": len(self.population.members), "memory": len(self.memory),
                                        "states of best": 0 if best is None else len(best.model.states)},
                                 best=None if best is None else best.id,
                                 match=None if best is None else self.population.best_score, core=self.core(),
                                 models=[m.id for m in self.population.members],
                                 expected_match=self.expected_match.to_float(), surprise=self.surprise,
                                 confidence=self.expected_match.confidence())

    def state(self) -> dict[str, Any]:
        return {"poses": self.poses.to_dict(), "population": self.population.to_dict(),
                "expected match": self.expected_match.to_dict()}

    def restore(self, state: dict[str, Any]) -> None:
        state = bounds.table(state, self.name)
        if "poses" in state:
            self.poses.restore(state["poses"])
        if "population" in state:
            self.population.restore(state["population"], nodes=len(self.creature.body.graph),
                                    now=self.creature.now())
            self.dance.follow(self.population.best)
        if "expected match" in state:
            self.expected_match.restore(state["expected match"])
