"""The built-in percept library of authored creatures (thesis: "percepts", "percept trees",
"state objects and decaying memory traces"; "soft state" for drives as percepts).

Each class is one ``type`` a ``[creature.percepts.NAME]`` table can name; its ``Params`` are
that table's keys. ``build`` returns a library :class:`~creatures.behaviour.percept.Percept`
(models come from :mod:`creatures.behaviour.models`, not re-implemented here).
"""

from __future__ import annotations

import math
from collections import deque
from typing import TYPE_CHECKING, Any, ClassVar, Literal

from pydantic import BaseModel, Field, ValidationInfo, field_validator, model_validator

from creatures.authored.ear import DENSITY_WINDOW

from creatures import bounds
from creatures.bounds import LONGEST_SECONDS, MidiPitch, Seconds
from creatures.kinds.model_population import MOST_MODELS, MOST_STATES
from creatures.authored.registry import PERCEPTS, Params, Part
from creatures.authored.scripted import Scripted
from creatures.kinds.hearing_parts import SeedModel
from creatures.behaviour.models.activation import ActivationModel
from creatures.behaviour.models.fuzzy import AndPercept, NotPercept, OrPercept
from creatures.behaviour.models.gaussian import GaussianModel, GaussianPercept
from creatures.behaviour.motivation import Motivation
from creatures.behaviour.perception import PerceivingPercept
from creatures.behaviour.percept import FunctionPercept, Percept
from creatures.temporal.durations import SimpleDurationModel
from creatures.temporal.readings import Level
from creatures.temporal.tree import on_grid
from midi.fifths import STEPS

if TYPE_CHECKING:
    from creatures.authored.creature import Authored


class PerceptPart(Part):
    """A percept type: ``build`` makes the percept for one creature. ``joins_tree``: it is
    placed under its ``parent`` in the creature's percept tree (false for the root of a tree
    of its own, whose saliency depends on being a root)."""

    joins_tree: ClassVar[bool] = True
    pure: ClassVar[bool] = False
    """Its saliency reads only the creature's own state (its drives, ear, tuples) or what no
    creature's tick changes (the room's places, sensors, the colony's pulse): a crowd of
    creatures with only such percepts has its triggers read together before each finishes
    its tick (Authored.tick_many), which a percept reading another creature (``sensed``) or
    what the colony learns as it goes would see out of turn."""

    def build(self, params: BaseModel, creature: "Authored", name: str) -> Percept:  # pragma: no cover
        raise NotImplementedError


def ramp(x: float, low: float, high: float) -> float:
    """A fuzzy membership: 0 at ``low``, 1 at ``high``, linear between (either order)."""
    if high == low:
        return 1.0 if x >= high else 0.0
    return min(max((x - low) / (high - low), 0.0), 1.0)


# -- what is heard --------------------------------------------------------------------------
class _HeardParams(Params):
    window: float = Field(1.0, gt=0, description="seconds a heard onset stays salient")
    outside: bool = Field(False, description="count only notes from outside the colony (a visitor's: what the "
                                             "pulse hears), not the creatures'")


@PERCEPTS.register
class Heard(PerceptPart):
    """A note was heard within the last ``window`` seconds (1), else 0."""

    pure = True
    name = "heard"
    thesis = "percepts"
    Params = _HeardParams

    def build(self, params, creature, name):
        if not params.outside:
            return FunctionPercept(name, lambda t: 1.0 if creature.ear.since_heard(t) <= params.window else 0.0)
        heard_at = [-math.inf]

        def hear(note, source) -> None:
            if creature.world.outside(source):
                heard_at[0] = creature.now()

        creature.on_hear(hear)
        return FunctionPercept(name, lambda t: 1.0 if t - heard_at[0] <= params.window else 0.0)


class _OnsetParams(_HeardParams):
    window: float = Field(0.1, gt=0, description="seconds an onset counts as 'now'")


@PERCEPTS.register
class Onset(Heard):
    """A note began just now (within ``window``, a tick or so): the moment of an onset."""

    name = "onset"
    Params = _OnsetParams


class _SilenceParams(Params):
    after: float = Field(2.0, ge=0, description="seconds of silence before the percept starts to rise")
    ramp: float = Field(4.0, ge=0, description="seconds more until it is fully salient")


@PERCEPTS.register
class Silence(PerceptPart):
    """How long nothing has been heard, as a fuzzy ramp from ``after`` to ``after + ramp`` seconds."""

    pure = True
    name = "silence"
    thesis = "percepts"
    Params = _SilenceParams

    def build(self, params, creature, name):
        return FunctionPercept(name, lambda t: ramp(creature.ear.since_heard(t), params.after,
                                                    params.after + params.ramp))


class _FeatureParams(Params):
    near: float | None = Field(None, ge=-bounds.LARGEST_RATE, le=bounds.LARGEST_RATE,
                               description="Gaussian model: the typical value (with 'spread')")
    spread: float = Field(2.0, gt=0, le=bounds.LARGEST_RATE, description="Gaussian model: its standard deviation")
    low: float | None = Field(None, ge=-bounds.LARGEST_RATE, le=bounds.LARGEST_RATE,
                              description="fuzzy ramp: saliency 0 here …")
    high: float | None = Field(None, ge=-bounds.LARGEST_RATE, le=bounds.LARGEST_RATE,
                               description="… and 1 here (either order)")
    lookback: float = Field(0.0, ge=0, le=LONGEST_SECONDS, description="Gaussian model: learn from the most salient datum this "
                                                   "many seconds before a valued action")

    @model_validator(mode="after")
    def _one_shape(self):
        if (self.near is None) == (self.low is None or self.high is None):
            raise ValueError("give either 'near' (a Gaussian model) or both 'low' and 'high' (a fuzzy ramp)")
        return self


