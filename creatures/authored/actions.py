"""The built-in action library of authored creatures (thesis: "the action-tuple": Ac is what
the creature does; "phase four – extensions" for drives perturbed by behaviour).

Each class is one ``type`` a tuple's ``action`` can name; its ``Params`` are the keys of the
action's table. ``build`` returns a library :class:`~creatures.behaviour.action_tuple.Action`.
Actions that play material remember where the phrase ends, so a Du with ``done = true`` stops
the tuple when the phrase has been played out.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, Annotated, Callable, ClassVar, Literal

import numpy as np
from pydantic import AfterValidator, BaseModel, Field, ValidationInfo, field_validator, model_validator

from creatures.authored.registry import ACTIONS, Params, Part
from creatures.behaviour.action_tuple import Action, ActionTuple
from creatures.bounds import MidiPitch
from creatures.kinds.note_world import SeekNote, Vary, Variation, Wander
from creatures.motor.programs import (MotorProgramGraph, ProgramStack, Statement, chosen_program, edge_problem,
                                      parse_programs, parse_statement, replaced_courses, start_problem)
from creatures.motor.search import NoPath
from creatures.temporal.readings import Level
from midi.notes import NoteEvent

if TYPE_CHECKING:
    from creatures.authored.creature import Authored


class ActionPart(Part):
    """An action type: ``build`` makes the Ac of one tuple. ``ends``: its Action has
    ``done(t)`` (1 once it is finished), so a Du can say ``done = true``."""

    ends: ClassVar[bool] = False

    def build(self, params: BaseModel, creature: "Authored", name: str) -> Action:  # pragma: no cover
        raise NotImplementedError


AHEAD = 0.5
"""Seconds ahead of each note that a playing action hands it to the scheduler: a live creature
whose tick comes this late still plays on time, and an interruption cuts the phrase within
this much of the moment it came."""


class Playing(Action):
    """An action that plays notes from its start: ``notes(t)`` gives them (times relative to
    the start); ``done(t)`` is 1 once the last has ended (for ``until.done``).

    The notes go to the scheduler :data:`AHEAD` of their time (or two of the creature's ticks,
    if those are longer), not all at the start: an interrupted tuple stops playing (thesis "a
    baseline action selection mechanism": the interrupted action ends), so the phrase it was
    playing is cut where the creature turned to something else, and no one (the colony, a
    peer, the room) ever hears the notes it did not play. A tuple that ends by its Du plays its
    phrase out, as it always has: its Du said the tuple was done, not that the phrase stops."""

    def __init__(self, name: str, creature: "Authored", notes: Callable[[float], list[NoteEvent]]) -> None:
        super().__init__(name)
        self.creature = creature
        self.notes = notes
        self.ends_at = -np.inf
        self._due: list[NoteEvent] = []  # not yet handed over, absolute times, latest first
        self._last = -np.inf

    def start(self, t: float, tuple_: ActionTuple) -> None:
        notes = [dataclasses.replace(n, time=t + n.time) for n in self.notes(t)]
        self.ends_at = max((n.end for n in notes), default=t)
        self._due = sorted(notes, key=lambda n: n.time, reverse=True)
        self._last = t
        self._hand_over(t, t + AHEAD)

    def update(self, t: float) -> None:
        step, self._last = t - self._last, t
        self._hand_over(t, t + max(AHEAD, 2.0 * step))

    def stop(self, t: float, *, interrupted: bool) -> None:
        if interrupted:
            self._due.clear()
        else:
            self._hand_over(t, np.inf)

    def _hand_over(self, now: float, until: float) -> None:
        """Hand over the notes due by ``until``, except those that would have ended by
        ``now``: across a clock gap (a night's closing, a pause, a suspended machine) the
        rest of a phrase is not played in a burst on waking, as nothing else is."""
        while self._due and self._due[-1].time <= until:
            note = self._due.pop()
            if note.end > now:
                self.creature.play(note.pitch, note.velocity, note.duration, at=note.time)

    def done(self, t: float) -> float:
        return 1.0 if t >= self.ends_at else 0.0


def _relative(notes: list[NoteEvent], transpose: int = 0) -> list[NoteEvent]:
    """Heard notes moved to start at 0 (their rhythm kept), transposed and kept in MIDI range."""
    if not notes:
        return []
    # In time order: the ear keeps notes in the order they reached it, and in a room a nearer
    # player's later note arrives before a farther one's (or a saved ear was edited).
    notes = sorted(notes, key=lambda n: n.time)
    t0 = notes[0].time
    return [NoteEvent(n.time - t0, min(max(n.pitch + transpose, 0), 127), n.velocity, 0, n.duration) for n in notes]


# -- playing --------------------------------------------------------------------------------
class _NoteParams(Params):
    pitch: int = Field(ge=0, le=127, description="MIDI pitch")
    velocity: int = Field(90, ge=1, le=127, description="MIDI velocity")
    duration: float = Field(0.5, gt=0, le=60, description="seconds")


@ACTIONS.register
class PlayNote(ActionPart):
    """Play one note."""

    ends = True
    name = "play_note"
    thesis = "the action-tuple"
    Params = _NoteParams

    def build(self, params, creature, name):
        note = NoteEvent(0.0, params.pitch, params.velocity, 0, params.duration)
        return Playing(name, creature, lambda t: [note])


class _PhraseParams(Params):
    pitches: list[MidiPitch] = Field(min_length=1, description="MIDI pitches in order")
    durations: list[float] | float = Field(0.5, description="seconds per note (one for all, or one each)")
    velocity: int = Field(90, ge=1, le=127, description="MIDI velocity")
    transpose: int = Field(0, ge=-48, le=48, description="semitones (a crowd's `vary` gives each its own key)")
    beats: list[float] | None = Field(None, max_length=4096,
                                      description="the rhythm in beats of the colony's heard pulse instead of "
                                                  "seconds, one per pitch: the phrase starts on the colony's next "
                                                  "beat and keeps its tempo (thesis 'temporal models': a coherent "
                                                  "pulse across action-tuples)")
    level: Level | None = Field(None, description="with beats: each beat is a step of this level of the heard "
                                                  "metre (beat, division, bar) as the colony hears it filled: a "
                                                  "run written in divisions is played straight while the visitor "
                                                  "plays straight and long-short once the visitor swings (thesis "
                                                  "'exotic duration models': a level of a duration percept tree)")

    @model_validator(mode="after")
    def _lengths(self):
        durations = self.durations if isinstance(self.durations, list) else [self.durations] * len(self.pitches)
        if len(durations) != len(self.pitches) or any(not d > 0 for d in durations):
            raise ValueError("durations must be positive seconds, one for all notes or one per pitch")
        if self.beats is not None and (len(self.beats) != len(self.pitches)
                                       or any(not 0 < b <= 64 for b in self.beats)):
            raise ValueError("beats must be one per pitch, each above 0 and at most 64")
        if self.level is not None and self.beats is None:
            raise ValueError("level counts the beats in steps of the heard metre: give beats too")
        return self


@ACTIONS.register
class PlayPhrase(ActionPart):
    """Play a written phrase, one note after another."""

    ends = True
    name = "play_phrase"
    thesis = "the action-tuple"
    Params = _PhraseParams

    def build(self, params, creature, name):
        pitches = [min(max(p + params.transpose, 0), 127) for p in params.pitches]
        if params.beats is not None:
            return Playing(name, creature, lambda t: _on_the_beat(creature, pitches, params.beats,
                                                                  params.velocity, t, params.level))
        durations = params.durations if isinstance(params.durations, list) else [params.durations] * len(params.pitches)
        onsets = np.concatenate(([0.0], np.cumsum(durations)[:-1]))
        written = [NoteEvent(float(o), p, params.velocity, 0, 0.9 * d) for o, p, d in zip(onsets, pitches, durations)]

        return Playing(name, creature, lambda t: written)


def _on_the_beat(creature: "Authored", pitches: list[int], beats: list[float], velocity: int,
                 t: float, level: Level | None = None) -> list[NoteEvent]:
    """``pitches`` in the rhythm of ``beats`` at the colony's heard pulse (its best reading),
    from the colony's next beat after ``t``: every creature's phrase shares one grid, so what
    the colony plays together stays on the ratio lattice of what it heard. With ``level``
    each beat is one step of that level as the colony hears it filled (:meth:`HeardPulse.step`)."""
    pulse = creature.world.pulse
    start = max(pulse.next_beat(t) - t, 0.0)  # rounding may put the beat a hair before t
    if level is None:
        lengths = np.array(beats) * pulse.model.pulse
    else:
        lengths = np.array([b * pulse.step(level, creature.rng) for b in beats])
    onsets = start + np.concatenate(([0.0], np.cumsum(lengths)[:-1]))
    return [NoteEvent(float(o), p, velocity, 0, 0.9 * d) for o, p, d in zip(onsets, pitches, lengths)]


class _HeardParams(Params):
    count: int = Field(4, ge=1, le=64, description="how many of the last heard notes")
    transpose: int = Field(0, ge=-48, le=48, description="semitones")


@ACTIONS.register
class PlayHeard(ActionPart):
    """Play back the last ``count`` notes heard, in their own rhythm (heard material)."""

    ends = True
    name = "play_heard"
    thesis = "the action-tuple"
    Params = _HeardParams

    def build(self, params, creature, name):
        return Playing(name, creature, lambda t: _relative(creature.ear.last(params.count), params.transpose))


class _EchoParams(Params):
    count: int = Field(4, ge=1, le=64, description="how many of the last heard notes")
    mutation: float = Field(0.2, ge=0, le=1, description="chance each note moves by one of 'steps'")
    steps: list[int] = Field([-12, -7, -5, 5, 7, 12], min_length=1, description="semitone moves a note may make")
    jitter: float = Field(0.0, ge=0, le=1, description="seconds of timing variation per note (uniform ±)")
    velocity: int | None = Field(None, ge=1, le=127, description="sing at this velocity; none = as heard "
                                                                "(in a [room], as softly as it arrived)")


@ACTIONS.register
class Echo(ActionPart):
    """Echo the last heard notes with variation: some move by fourths, fifths or octaves
    (circle-of-fifths neighbours, as exchange copies), onsets may drift."""

    ends = True
    name = "echo"
    thesis = "the action-tuple"
    Params = _EchoParams

    def build(self, params, creature, name):
        steps = np.array(params.steps)

        def varied(t: float) -> list[NoteEvent]:
            out = []
            for n in _relative(creature.ear.last(params.count)):
                pitch = n.pitch
                if creature.rng.random() < params.mutation:
                    pitch = min(max(pitch + int(creature.rng.choice(steps)), 0), 127)
                shift = float(creature.rng.uniform(-params.jitter, params.jitter)) if params.jitter else 0.0
                velocity = n.velocity if params.velocity is None else params.velocity
                out.append(NoteEvent(max(0.0, n.time + shift), pitch, velocity, 0, n.duration))
            return out

        return Playing(name, creature, varied)


class _LearnedParams(Params):
    phrase: int | Literal["latest", "longest", "best"] = Field(
        "latest", description="which remembered phrase: its number (1 = first heard), 'latest', 'longest', or "
                              "'best': the one whose own tuple (learning.phrases) is worth the most, so credit "
                              "chooses (the latest until there is one)")
    transpose: int = Field(0, ge=-48, le=48, description="semitones")


@ACTIONS.register
class PlayLearned(ActionPart):
    """Sing back a phrase the creature heard and remembered (the ear's phrase memory); with
    ``learning.phrases`` each new phrase gets a tuple of its own, so credit can favour one,
    and ``phrase = "best"`` plays the favourite: the best learned sequence."""

    ends = True
    name = "play_learned"
    thesis = "percept trees"
    Params = _LearnedParams

    def build(self, params, creature, name):
        def learned(t: float) -> list[NoteEvent]:
            ear = creature.ear
            number = creature.best_phrase() if params.phrase == "best" else params.phrase
            if isinstance(number, int):
                phrase = ear.phrase(number)
            elif number == "longest":
                phrase = max(ear.phrases, key=len, default=None)
            else:
                phrase = ear.phrases[-1] if ear.phrases else None
            return _relative(phrase or [], params.transpose)

        return Playing(name, creature, learned)


# -- doing nothing, and acting on the creature itself ----------------------------------------
@ACTIONS.register
class Rest(ActionPart):
    """Do nothing for the Du (a rest, or attending)."""

    name = "rest"
    thesis = "a baseline action selection mechanism"

    def build(self, params, creature, name):
        return Action(name)


class _PerturbParams(Params):
    drive: str = Field(description="the drive")
    amount: float = Field(description="added to its level when the tuple starts")


@ACTIONS.register
class Perturb(ActionPart):
    """Change a drive when the tuple starts (eating takes hunger down)."""

    name = "perturb"
    thesis = "soft state"
    Params = _PerturbParams
    refs = {"drive": "drives"}

    def build(self, params, creature, name):
        class PerturbAction(Action):
            def start(self, t, tuple_):
                creature.motivation.perturb(t, params.drive, params.amount)

        return PerturbAction(name)


# -- the body (thesis: "towards a complete motor system") -----------------------------------
class MotorPart(ActionPart):
    """An action that moves the creature's body (``body = true``) on the shared motor graph;
    ``labels`` names the motor-graph labels it needs, checked against the body at load."""

    needs: ClassVar[str] = "body"

    @classmethod
    def labels(cls, params: BaseModel) -> list[str]:
        return []

    @classmethod
    def joints(cls, params: BaseModel) -> list[str]:
        """The skeleton joints it names (checked against the body at load)."""
        return []


class _GoToParams(Params):
    labels: list[str] = Field(min_length=1, description="motor-graph labels; the nearest node with any of them")
    furthest: bool = Field(False, description="the furthest of the labels instead (getToFurthest)")


@ACTIONS.register
class GoTo(MotorPart):
    """Go to the nearest pose with a label, by A* on the motor graph (done on arrival)."""

    ends = True
    name = "go_to"
    thesis = "towards a complete motor system: complex labels"
    Params = _GoToParams

    @classmethod
    def labels(cls, params):
        return list(params.labels)

    def build(self, params, creature, name):
        from creatures.kinds.moves import head_for

        class GoToAction(Action):
            def start(self, t, tuple_):
                motor = creature.body.motor
                try:
                    head_for(creature.body, t, motor.course(t, params.labels, furthest=params.furthest))
                except NoPath:
                    pass

            def done(self, t):
                return 1.0 if creature.body.motor.arrived(t) else 0.0

        return GoToAction(name)


class _ProgramParams(Params):
    text: str = Field(description="motor programs in the thesis's language ('name: getTo {...}; wait; cycle'); "
                                  "each program begins a line of its own, so a text of several is a TOML "
                                  "multi-line string ('''...''')")
    program: str | None = Field(None, description="which program of the text runs (default: the first)")

    @model_validator(mode="after")
    def _parses(self):
        programs, _ = chosen_program(self.text, self.program, source="motor program")
        problem = replaced_courses(programs)
        if problem:
            raise ValueError(problem)
        return self


class _ProgramPart(MotorPart):
    """A motor program's part: the labels and node indices its statements name, checked at
    load against the body (a node past the graph's end was an IndexError on the creature's
    thread when its statement ran)."""

    @classmethod
    def labels(cls, params):
        return sorted(x for x in cls._targets(params) if isinstance(x, str))

    @classmethod
    def nodes(cls, params):
        return sorted(x for x in cls._targets(params) if isinstance(x, int))

    @staticmethod
    def _targets(params) -> set:  # pragma: no cover - every subclass says
        raise NotImplementedError


@ACTIONS.register
class RunProgram(_ProgramPart):
    """Run a motor program written as text (getTo / getToClosest / getToFurthest /
    forcedGetTo / wait / cycle; a target may name another program of the text). Done when the
    program ends; stopping the tuple asks it to exit (its forcedGetTo statements still run).
    A getTo sets a course and does not wait: one followed at once by another course is refused
    (the body would never head for the first); put ``wait`` between them."""

    ends = True
    name = "motor_program"
    thesis = "motor program graphs"
    Params = _ProgramParams

    @staticmethod
    def _targets(params) -> set:
        programs = parse_programs(params.text)
        return {x for p in programs.values() for s in p.statements for x in s.targets if x not in programs}

    def build(self, params, creature, name):
        programs = parse_programs(params.text, source=f"tuple {name!r}")
        return ProgramAction(name, creature, programs[params.program or next(iter(programs))], programs)


class ProgramAction(Action):
    """Runs a motor program (text or graph) under a :class:`ProgramStack` while the tuple is
    active; stopping the tuple asks the program to exit (its forced statements still run) and
    gives the body up. A program another action took the body from waits for it, said in the
    events log (``motor paused``, ``motor resumed``)."""

    def __init__(self, name: str, creature: "Authored", program, library: dict | None = None) -> None:
        super().__init__(name)
        self.creature = creature
        self.program = program
        self.library = library or {}
        self.stack: ProgramStack | None = None
        self._paused = False  # the program waiting for the body another action took (logged)

    def start(self, t: float, tuple_: ActionTuple) -> None:
        self.stack = ProgramStack(self.creature.body.motor, self.program, library=self.library)
        self.stack.start(t)
        self._paused = False

    def update(self, t: float) -> None:
        self.stack.tick(t)
        if self.stack.paused != self._paused:  # in the log: two actions at once on one body
            self._paused = self.stack.paused
            c = self.creature
            c.world.emit("motor paused" if self._paused else "motor resumed", creature=c.name, action=self.name)

    def stop(self, t: float, *, interrupted: bool) -> None:
        self.stack.stop(t, interrupted=interrupted)

    def done(self, t: float) -> float:
        return 1.0 if self.stack is None or self.stack.done else 0.0


def _statement(text: str) -> Statement:
    """One statement of the motor-program language (``getTo "reach"``, ``wait`` …)."""
    if ";" in text:
        raise ValueError("a vertex holds one statement: give each of these a vertex of its own, joined by edges")
    return parse_statement(text)


def _vertex(text: str) -> str:
    """A vertex's statement, checked where the config writes it (``vertices.w``)."""
    _statement(text)
    return text


class _GraphParams(Params):
    vertices: dict[str, Annotated[str, AfterValidator(_vertex)]] = Field(
        description="vertex name → one statement; flow starts at 'start', an exit heads for the nearest vertex "
                    "named 'exit…'")
    edges: dict[str, list[str]] = Field(default_factory=dict, description="vertex → the vertices that may follow")

    @field_validator("vertices")
    @classmethod
    def _starts(cls, vertices: dict[str, str]) -> dict[str, str]:
        problem = start_problem(vertices)
        if problem:
            raise ValueError(problem)
        return vertices

    @field_validator("edges")
    @classmethod
    def _joins(cls, edges: dict[str, list[str]], info: ValidationInfo) -> dict[str, list[str]]:
        """The edges, checked against the vertices (when those were valid: else their error is the one said)."""
        vertices = info.data.get("vertices")
        problem = vertices is not None and edge_problem({k: _statement(v) for k, v in vertices.items()}, edges)
        if problem:
            raise ValueError(problem)
        return edges


@ACTIONS.register
class RunGraph(_ProgramPart):
    """Run a motor program graph: statements as vertices, at each branch the successor whose
    target is nearest on the motor graph; stopping the tuple heads for the nearest exit. An
    edge from one getTo vertex straight to another is refused (the second course would replace
    the first at once): put a wait vertex between them."""

    ends = True
    name = "motor_graph"
    thesis = "motor program graphs"
    Params = _GraphParams

    @staticmethod
    def _targets(params) -> set:
        return {x for v in params.vertices.values() for x in _statement(v).targets}

    def build(self, params, creature, name):
        graph = MotorProgramGraph(name, {k: _statement(v) for k, v in params.vertices.items()}, params.edges)
        return ProgramAction(name, creature, graph)


class _ReachParams(Params):
    point: tuple[float, float, float] = Field(description="where the effector (right hand) should go, metres")
    tolerance: float = Field(0.1, gt=0, description="how close counts; none close: the nearest pose")


@ACTIONS.register
class ReachPoint(MotorPart):
    """Get the hand to a point in space: A* to a pose that puts the effector there (done on arrival)."""

    ends = True
    name = "reach_point"
    thesis = "towards a complete motor system"
    Params = _ReachParams

    def build(self, params, creature, name):
        from creatures.kinds.moves import head_for

        class Reach(Action):
            def start(self, t, tuple_):
                body = creature.body
                try:
                    head_for(body, t, body.finder.to_effector(body.motor.position(t), body.effector,
                                                              np.asarray(params.point), tolerance=params.tolerance))
                except NoPath:
                    pass

            def done(self, t):
                return 1.0 if creature.body.motor.arrived(t) else 0.0

        return Reach(name)


@ACTIONS.register
class RestPose(MotorPart):
    """Return to the nearest low-energy pose and stay there (thesis "enforcing physical constraints")."""

    name = "rest_pose"
    thesis = "towards a complete motor system"

    def build(self, params, creature, name):
        from creatures.kinds.moves import Rest as RestMove

        rest = RestMove(creature.body)
        rest.name = name
        return rest


# -- complex shaping (thesis "learning to chase your tail") ---------------------------------
class _StickParams(Params):
    period: float = Field(6.0, gt=0, le=3600, description="seconds the stick takes round its circle")
    laps: float = Field(1.0, gt=0, le=1000, description="laps followed before the tuple is done")
    size: float = Field(1.0, gt=0, le=10, description="radius as a multiple of the narrower spread of the "
                                                       "effector's reach (the circle lies in the plane of its two "
                                                       "widest directions, about its middle)")


@ACTIONS.register
class FollowStickPart(MotorPart):
    """The guide of complex shaping, "follow stick with your nose": a training stick circles
    through the effector's reach and the body keeps heading, by A*, for the pose that puts the
    effector nearest it (done after ``laps``)."""

    ends = True
    name = "follow_stick"
    thesis = "complex shaping"
    Params = _StickParams

    def build(self, params, creature, name):
        from creatures.kinds.shaping import Circle, FollowStick

        return FollowStick(name, creature.body, Circle.in_reach(creature.body.reach(), params.size),
                           period=params.period, laps=params.laps)


class _ShapeParams(Params):
    guide: str = Field(description="the guide tuple (e.g. follow_stick): this tuple gets proximity 1 to it, "
                                   "takes its credit and learns the body's memory of its rewarded runs")
    dispatch_after: int = Field(8, ge=1, le=10_000, description="rewarded runs learnt before the model's core is "
                                                                "dispatched into the motor graph")
    gesture: str | None = Field(None, pattern=r"^[A-Za-z_][\w -]*$", max_length=64,
                                description="name of the new material and of the tuple left behind that "
                                            "performs it, not a take of the body nor another tuple's gesture "
                                            "(default: '<tuple> gesture')")


@ACTIONS.register
class ShapeGesturePart(MotorPart):
    """The Ac percept of complex shaping: a gesture model of the motor-graph nodes the body
    passed in rewarded runs of ``guide`` (and of itself), performed as a motor program; after
    ``dispatch_after`` lessons its core becomes new material in the body's graph and a new
    tuple, ``gesture``, performs it without the guide in this tuple's place."""

    ends = True
    name = "shape_gesture"
    thesis = "learning to chase your tail – part 2"
    Params = _ShapeParams
    refs = {"guide": "tuples"}

    def build(self, params, creature, name):
        from creatures.kinds.shaping import GestureShaping

        gesture = params.gesture or f"{name} gesture"
        return GestureShaping(name, creature.body, creature.body_memory(), dispatch_after=params.dispatch_after,
                              gesture=gesture, guide=params.guide, on_dispatch=lambda g: creature.leave_behind(name, g))


# -- notes in space (thesis: "musical worlds") ----------------------------------------------
@ACTIONS.register
class WanderSpace(MotorPart):
    """Wander to a random pose of the motor graph, striking the notes in space the hand passes
    (exchange's slow progression; needs ``[creature.space]``)."""

    name = "wander"
    thesis = "musical worlds"
    needs = "space"

    def build(self, params, creature, name):
        return Wander(creature.notes, name)


@ACTIONS.register
class SeekNoteSpace(MotorPart):
    """Go to the nearest note in space not struck lately, by one A* search over the poses that
    put the hand on any of them, and strike it (done when struck; needs ``[creature.space]``)."""

    name = "seek_note"
    thesis = "musical worlds"
    needs = "space"
    ends = True

    def build(self, params, creature, name):
        return SeekNote(creature.notes, name)


class _VaryParams(Params):
    transform: Variation = Field(description="'retrograde' (the passage backwards) or 'swap' (two of its "
                                             "sub-segments in the other order)")
    passage: Literal["latest", "longest"] = Field("latest", description="which heard passage of those long enough "
                                                                        "to vary (space.passage_gap splits them)")
    segment: int = Field(3, ge=1, le=1024, description="fewest notes of a swapped sub-segment (a swap needs a "
                                                       "passage of twice as many)")


@ACTIONS.register
class VaryPassage(MotorPart):
    """Play a heard passage varied: the hand strikes its note objects in retrograde, or with
    two sub-segments swapped at a random cut, walking from each to the next by A* (a pattern
    generator as a motor program; done when the last is struck; needs ``[creature.space]``)."""

    name = "vary"
    thesis = "exchange (installation)"
    needs = "space"
    ends = True
    Params = _VaryParams

    @staticmethod
    def passage_notes(params) -> tuple[str, int]:
        """The key and the fewest heard notes a passage needs to be varied (:class:`Vary`)."""
        return ("transform", 2) if params.transform == "retrograde" else ("segment", 2 * params.segment)

    def build(self, params, creature, name):
        return Vary(creature.notes, name, transform=params.transform, passage=params.passage, segment=params.segment)


@ACTIONS.register
class StrikeNearby(MotorPart):
    """Strike the notes in space the hand passes, wherever another group moves it (one note
    at a time, within the space's ``strike_interval`` and ``refractory``)."""

    name = "strike"
    thesis = "musical worlds"
    needs = "space"

    def build(self, params, creature, name):
        class Strike(Action):
            def update(self, t):
                creature.notes.strike_nearby(t)

        return Strike(name)


# -- sounds (thesis: "soundcreatures (installation)", "aural Ac percept trees") ---------------
class _SingParams(Params):
    percept: str = Field(description="an 'utterance' percept (or the tree's root, whose learnt classes become "
                                     "new tuples singing each)")


@ACTIONS.register
class Sing(ActionPart):
    """Sing from an aural percept: an exemplar drawn from the utterance class, sung through
    the mouth (and the body, which moves across the graph while singing). Tuples singing one
    class share one action, so credit flows between them."""

    name = "sing"
    thesis = "aural Ac percept trees"
    Params = _SingParams
    refs = {"percept": "utterances"}
    needs = "hearing"

    def build(self, params, creature, name):
        return creature.aural.sing_from(creature.aural.percept(params.percept))


class _AttendParams(Params):
    percept: str = Field(description="the 'utterance' percept whose sound is attended")
    drive: str | None = Field(None, description="a drive attending relieves (the motivation to hear)")
    relief: float = Field(0.5, ge=0, le=1e3, description="taken off the drive each time")


@ACTIONS.register
class Attend(ActionPart):
    """Turn to a heard sound: the consummatory act of the motivation to hear. The sound
    attended joins the tree's exemplars now (by the time this activation's credit is assigned
    the tree may hear a newer one), and ``drive`` falls by ``relief``. With a non-plastic
    value it is the primary reinforcer: the perception of sound rewards what came before.
    The sound is then attended: an ``unattended`` percept, its trigger, falls while the sound
    is still heard, so what follows may answer it."""

    name = "attend"
    thesis = "soundcreatures (installation)"
    Params = _AttendParams
    refs = {"percept": "utterances", "drive": "drives"}
    needs = "hearing"

    def build(self, params, creature, name):
        tree = creature.aural.percept(params.percept)

        class AttendAction(Action):
            def start(self, t, tuple_):
                if params.drive is not None:
                    creature.motivation.perturb(t, params.drive, -params.relief)
                tree.update(t, tuple_.value.to_float())
                heard = tree.heard(t)
                creature.aural.attended = heard  # taken: an 'unattended' percept of it falls
                creature.world.emit("attend", creature=creature.name, percept=tuple_.trigger.name,
                                    heard_at=None if heard is None else heard.time)

        return AttendAction(name)


# -- dancing what a model population hears (thesis: "listen (installation)") ---------------
class _DanceParams(Params):
    of: str = Field(description="a 'population' percept: its best model is danced")
    poses: str | None = Field(None, description="a 'maps' percept: head for the pose its pose map holds where its "
                                                "music map places the predicted note (thesis: listen, extensions); "
                                                "none: each pitch's own pose")


@ACTIONS.register
class DanceAction(MotorPart):
    """Dance to the music: every note heard while it runs sends the body, by A*, towards the
    pose of the note the best model predicts next (notes are poses, one node per pitch).
    Reactive in when it moves, predictive in where."""

    name = "dance"
    thesis = "listen (installation)"
    Params = _DanceParams
    refs = {"of": "populations", "poses": "maps"}

    def build(self, params, creature, name):
        listening = creature.percept(params.of)  # a 'population' percept (checked at load)
        maps = creature.percept(params.poses) if params.poses else None  # a 'maps' percept (checked at load)

        class Dancing(Action):
            def start(self, t, tuple_):
                listening.dancing = True

            def update(self, t):
                listening.step_with_music(t, maps)

            def stop(self, t, *, interrupted):
                listening.dancing = False

        return Dancing(name)


class _AnticipateParams(Params):
    of: str = Field(description="a 'population' percept: its best model is carried on")
    poses: str | None = Field(None, description="a 'maps' percept: its poses, as dance's")
    velocity: float = Field(0.4, gt=0, le=1, description="velocity of a predicted note, relative to the notes it "
                                                         "was learnt from")


@ACTIONS.register
class Anticipate(MotorPart):
    """The music stopped: carry on through the best model at the timing stored in its
    states, moving to each predicted pose and playing its note quietly (at most the
    population's ``continuation`` notes; the ``predicts`` percept says when they are spent)."""

    name = "anticipate"
    thesis = "listen (installation)"
    Params = _AnticipateParams
    refs = {"of": "populations", "poses": "maps"}

    def build(self, params, creature, name):
        listening = creature.percept(params.of)  # a 'population' percept (checked at load)
        maps = creature.percept(params.poses) if params.poses else None

        class Anticipating(Action):
            def start(self, t, tuple_):
                listening.dance.at = t

            def update(self, t):
                listening.step_alone(t, params.velocity, maps)

        return Anticipating(name)


# -- singing a precomposed song (thesis: "sand:stone (installation)") ---------------------
SHORTEST_BEATS = 1 / 16
"""Shortest note of a song, in beats: at the fastest internal time (tempo 400, pulse 2) 213
notes a second. A song is sung as fast as its onsets come, so with no bound a millionth of a
beat sent 133,000 notes a tick and a run never ended."""


class _SongParams(Params):
    phrases: list[list[tuple[int, float]]] = Field(min_length=1, max_length=1024,
                                                   description="precomposed segments, sung in order: each a list of "
                                                               "[pitch, beats] notes (beats from this note's onset "
                                                               "to the next, 1/16 to 64)")
    tempo: float = Field(96.0, ge=10, le=400, description="beats per minute of internal time at pulse 1 (at 10, the "
                                                          "longest note lasts under 13 minutes)")
    phrase_rest: float = Field(1.0, ge=0, le=64, description="beats of silence between the end of a segment and the "
                                                            "next")
    velocity: int = Field(96, ge=1, le=127, description="loudness of a fresh (unbored) creature")
    timbre_depth: float = Field(0.5, ge=0, le=1, description="how much full boredom softens (velocity) and detaches "
                                                             "(note length) the singing")
    breath: str | None = Field(None, description="a drive: no note is begun that its level, drawn at its current "
                                                 "input, cannot hold to the end; then the action is done")
    boredom: str | None = Field(None, description="a drive whose level (to 1) dulls the timbre")
    pulse: str | None = Field(None, description="a drive: internal time runs at tempo × its level (0.5–2)")

    @field_validator("phrases")
    @classmethod
    def _notes(cls, phrases: list[list[tuple[int, float]]]) -> list[list[tuple[int, float]]]:
        for p, phrase in enumerate(phrases):
            if not phrase:
                raise ValueError(f"phrase {p} is empty")
            for n, (pitch, beats) in enumerate(phrase):
                if not 0 <= pitch <= 127 or not SHORTEST_BEATS <= beats <= 64:
                    raise ValueError(f"phrase {p} note {n}: need pitch 0..127 and 1/16 <= beats <= 64, "
                                     f"got [{pitch}, {beats}]")
        return phrases


@ACTIONS.register
class SingPhrases(ActionPart):
    """Sing precomposed phrases, resuming where the song stopped: notes at the creature's
    internal time (tempo × the ``pulse`` drive), softened and detached by ``boredom``, and
    none begun that the ``breath`` drive cannot hold (done when out of breath)."""

    ends = True
    name = "sing_phrases"
    thesis = "sand:stone (installation)"
    Params = _SongParams
    refs = {"breath": "drives", "boredom": "drives", "pulse": "drives"}

    def build(self, params, creature, name):
        from creatures.authored.song import Singing

        return Singing(name, creature, params)
# The skills layered over the course (looking, sweeps, adverbs) register from their own module.
from creatures.authored import skills as _skills  # noqa: E402, F401