class _Feature(PerceptPart):
    thesis = "percept trees"
    pure = True
    Params = _FeatureParams
    flow: ClassVar[str]

    def build(self, params, creature, name):
        state = creature.ear.flow(self.flow)
        if params.near is not None:
            # A model, not a threshold: learning (fission) may split it into children.
            return GaussianPercept(name, state, GaussianModel(params.near, params.spread), lookback=params.lookback)

        def fuzzy(t: float) -> float:
            datum = state.datum_at(t)
            return 0.0 if datum is None else ramp(float(datum), params.low, params.high)

        return FunctionPercept(name, fuzzy)


def _feature(flow: str, doc: str) -> type[_Feature]:
    cls = type(f"{flow.title()}Percept", (_Feature,), {"name": flow, "flow": flow, "__doc__": doc})
    return PERCEPTS.register(cls)


_feature("pitch", "The pitch of the last heard note (MIDI number), as a Gaussian model or a fuzzy ramp.")
_feature("velocity", "The velocity of the last heard note (1–127), as a Gaussian model or a fuzzy ramp.")
_feature("interval", "Semitones from the previous heard note to the last, as a Gaussian model or a fuzzy ramp.")
_feature("register", "The octave of the last heard note (pitch // 12), as a Gaussian model or a fuzzy ramp.")
_feature("density", f"Notes per second heard over the last {DENSITY_WINDOW:g} s, as a Gaussian model or a ramp.")


# -- the colony's pulse ---------------------------------------------------------------------
class _PulseParams(Params):
    width: float = Field(0.1, gt=0, description="seconds either side of a predicted beat that count as on it")


@PERCEPTS.register
class OnPulse(PerceptPart):
    """On a beat of the colony's heard pulse (its low-integer-ratio model), counted from the
    last heard onset; 0 until the pulse is trusted."""

    pure = True
    name = "pulse"
    thesis = "temporal models"
    Params = _PulseParams

    def build(self, params, creature, name):
        pulse = creature.world.pulse

        def on_beat(t: float) -> float:
            if not pulse.ready:
                return 0.0
            beat = pulse.model.pulse
            phase = math.fmod(creature.ear.since_heard(t), beat)
            return 1.0 if min(phase, beat - phase) <= params.width else 0.0

        return FunctionPercept(name, on_beat)


class _InTimeParams(Params):
    level: Level = Field(
        "division", description="the level of the heard metre's pulse tree: 'beat', 'division' (halves of the beat "
                                "in a duple reading, thirds in a triple one) or 'bar'")
    sharpness: float = Field(1.0, gt=0, le=100, description="κ: a note at phase φ of the level's grid is "
                                                            "exp(κ(cos 2πφ − 1)) in time: 1 on a grid point, "
                                                            "e^(−2κ) half way between")


@PERCEPTS.register
class InTime(PerceptPart):
    """How well the last note heard from outside the colony sat on a level of the heard metre,
    counted from the note before it (the interval, on that level of the best reading's pulse
    tree): exp(κ(cos 2πφ − 1)) at its phase φ; 1 after a pause (the time starts afresh), 0
    until the pulse is trusted.
    The until-percept of a tuple that hears a note: its Du then expects the note in time, and
    a note off the metre is a surprise (thesis "perception as action": "more sophisticated
    expectations about those perceptions")."""

    name = "in_time"
    thesis = "exotic duration models"
    Params = _InTimeParams

    def build(self, params, creature, name):
        pulse = creature.world.pulse
        fit = [0.0]

        def hear(note, source) -> None:
            if not creature.world.outside(source):
                return
            phase = pulse.phase(note.time, params.level)
            if phase is None:
                fit[0] = 0.0 if not pulse.ready else 1.0
            else:
                fit[0] = on_grid(phase, params.sharpness)

        creature.on_hear(hear)
        return FunctionPercept(name, lambda t: fit[0])


# -- drives, time, sensors, the creature's own playing --------------------------------------
class _DriveParams(Params):
    drive: str = Field(description="the drive")
    scale: Literal["free", "level"] = Field("free", description="'free': how high the level is among the levels "
                                                               "it has had (a model of the drive); 'level': the "
                                                               "level itself")
    spread: float = Field(0.1, gt=0, le=bounds.LARGEST_RATE, description="free: the model's prior spread")
    low: float | None = Field(None, description="level: a fuzzy ramp of it instead, saliency 0 here …")
    high: float | None = Field(None, description="… and 1 here (either order; equal: a step)")

    @model_validator(mode="after")
    def _ramp(self):
        if (self.low is None) != (self.high is None):
            raise ValueError("give both 'low' and 'high' (a fuzzy ramp of the level), or neither")
        if self.low is not None and self.scale != "level":
            raise ValueError("'low' and 'high' ramp the level: set scale = \"level\"")
        return self


@PERCEPTS.register
class DrivePercept(PerceptPart):
    """A drive's level. Scale-free by default: a Gaussian model of the levels the drive has
    had, read as its cumulative probability, so "bored" means bored for this creature
    whatever units the author chose (a model of the drive, not a threshold)."""

    pure = True
    name = "drive"
    thesis = "soft state"
    Params = _DriveParams
    refs = {"drive": "drives"}

    def build(self, params, creature, name):
        if params.scale == "level" and params.low is not None:
            return FunctionPercept(name, lambda t: ramp(creature.level(params.drive, t), params.low, params.high))
        if params.scale == "level":
            return DriveLevel(name, creature.motivation, params.drive)
        model = GaussianModel(creature.level(params.drive, creature.now()), params.spread, size=64)
        last = [-math.inf]

        def scale_free(t: float) -> float:
            level = creature.level(params.drive, t)
            if t - last[0] >= 1.0:  # one sample a second: the model follows the drive's history
                model.update(level)
                last[0] = t
            return 0.5 * (1.0 + math.erf((level - model.mean) / (math.sqrt(2.0) * model.std)))

        return FunctionPercept(name, scale_free)


class DriveLevel(Percept):
    """A drive's level (``scale = "level"``) read from the drives themselves, as
    :meth:`Authored.level` reads it: a crowd's triggers ask it of every creature every tick."""

    def __init__(self, name: str, motivation: Motivation, drive: str) -> None:
        super().__init__(name)
        self.motivation = motivation
        self.drive = motivation.index(drive)

    def evaluate(self, t: float) -> float:
        m = self.motivation
        return float(m.levels[self.drive] if t <= m.time else m.levels_at(t)[self.drive])


class _TimerParams(Params):
    after: float = Field(gt=0, description="seconds before the timer starts to rise")
    ramp: float = Field(0.0, ge=0, description="seconds more until fully salient")
    since: str | None = Field(None, description="a tuple: count from when it last stopped (none: from the start)")


@PERCEPTS.register
class Timer(PerceptPart):
    """Time since the start, or since a tuple last stopped, as a fuzzy ramp."""

    pure = True
    name = "timer"
    thesis = "percepts"
    Params = _TimerParams
    refs = {"since": "tuples"}

    def build(self, params, creature, name):
        start = creature.now()

        def elapsed(t: float) -> float:
            origin = start
            if params.since is not None:
                stopped = creature.tuple(params.since).stopped_at
                origin = start if stopped is None else stopped
            return ramp(t - origin, params.after, params.after + params.ramp)

        return FunctionPercept(name, elapsed)


class _SensorParams(Params):
    sensor: str = Field(description="an [[input]] sensor by name")
    low: float = Field(0.0, description="saliency 0 at this sensor value …")
    high: float = Field(1.0, description="… and 1 here")


@PERCEPTS.register
class Sensor(PerceptPart):
    """A sensor of the installation's input map, by name (a StateObject in the World), as a ramp."""

    pure = True
    name = "sensor"
    thesis = "state objects and decaying memory traces"
    Params = _SensorParams

    def build(self, params, creature, name):
        state = creature.sensor(params.sensor)

        def read(t: float) -> float:
            datum = state.datum_at(t)
            return 0.0 if datum is None else ramp(float(datum), params.low, params.high)

        return FunctionPercept(name, read)


class _ScheduleParams(Params):
    times: list[float] = Field(min_length=1, description="clock times (seconds) of the events")
    width: float = Field(1.0, gt=0, description="seconds each stays salient")


@PERCEPTS.register
class Schedule(PerceptPart):
    """Scripted events at given times (a visitor's rewards, a cue): 1 for ``width`` seconds after each."""

    pure = True
    name = "schedule"
    thesis = "percepts"
    Params = _ScheduleParams

    def build(self, params, creature, name):
        times = sorted(params.times)
        return FunctionPercept(name, lambda t: 1.0 if any(0.0 <= t - x <= params.width for x in times) else 0.0)


class _PlayedParams(Params):
    pitches: list[MidiPitch] = Field(min_length=1, description="the pitches that count")
    window: float = Field(1.0, gt=0, description="seconds after the note started")


@PERCEPTS.register
class Played(PerceptPart):
    """The creature itself played one of ``pitches`` within ``window`` seconds (what it just
    did, e.g. what a scripted visitor likes to hear)."""

    pure = True
    name = "played"
    thesis = "percepts"
    Params = _PlayedParams

    def build(self, params, creature, name):
        wanted = set(params.pitches)

        def played(t: float) -> float:
            for note in reversed(creature.ear.played):
                if t - note.time > params.window:
                    break
                if note.pitch in wanted and note.time <= t:
                    return 1.0
            return 0.0

        return FunctionPercept(name, played)


# -- fuzzy logic ----------------------------------------------------------------------------
class _OfParams(Params):
    of: list[str] = Field(min_length=1, description="the percepts combined")
    logic: Literal["minmax", "product"] = Field("minmax", description="fuzzy logic: min/max or product/sum")


@PERCEPTS.register
class And(PerceptPart):
    """Fuzzy and of other percepts."""

    pure = True
    name = "and"
    thesis = "percepts"
    Params = _OfParams
    refs = {"of": "percepts"}
    combine: ClassVar[type] = AndPercept

    def build(self, params, creature, name):
        return self.combine(name, [creature.percept(p) for p in params.of], logic=params.logic)


@PERCEPTS.register
class Or(And):
    """Fuzzy or of other percepts."""

    name = "or"
    combine = OrPercept


class _NotParams(Params):
    of: str = Field(description="the percept negated")


@PERCEPTS.register
class Not(PerceptPart):
    """Fuzzy not (1 − saliency) of another percept."""

    pure = True
    name = "not"
    thesis = "percepts"
    Params = _NotParams
    refs = {"of": "percepts"}

    def build(self, params, creature, name):
        return NotPercept(name, creature.percept(params.of))


# -- the body and the notes in space --------------------------------------------------------
@PERCEPTS.register
class Arrived(PerceptPart):
    """The body has arrived where its course led (1), or is still on its way (0)."""

    name = "arrived"
    thesis = "towards a complete motor system"
    needs = "body"

    def build(self, params, creature, name):
        return FunctionPercept(name, lambda t: 1.0 if creature.body.motor.arrived(t) else 0.0)


class _ShapedParams(Params):
    shaping: str = Field(description="a shape_gesture tuple: its gesture model judges the performance")
    window: float = Field(1.0, gt=0, le=60, description="seconds after a performance ends that it is salient")


@PERCEPTS.register
class Shaped(PerceptPart):
    """How well the body's last performance of a shaped gesture (the shape_gesture tuple's, or
    the tuple left behind after dispatch) matches what the gesture model learnt, in [0, 1],
    for ``window`` seconds after it ended: a trainer's eye for "it chased its tail"."""

    name = "shaped"
    thesis = "learning to chase your tail – part 2"
    needs = "body"
    Params = _ShapedParams
    refs = {"shaping": "tuples"}

    def build(self, params, creature, name):
        return FunctionPercept(name, lambda t: creature.tuple(params.shaping).action.performance_match(t, params.window))


@PERCEPTS.register
class FreshNotes(PerceptPart):
    """There are notes in space not struck lately (something to eat): 1, else 0."""

    name = "notes"
    thesis = "musical worlds"
    needs = "space"

    def build(self, params, creature, name):
        return FunctionPercept(name, lambda t: 1.0 if creature.notes.unstruck(t) else 0.0)


class _MotifParams(Params):
    pitches: list[MidiPitch] = Field(min_length=2, max_length=64, description="MIDI pitches of the phrase, in order")
    window: float = Field(0.1, gt=0, le=60, description="seconds it stays salient after the phrase's last note")


@PERCEPTS.register
class Motif(PerceptPart):
    """A phrase of the style was just heard from outside the colony: the last notes heard from
    outside are ``pitches``, in order; 1 for ``window`` seconds after the last of them. The
    trigger of a perception tuple that records the phrase in a forward transition model
    (thesis "perception as action": "*Du* percepts equipped with forward transition models
    ... can simulate and learn priming effects"). Only notes from outside count: what the
    colony plays is recorded by the tuples that play it, so it is not heard twice."""

    name = "motif"
    thesis = "perception as action"
    Params = _MotifParams

    def build(self, params, creature, name):
        from creatures.runtime.world import INPUT

        heard: deque[int] = deque(maxlen=len(params.pitches))
        matched = [-math.inf]

        def hear(note, source) -> None:
            if source != INPUT:
                return
            heard.append(note.pitch)
            if list(heard) == params.pitches:
                matched[0] = creature.now()

        creature.on_hear(hear)
        return FunctionPercept(name, lambda t: 1.0 if t - matched[0] <= params.window else 0.0)


class _PassageParams(Params):
    notes: int = Field(3, ge=2, le=4096, description="fewest notes of a heard passage still in space that count")


@PERCEPTS.register
class PassagePercept(PerceptPart):
    """A heard passage of at least ``notes`` notes is still in space (something to vary): 1,
    else 0 (passages as ``vary`` finds them: ``space.passage_gap`` splits each player's)."""

    name = "passage"
    thesis = "exchange (installation)"
    needs = "space"
    Params = _PassageParams

    @staticmethod
    def passage_notes(params) -> tuple[str, int]:
        """The key and the fewest heard notes a passage needs (checked against space.max_notes)."""
        return "notes", params.notes

    def build(self, params, creature, name):
        return FunctionPercept(name, lambda t: 1.0 if any(len(p) >= params.notes for p in creature.notes.passages())
                               else 0.0)


# -- temporal and activation models ---------------------------------------------------------
class _DueParams(Params):
    mean: float = Field(1.0, gt=0, description="prior inter-onset interval, seconds")
    std: float = Field(0.5, gt=0, le=bounds.LARGEST_RATE, description="its prior spread")
    longest: float = Field(3.0, gt=0, description="a longer gap is a pause, not an interval of the rhythm")
    memory: int = Field(8, ge=2, le=1024, description="intervals the model remembers")


@PERCEPTS.register
class Due(PerceptPart):
    """A note is due: a duration model of the intervals between heard onsets, read as the
    probability that the next onset should have come by now (0 just after a note, toward 1
    as the silence outlasts the rhythm). Expectation, not a threshold."""

    name = "due"
    thesis = "temporal models – duration models"
    Params = _DueParams

    def build(self, params, creature, name):
        model = SimpleDurationModel(params.mean, params.std, size=params.memory)
        last = [creature.ear.heard_at]

        def due(t: float) -> float:
            ear = creature.ear
            if ear.heard_at != last[0]:  # a new onset: teach the interval that led to it
                gap = ear.heard_at - last[0]
                if 0.0 < gap <= params.longest:
                    model.update(gap)
                last[0] = ear.heard_at
            if not math.isfinite(ear.heard_at):
                return 0.0
            z = (ear.since_heard(t) - model.mean) / (math.sqrt(2.0) * model.std)
            return 0.5 * (1.0 + math.erf(z))

        return FunctionPercept(name, due)


class _TogetherParams(Params):
    of: str = Field(description="the tuple whose usual company this percept looks for")
    alpha: float = Field(0.9, gt=0, lt=1, description="per-second filter constant of the activation model")


@PERCEPTS.register
class Together(PerceptPart):
    """How close the tuples active now are to ``of`` in an activation model of which tuples
    run together (1: always together, 0: never seen together): a Tr for "what usually
    accompanies this"."""

    name = "together"
    thesis = "activation models"
    Params = _TogetherParams
    refs = {"of": "tuples"}

    def build(self, params, creature, name):
        model: list[ActivationModel] = []

        def together(t: float) -> float:
            if not model:  # tuples are all built by the first evaluation
                model.append(ActivationModel(list(creature.tuples), alpha=params.alpha, start=t))
            m = model[0]
            active = [n for n, tp in creature.tuples.items() if tp.active]
            m.observe(t, active)
            others = [n for n in active if n != params.of]
            if not others:
                return 0.0
            return 1.0 - min(m.distance(params.of, n) for n in others) / m.max_distance

        return FunctionPercept(name, together)


# -- where it is (the installation's [room]: creatures/room/stage.py) -----------------------
ROOM_PERCEPTS = ("proximity", "bearing", "crowding", "sees")
"""Percept types that need a ``[room]`` (the config loader refuses them without one)."""

Whom = Literal["visitor", "creature", "player", "loud"]


def watched(kind: str, params: dict[str, Any]) -> str | None:
    """Whom a room percept of type ``kind`` with these keys watches (its ``of``, written or by
    default: the config loader refuses a visitor in a room that tracks none); None for a percept
    of no one in particular (crowding)."""
    part = PERCEPTS.get(kind)
    field = None if part is None else part.Params.model_fields.get("of")
    return None if field is None else params.get("of", field.default)


def _stage(creature: "Authored"):
    return creature.world.room


def _ramped(name: str, measure, low: float, high: float) -> Percept:
    """A percept of a room measure (``measure()``: a number, or None/inf when there is
    nothing to measure, which reads 0) as a fuzzy ramp from ``low`` (0) to ``high`` (1)."""
    def read(t: float) -> float:
        x = measure()
        return 0.0 if x is None or not math.isfinite(x) else ramp(x, low, high)

    return FunctionPercept(name, read)


class _ProximityParams(Params):
    of: Whom = Field("visitor", description="'visitor' (tracked), 'creature' (another), 'player' (where the "
                                            "last outside note came from) or 'loud' (a loud sound)")
    near: float = Field(1.0, ge=0, le=1000, description="metres at which it is fully salient")
    far: float = Field(5.0, ge=0, le=1000, description="metres beyond which it is 0")

    @field_validator("far")
    @classmethod
    def _beyond_near(cls, far: float, info: ValidationInfo) -> float:
        """Swapped, the ramp read 1 with no one near and 0 with someone beside it, nothing said."""
        near = info.data.get("near")
        if near is not None and near > far:
            raise ValueError(f"near = {near:g} m is beyond far = {far:g} m: the percept would read 1 when no one "
                             "is near and 0 when someone is (near ≤ far; a 'not' percept reads distance)")
        return far


@PERCEPTS.register
class Proximity(PerceptPart):
    """How near the nearest visitor, creature or loud sound is: 1 within ``near`` m, 0 beyond
    ``far``, linear between (REACT: neighbourhood; IViHumans: proximity)."""

    pure = True
    name = "proximity"
    thesis = "percepts"
    Params = _ProximityParams

    def build(self, params, creature, name):
        return _ramped(name, lambda: _stage(creature).distance(creature.name, params.of), params.far, params.near)


class _BearingParams(Params):
    of: Whom = Field("visitor", description="'visitor', 'creature', 'player' or 'loud'")
    width: float = Field(90.0, gt=0, le=180, description="degrees either side of ahead at which it falls to 0")


@PERCEPTS.register
class Bearing(PerceptPart):
    """How straight ahead the nearest visitor, creature or loud sound is: 1 dead ahead, 0 at
    ``width`` degrees off the heading or more (facing someone, IViHumans)."""

    pure = True
    name = "bearing"
    thesis = "percepts"
    Params = _BearingParams

    def build(self, params, creature, name):
        def off_ahead() -> float | None:
            b = _stage(creature).bearing(creature.name, params.of)
            return None if b is None else abs(b)

        return _ramped(name, off_ahead, params.width, 0.0)


class _CrowdingParams(Params):
    radius: float = Field(2.0, gt=0, le=1000, description="metres around the creature counted")
    full: int = Field(6, ge=1, le=10_000, description="others within `radius` at which it is fully salient")


@PERCEPTS.register
class Crowding(PerceptPart):
    """Crowd density: others within ``radius`` m as a fraction of ``full`` (REACT's kd-tree
    range search)."""

    pure = True
    name = "crowding"
    thesis = "percepts"
    Params = _CrowdingParams

    def build(self, params, creature, name):
        return FunctionPercept(name, lambda t: min(_stage(creature).crowding(creature.name, params.radius)
                                                   / params.full, 1.0))


class _SeesParams(Params):
    of: Literal["visitor", "creature"] = Field("visitor", description="'visitor' or 'creature'")
    full: int = Field(1, ge=1, le=10_000, description="how many seen make it fully salient")


@PERCEPTS.register
class Sees(PerceptPart):
    """What is in the creature's vision cone (``[creature.vehicle]`` fov and sight) and not behind
    an obstacle, as a fraction of ``full`` (REACT: the range search over the vision cone)."""

    pure = True
    name = "sees"
    thesis = "percepts"
    Params = _SeesParams

    def build(self, params, creature, name):
        return FunctionPercept(name, lambda t: min(_stage(creature).sees(creature.name, params.of) / params.full, 1.0))
# -- sounds heard, as utterance classes (thesis: "soundcreatures", "aural models") -----------
class _UtteranceParams(Params):
    seed_model: SeedModel = Field(None, description="an aural model (save_aural_model JSON, or `creatures aural-model` "
                                                    "from sound files; relative to the config) to start from instead of an "
                                                    "empty repertoire (thesis: persistent aural models seed "
                                                    "a creature)")
    nearest: bool = Field(False, description="each sound is heard as one class: a class is salient only while the "
                                             "sound resembles it more than its sibling classes and lies within its "
                                             "radius of an exemplar (false: each as much as the sound resembles it)")


@PERCEPTS.register
class Utterances(PerceptPart):
    """What is heard, as utterance classes: the root of the creature's one aural percept tree
    (1 while a sound heard within ``hearing.memory`` is perceived). It keeps the sounds that
    led to valued tuples; when a tuple on a class becomes valuable, fission clusters its
    sounds into child classes by cepstral distance (each salient by similarity to its
    exemplars, or with ``nearest`` only the class the sound is nearest, within its radius),
    and children no longer distinct fuse back (``learning.aural``)."""

    name = "utterance"
    thesis = "aural models – cepstral models"
    Params = _UtteranceParams
    needs = "hearing"
    joins_tree = False

    def build(self, params, creature, name):
        return creature.aural.tree(name, params.seed_model, nearest=params.nearest)


class _OfUtterancesParams(Params):
    of: str = Field(description="an 'utterance' percept")


@PERCEPTS.register
class Repertoire(PerceptPart):
    """The utterance percept ``of`` holds sounds to sing (1), or none yet (0)."""

    name = "repertoire"
    thesis = "aural Ac percept trees"
    Params = _OfUtterancesParams
    refs = {"of": "utterances"}
    needs = "hearing"

    def build(self, params, creature, name):
        tree = creature.aural.percept(params.of)
        return FunctionPercept(name, lambda t: 1.0 if tree.members else 0.0)


@PERCEPTS.register
class Unattended(PerceptPart):
    """A sound of ``of`` is heard (within ``hearing.memory``) that no ``attend`` has taken yet
    (1), else 0. The trigger of an ``attend`` that takes each sound once: the sound stays
    heard after it, so the tuples its classes trigger (an answer in kind) can follow
    attending instead of losing to it again."""

    name = "unattended"
    thesis = "soundcreatures (installation)"
    Params = _OfUtterancesParams
    refs = {"of": "utterances"}
    needs = "hearing"

    def build(self, params, creature, name):
        tree = creature.aural.percept(params.of)
        return FunctionPercept(name, lambda t: creature.aural.unattended(tree, t))


class _SungParams(Params):
    wait: float = Field(1.0, ge=0, le=10, description="seconds after the song in which an answer is awaited")


@PERCEPTS.register
class Sung(PerceptPart):
    """The creature's latest song is over, and ``wait`` seconds more (a Du for "until sung
    and answered": a sound heard in the wait still rewards the song)."""

    name = "sung"
    thesis = "soundcreatures (installation)"
    Params = _SungParams
    needs = "hearing"

    def build(self, params, creature, name):
        mouth = creature.aural.mouth
        return FunctionPercept(name, lambda t: 1.0 if t >= mouth.until + params.wait else 0.0)


# -- expectations and perception as action ---------------------------------------------------
class _SurpriseParams(Params):
    tuple: str | None = Field(None, description="whose surprise (none: the creature's latest, any tuple's)")
    low: float | None = Field(None, ge=0, le=1, description="a fuzzy ramp of the surprise instead: saliency 0 "
                                                            "here (a faded surprise startles nothing) …")
    high: float | None = Field(None, ge=0, le=1, description="… and 1 here")

    @model_validator(mode="after")
    def _ramp(self):
        if (self.low is None) != (self.high is None):
            raise ValueError("give both 'low' and 'high' (a fuzzy ramp of the surprise), or neither")
        return self


@PERCEPTS.register
class Surprise(PerceptPart):
    """How surprised the creature is: confidence × violation of the last expectation violated
    (a Du's end or a value), fading over ``expectations.decay`` seconds; 0 while nothing has
    surprised it. Needs ``[creature.expectations]``."""

    name = "surprise"
    thesis = "expectations about the consequences of actions"
    Params = _SurpriseParams
    refs = {"tuple": "tuples"}

    def build(self, params, creature, name):
        if params.low is None:
            return FunctionPercept(name, lambda t: creature.expectations.surprise(t, params.tuple))
        return FunctionPercept(name, lambda t: ramp(creature.expectations.surprise(t, params.tuple), params.low,
                                                    params.high))


class _ConfidenceParams(Params):
    tuple: str = Field(description="whose confidence")


@PERCEPTS.register
class ConfidencePercept(PerceptPart):
    """How much the creature trusts ``tuple``'s expectations now, in [0, 1]: falls when they
    were recently wrong and while they go untested. Needs ``[creature.expectations]``."""

    name = "confidence"
    thesis = "expectations about value"
    Params = _ConfidenceParams
    refs = {"tuple": "tuples"}

    def build(self, params, creature, name):
        return FunctionPercept(name, lambda t: creature.expectations.confidence(t, params.tuple))


class _PerceivingParams(Params):
    tuple: str | None = Field(None, description="the perception action whose activity this models")
    group: str | None = Field(None, description="… or a perception group: the strongest of its members")
    trace: float = Field(0.0, ge=0, le=3600, description="seconds the activity lingers after the tuple stops "
                                                         "(exp(−age/trace))")
    valued: bool = Field(True, description="saliency is activity × the perception's value (its saliency)")
    ground: float = Field(0.1, ge=0, le=1, description="rate at which the credit of tuples triggered by this "
                                                       "percept grounds the perception's value "
                                                       "(their group in learning.groups)")

    @model_validator(mode="after")
    def _one_source(self):
        if (self.tuple is None) == (self.group is None):
            raise ValueError("give either 'tuple' or 'group'")
        return self


@PERCEPTS.register
class Perceiving(PerceptPart):
    """The act of perceiving (a perception action, or a group of them, is active), valued:
    a sub-tree of these models a perception group's activity for other tuples' Tr, and the
    perceptions' values ground its saliency (see creatures/behaviour/perception.py)."""

    name = "perceiving"
    thesis = "perception as action"
    Params = _PerceivingParams
    refs = {"tuple": "tuples", "group": "groups"}

    def build(self, params, creature, name):
        def watched() -> list:
            if params.tuple is not None:
                return [creature.tuple(params.tuple)]
            return creature.groups[params.group].tuples

        return PerceivingPercept(name, watched, trace=params.trace, valued=params.valued, ground=params.ground)


# -- a population of sequence models (thesis: "listen (installation)") ----------------------
class _PopulationParams(Params):
    memory: int = Field(16, ge=3, le=256, description="notes in the running memory buffer models are matched against")
    analysis_every: float = Field(0.5, gt=0, le=10, description="seconds between analyses of the population "
                                                                 "(matching, learning, maintenance)")
    context: int = Field(4, ge=1, le=32, description="already-learnt notes put in front of new notes when a model "
                                                     "learns them, so it can find where they go")
    known: float = Field(0.2, ge=0, le=1, description="fraction of the arriving notes' transitions a model must "
                                                      "already explain to learn them (else a growing model extends "
                                                      "itself, or a new model is spawned)")
    max_models: int = Field(6, ge=1, le=MOST_MODELS, description="most models in the population; the least useful "
                                                                 "retires")
    max_states: int = Field(96, ge=8, le=MOST_STATES, description="states a model may grow to before it is distilled "
                                                                  "to its core")
    forget: float = Field(120.0, gt=0, le=LONGEST_SECONDS, description="time constant (s) of a model's usefulness; "
                                                                       "unused models retire")
    continuation: int = Field(8, ge=0, le=256, description="predicted notes it may play when the music stops")

    @model_validator(mode="after")
    def _context_fits(self):
        if self.context >= self.memory:
            raise ValueError(f"context ({self.context}) must be smaller than memory ({self.memory}): "
                             "the memory holds the context and the new notes")
        return self


@PERCEPTS.register
class Population(PerceptPart):
    """A population of sequence models of the heard notes, kept in a percept (figure 43):
    models are spawned for material none explains, fused, distilled and retired, and the
    best match is what ``dance`` and ``anticipate`` play out. Salient as the music is
    familiar (exp of the best model's mean log-likelihood of the memory)."""

    name = "population"
    thesis = "listen (installation)"
    Params = _PopulationParams
    needs = "body"

    def build(self, params, creature, name):
        from creatures.authored.listening import Listening

        return Listening(name, creature, params)


class _MapsParams(Params):
    size: tuple[int, int] = Field((6, 6), description="rows and columns of the grid both maps share")
    radius: float = Field(1.0, gt=0, le=16, description="neighbourhood radius in grid steps (a Gaussian's "
                                                        "deviation); constant, so the maps track what is heard now")
    rate: float = Field(0.5, gt=0, le=1, description="how far a note of velocity 127 moves its winner toward it "
                                                     "(and the pose map's node there toward the pose); softer notes "
                                                     "in proportion")
    background: float = Field(0.02, ge=0, le=1, description="how far each tick's pose moves the pose map's winner "
                                                            "toward it (the animation in the background)")

    @field_validator("size")
    @classmethod
    def _grid(cls, size):
        if not all(2 <= n <= 32 for n in size):
            raise ValueError(f"size: rows and columns must be 2 to 32, found {list(size)}")
        return size


@PERCEPTS.register
class Maps(PerceptPart):
    """listen's two self-organising maps on one grid: music (pitch, interval, inter-onset
    time of each heard note) and pose (the body's poses), tied by strict topology and made
    plastic by each note's velocity; ``dance``/``anticipate`` with ``poses`` dance on them.
    Salient as the music is familiar to the map (``exp`` of minus its running quantisation
    error)."""

    name = "maps"
    thesis = "listen (installation): extensions"
    Params = _MapsParams
    needs = "body"

    def build(self, params, creature, name):
        from creatures.authored.maps import MusicPoseMaps

        return MusicPoseMaps(name, creature, params)


class _LullParams(Params):
    of: str = Field(description="a 'population' percept")
    patience: float = Field(2.0, gt=1, le=10, description="silence, in multiples of the gap its model expects "
                                                          "next, before the lull is salient")


@PERCEPTS.register
class Lull(PerceptPart):
    """The music has stopped, by the model's own clock: 1 once nothing has been heard for
    ``patience`` times the gap the played-out model expects next (after some music)."""

    name = "lull"
    thesis = "listen (installation)"
    Params = _LullParams
    refs = {"of": "populations"}

    def build(self, params, creature, name):
        listening = creature.percept(params.of)
        return FunctionPercept(name, lambda t: listening.lull(t, params.patience))


class _PredictsParams(Params):
    of: str = Field(description="a 'population' percept")


@PERCEPTS.register
class Predicts(PerceptPart):
    """The played-out model predicts a next note the creature may still play (1), or none /
    its ``continuation`` is spent (0)."""

    name = "predicts"
    thesis = "listen (installation)"
    Params = _PredictsParams
    refs = {"of": "populations"}

    def build(self, params, creature, name):
        listening = creature.percept(params.of)
        return FunctionPercept(name, lambda t: listening.predicts())


# -- a rock on the sand (thesis: "sand:stone (installation)") ------------------------------
class _ActiveParams(Params):
    tuple: str = Field(description="a tuple")


@PERCEPTS.register
class Active(PerceptPart):
    """The tuple is running (1) or not (0): what the creature is doing, as a percept (a drive
    input for what singing draws, what inhaling restores)."""

    name = "active"
    thesis = "percepts"
    Params = _ActiveParams
    refs = {"tuple": "tuples"}

    def build(self, params, creature, name):
        return FunctionPercept(name, lambda t: 1.0 if creature.tuples[params.tuple].active else 0.0)


class _ScriptParams(Params):
    points: list[tuple[Seconds, float]] = Field(min_length=1, max_length=100_000,
                                                description="[seconds, level 0..1] points, linearly interpolated and "
                                                            "held beyond the ends")
    rock: int | None = Field(None, ge=0, le=127, description="pitch a sensor sends on sensor_channel; its reading "
                                                             "(velocity/127) overrides the script from then on")
    sensor_channel: int = Field(15, ge=0, le=15, description="MIDI channel of sensor readings (never heard as music)")

    @field_validator("points")
    @classmethod
    def _script(cls, points: list[tuple[float, float]]) -> list[tuple[float, float]]:
        times = [t for t, _ in points]
        if any(not 0.0 <= level <= 1.0 for _, level in points):
            raise ValueError("levels must lie in 0..1")
        if times[0] < 0 or any(b <= a for a, b in zip(times, times[1:])):
            raise ValueError(f"times must start at >= 0 and strictly increase, got {times}")
        return points


@PERCEPTS.register
class Script(PerceptPart):
    """A level scripted over time (a visitor moving a rock in and out), which a sensor that
    reports as notes takes over: notes from outside on ``sensor_channel`` are readings, not
    music (nothing of the creature hears them), and one of pitch ``rock`` sets the level to
    its velocity / 127 from then on (saved with the creature)."""

    name = "script"
    thesis = "sand:stone (installation)"
    Params = _ScriptParams

    def build(self, params, creature, name):
        from creatures.runtime.world import INPUT

        script = Scripted(params.points)
        sensed: list[float | None] = [None]

        def reading(note, source) -> bool:
            if source != INPUT or note.channel != params.sensor_channel:
                return False
            if note.pitch == params.rock:
                sensed[0] = note.velocity / 127.0
            return True

        def restore(state) -> None:
            sensed[0] = None if state is None else bounds.number(state, "sensed", low=0.0, high=1.0)

        creature.on_reading(reading)
        creature.keep("percepts", name, lambda: sensed[0], restore)
        return FunctionPercept(name, lambda t: sensed[0] if sensed[0] is not None else script(t))


class _SensedParams(Params):
    creature: str = Field(description="another creature of the installation, by name")
    percept: str = Field(description="one of that creature's percepts, by name")


@PERCEPTS.register
class Sensed(PerceptPart):
    """Another creature's percept, read as this one's own: sand:stone's statue is moved by
    what each rock senses ("the proximity to the center of the bed of sand and the identity
    of the rocks is sensed ... firstly by directly modulating the pose of the character on
    screen, and secondly by controlling the colony of music creatures"). Both names are
    checked when the installation loads."""

    name = "sensed"
    thesis = "sand:stone (installation)"
    Params = _SensedParams

    def build(self, params, creature, name):
        found: list[Percept] = []

        def read(t: float) -> float:
            if not found:  # every creature is made by the first tick
                other = next(c for c in creature.world.creatures if c.name == params.creature)
                found.append(other.percept(params.percept))
            return found[0].evaluate(t)

        return FunctionPercept(name, read)


class _DaylightParams(Params):
    start: float | Literal["local"] = Field(10.0, description="the hour (0–24) of the installation world's day when "
                                                              "the creature is made; 'local': the machine's local "
                                                              "time then (a live show in the gallery's own day; a "
                                                              "number keeps offline runs reproducible)")
    day: float = Field(86_400.0, gt=1, le=LONGEST_SECONDS, description="seconds a day of the installation world "
                                                                       "lasts (86400: the visitors' own)")
    noon: float = Field(14.0, ge=0, lt=24, description="the brightest hour")

    @field_validator("start")
    @classmethod
    def _hour(cls, start):
        if start != "local" and not 0 <= start < 24:
            raise ValueError(f"start: an hour in [0, 24) or 'local', found {start}")
        return start


@PERCEPTS.register
class Daylight(PerceptPart):
    """The time of day in the installation world, as its light: 1 at ``noon``, 0 twelve hours
    from it, a cosine between (sand:stone: "timbre is modulated directly by the boredom model,
    and by the time of day in the installation world")."""

    name = "daylight"
    thesis = "sand:stone (installation)"
    Params = _DaylightParams

    def build(self, params, creature, name):
        import time

        made = creature.now()
        if params.start == "local":
            now = time.localtime()
            start = now.tm_hour + now.tm_min / 60 + now.tm_sec / 3600
        else:
            start = float(params.start)

        def light(t: float) -> float:
            hour = start + 24.0 * (t - made) / params.day
            return 0.5 + 0.5 * math.cos(2 * math.pi * (hour - params.noon) / 24.0)

        return FunctionPercept(name, light)


class _DiscordParams(Params):
    key_of: str = Field(description="a tuple whose action is 'sing_phrases': the key of the segment it sings")
    within: float = Field(1.5, ge=0, lt=STEPS / 2, description="circle-of-fifths distance below which heard music "
                                                                "is correlated")
    memory: float = Field(4.0, gt=0, le=LONGEST_SECONDS, description="seconds over which heard music fades from the ear")


@PERCEPTS.register
class Discord(PerceptPart):
    """Uncorrelated music: what was heard lately (one fading circle-of-fifths vector) far from
    the key of the segment being sung — 0 within ``within`` fifths, rising to 1 at the
    tritone, scaled by how much music is in the ear."""

    name = "discord"
    thesis = "sand:stone (installation)"
    Params = _DiscordParams
    refs = {"key_of": "tuples"}

    def build(self, params, creature, name):
        from creatures.authored.song import HeardMusic

        heard = HeardMusic(params.memory)

        def hear(note, source) -> None:
            heard.hear(creature.now(), note.pitch, note.duration)

        def discord(t: float) -> float:
            heard.fade(t)
            key = creature.tuples[params.key_of].action.song.key()
            beyond = (heard.distance(key) - params.within) / (STEPS / 2 - params.within)
            return heard.amount() * min(1.0, max(0.0, beyond))

        creature.on_hear(hear)
        creature.keep("percepts", name, heard.state, lambda s: heard.restore(s, creature.now()))
        percept = FunctionPercept(name, discord)
        percept.heard = heard  # the 'music heard' percept reads the same ear
        return percept


class _MusicHeardParams(Params):
    of: str = Field(description="a 'discord' percept: its ear")


@PERCEPTS.register
class MusicHeard(PerceptPart):
    """How much music is in a ``discord`` percept's ear, 0..1 (w / (w + 1) of its fading
    duration-weighted notes)."""

    name = "music_heard"
    thesis = "sand:stone (installation)"
    Params = _MusicHeardParams
    refs = {"of": "percepts"}

    def build(self, params, creature, name):
        ear = creature.percept(params.of).heard

        def amount(t: float) -> float:
            ear.fade(t)
            return ear.amount()

        return FunctionPercept(name, amount)
