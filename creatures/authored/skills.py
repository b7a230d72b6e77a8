"""Skills an authored creature layers over its course: looking, sweeps, adverbs, and the Ac
percept that shapes an adverb (thesis "blend based motor systems", "general layering – adverb
parameters", "simple shaping"; WavesWorld "Reflex, Oscillator, or Servo-Mechanism").

Each action here adds one ``add`` contribution to the body's blend
(:meth:`creatures.kinds.parts.Body.layer`), masked to the joints it moves, so it runs while
another group's action (a wander, a program) sets the course: a creature can look at whoever
it hears while it wanders, or wander in a bored way. Joint variables are written
``"joint.axis"`` (``"head.y"``: the head's turn about its own y axis, degrees).

* ``look_at`` — eyes, then the head within its limits, then the body, the short way round,
  toward whoever it heard last (:func:`heard_bearing`), on a :class:`~creatures.motor.skills.Servo`
  with patience; when it stops the servo brings every joint back and the layer leaves.
* ``sweep`` — WavesWorld's current→min→max→current over a list of joint variables.
* ``adverb`` — an RBF blend of example animations in neutral time
  (:class:`~creatures.motor.adverbs.AdverbBlend`) played as a loop; its adverb value comes
  from a drive (re-read every cycle) or is sampled from an ``adverb_model`` Ac percept when the
  tuple starts. A reward that credits the tuple feeds that sample back into the percept's
  model (:meth:`AdverbModel.reinforce`): rewarding high begs makes it beg higher.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from pydantic import Field, model_validator

from creatures.authored.actions import ActionPart, MotorPart
from creatures.authored.percepts import PerceptPart
from creatures.authored.registry import ACTIONS, PERCEPTS, Params
from creatures.behaviour.action_tuple import Action, ActionTuple
from creatures.behaviour.models.gaussian import GaussianModel
from creatures.behaviour.percept import FunctionPercept
from creatures.bounds import Bounded
from creatures.config import nearest
from creatures.kinds.layers import LayerSpec, blend_field, source_limits
from creatures.motor.adverbs import AdverbBlend, Example
from creatures.motor.pose import PoseSet
from creatures.motor import quaternion as quat
from creatures.motor.skills import Servo, Sweep, look_turns, paired_stages

if TYPE_CHECKING:
    from creatures.authored.creature import Authored
    from creatures.kinds.parts import Body

AXES = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}
STAGE_HALF_WIDTH = 2.0
"""Metres from the middle of a stage without a ``[room]`` to a creature panned hard left or right."""
AUDIENCE = 2.0
"""Metres in front of that line where an outside player (``input``) stands."""
LOOK_CHAIN = {"eye_l": 30.0, "eye_r": 30.0, "head": 70.0, "neck": 50.0, "chest": 35.0, "spine": 20.0, "pelvis": 90.0}
"""The default look: the eyes (a body that has them), then the head, then the body, degrees each."""


def _variable(body: "Body", name: str) -> tuple[int, np.ndarray]:
    """``"joint.axis"`` → the joint's index and its unit axis (ValueError naming the nearest joints)."""
    _joint_variables([name])
    joint, _, axis = name.rpartition(".")
    if joint not in body.skeleton.names:
        raise ValueError(f"{name!r}: no joint {joint!r} in the body{nearest(joint, body.skeleton.names, 'joints')}")
    return body.skeleton.names.index(joint), np.array(AXES[axis])


def _joint_variables(names) -> None:
    """Every name is ``joint.x``, ``joint.y`` or ``joint.z`` (a ValueError for the config's line,
    naming the name and the nearest it could mean)."""
    for name in names:
        joint, _, axis = name.rpartition(".")
        if not joint:
            raise ValueError(f"{name!r}: a joint variable is 'joint.x', 'joint.y' or 'joint.z'")
        if axis not in AXES:
            meant = nearest(name, [f"{joint}.{a}" for a in AXES], "joint variables", n=len(AXES))
            raise ValueError(f"{name!r}: no axis {axis!r}{meant}")


def asked_turns(frames: list[dict[str, float]]) -> dict[str, float]:
    """The most each joint is asked to turn (degrees) over ``frames`` (joint variable →
    degrees; voice parameters are passed over): a frame's turns about one joint's axes are one
    rotation (:class:`JointOffsets`), as far as their root sum of squares."""
    most: dict[str, float] = {}
    for frame in frames:
        squares: dict[str, float] = {}
        for name, degrees in frame.items():
            if not name.startswith("voice."):
                joint = name.rpartition(".")[0]
                squares[joint] = squares.get(joint, 0.0) + degrees * degrees
        for joint, total in squares.items():
            most[joint] = max(most.get(joint, 0.0), math.sqrt(total))
    return most


class JointOffsets:
    """An ``add`` layer's source: named joint variables (degrees) as one rotation per joint
    (the turns about each joint's axes summed as a rotation vector)."""

    def __init__(self, body: "Body", variables: list[str]) -> None:
        self.count = body.skeleton.joint_count
        pairs = [_variable(body, v) for v in variables]
        self.joints = np.array([j for j, _ in pairs], dtype=int)
        self.axes = np.array([a for _, a in pairs]).reshape(-1, 3)
        self.mask = np.zeros(self.count)
        self.mask[self.joints] = 1.0
        self.degrees = np.zeros(len(pairs))

    def __call__(self, t: float) -> np.ndarray:
        return quat.turns_about(self.count, self.joints, self.axes, np.radians(self.degrees))


def heard_bearing(creature: "Authored") -> float | None:
    """Degrees (positive to its left) from the creature's heading to whoever it heard last.

    In a ``[room]`` the stage knows where creatures and players stand. Without one the
    creatures stand on a line across the stage at their ``pan`` facing the audience (pan −1
    is the audience's left, so the creature's right), and an outside player stands in front.
    None when it has heard no one."""
    source = creature.ear.heard_from
    if not source:
        return None
    if creature.stage is not None:
        return creature.stage.toward(creature.name, source)
    pans = {c.name: c.spec.pan for c in creature.world.creatures}
    me = pans.get(creature.name, 0.0) * STAGE_HALF_WIDTH
    if source in pans:
        return math.degrees(math.atan2(pans[source] * STAGE_HALF_WIDTH - me, 0.0))
    return math.degrees(math.atan2(-me, AUDIENCE))


# -- looking --------------------------------------------------------------------------------
class _LookParams(Params):
    joints: dict[str, float] | None = Field(None, description="joint → the most it turns (degrees), eyes first, "
                                                              "then head, then body; a left/right pair (eye_l, "
                                                              "eye_r) turns together (default: those of "
                                                              f"{', '.join(LOOK_CHAIN)} the body has); each is "
                                                              "also held within the source material's range")
    axis: str = Field("y", pattern="^[xyz]$", description="the joints' axis the look turns about (the "
                                                          "shipped bodies' up)")
    speed: float = Field(120.0, gt=0, le=3600, description="degrees per second each joint turns at most")
    patience: float = Field(3.0, gt=0, le=3600, description="seconds the look may lag a moving source before "
                                                            "it gives up (done)")
    fade: float = Field(0.0, ge=0, le=60, description="seconds the layer eases in and out (an add look is eased "
                                                      "by its servo; a mean or exclusive one takes the joints "
                                                      "from the course, so give it a fade)")
    blend: LayerSpec = blend_field()


@ACTIONS.register
class LookAt(MotorPart):
    """Turn to look at whoever it heard last: eyes, then head within its limits, then body,
    the short way round, over whatever the course does (done if it gives up); stopped, it
    turns back and the layer leaves."""

    name = "look_at"
    thesis = "blend based motor systems"
    ends = True
    Params = _LookParams

    @classmethod
    def joints(cls, params):
        return list(params.joints or {})

    def build(self, params, creature, name):
        body = creature.body
        chain = params.joints if params.joints is not None else {
            j: limit for j, limit in LOOK_CHAIN.items() if j in body.skeleton.names}
        if not chain:
            raise ValueError(f"look_at: the body has none of the joints {', '.join(LOOK_CHAIN)}; name some in 'joints'")
        held = np.degrees(source_limits(body.graph).range)
        names = body.skeleton.names
        limits = {j: min(limit, float(held[names.index(j)])) for j, limit in chain.items()}
        turning = [j for j, limit in limits.items() if limit > 0.0]  # a joint the material never turns stays out
        if not turning:
            raise ValueError(f"look_at: none of {', '.join(chain)} ever turns in the body's material")
        offsets = JointOffsets(body, [f"{j}.{params.axis}" for j in turning])
        limits = np.array([limits[j] for j in turning])
        return LookAction(name, body, offsets, limits, paired_stages(turning), lambda: heard_bearing(creature), params)


class LookAction(Action):
    """The look skill over one body (see :class:`LookAt`)."""

    def __init__(self, name: str, body: "Body", offsets: JointOffsets, limits: np.ndarray, stages: list[int], bearing,
                 params) -> None:
        super().__init__(name)
        self.body, self.offsets, self.limits, self.stages, self.bearing = body, offsets, limits, stages, bearing
        self.servo = Servo(len(limits), rate=params.speed, tolerance=0.5)
        self.patience, self.blend, self.fade = params.patience, params.blend, params.fade
        self._bearing, self._turns = None, np.zeros(len(limits))

    def _source(self, t: float) -> np.ndarray:
        self.offsets.degrees = self.servo.step(t)
        return self.offsets(t)

    def start(self, t: float, tuple_: ActionTuple) -> None:
        self.servo.patience = self.patience
        self.body.layer(self.blend.contribution(self.name, self._source, self.offsets.mask, self.fade), t)
        self.update(t)

    def update(self, t: float) -> None:
        bearing = self.bearing()
        if bearing is not None:
            if bearing != self._bearing:  # the turns change only when the source moves
                self._bearing, self._turns = bearing, look_turns(bearing, self.limits, self.stages)
            self.servo.aim(self._turns, t)

    def stop(self, t: float, *, interrupted: bool) -> None:
        self.servo.patience, self.servo.gave_up = math.inf, False
        self.servo.aim(np.zeros(len(self.limits)), t)
        # an offset is back at rest by the servo's eta, and the layer then leaves exactly; a look
        # that holds the joints itself (mean, exclusive) eases back to the course from now
        self.body.unlayer(self.name, self.servo.eta(t) if self.blend.offsets else t)

    def done(self, t: float) -> float:
        return 1.0 if self.servo.gave_up else 0.0


# -- skills over named variables: sweeps, oscillators, servos --------------------------------
VOICE_PARAMETERS = ("voice.gain", "voice.pan", "voice.push", "voice.cutoff", "voice.tension", "voice.damping")
"""Voice parameters a skill may drive, blended per tick as a body's joints are (a skill's
numbers are offsets added to the rest value): ``voice.gain`` multiplies what the creature
sounds (1 at rest), ``voice.pan`` moves it across the stereo pair from its ``pan`` (0 at rest;
the sum held to [−1, 1]; a ``[room]`` places creatures by where they stand instead), and
``voice.push`` scales how hard the body's movement pushes its scanned strings (1 at rest:
``[creature.voice] body_gain``; thesis "artificial gestural control"), and ``voice.cutoff``
scales the low-pass cutoff of a creature that sings through a mouth (1 at rest: what its back
angle sets; thesis "soundcreatures") or through strings with ``[creature.voice] bright_hz``
(1 at rest: that cutoff; thesis "sand:stone", a timbre the boredom model modulates), and
``voice.tension`` and ``voice.damping`` scale its scanned strings' stiffness and damping (1 at rest: ``[creature.voice]``'s; held within the
gestural limit and a stable integrator, :meth:`audio.scanned.StringParameters.retuned`): the
timbre of a scanned string is its physics (thesis "scanned synthesis")."""
VOICE_REST = np.array([1.0, 0.0, 1.0, 1.0, 1.0, 1.0])
"""Each voice parameter's value at rest (what the blend holds where no layer drives it)."""
GAIN, PAN, PUSH, CUTOFF, TENSION, DAMPING = range(len(VOICE_PARAMETERS))
"""Each voice parameter's channel in the blend (the order of :data:`VOICE_PARAMETERS`)."""


def _named(names) -> None:
    """Every name is a joint variable or a voice parameter (ValueError for the config's line)."""
    _joint_variables(n for n in names if not n.startswith("voice."))
    for n in names:
        if n.startswith("voice.") and n not in VOICE_PARAMETERS:
            raise ValueError(f"{n!r} is no voice parameter{nearest(n, VOICE_PARAMETERS, 'voice parameters')}")


def _joints_of(names) -> list[str]:
    return [n.rpartition(".")[0] for n in names if not n.startswith("voice.")]


class Variables:
    """One action's layers over named variables: joint variables (degrees) as an ``add``
    layer on the body, voice parameters as an ``add`` layer on the creature's voice
    parameters; ``value(t)`` gives every variable's offset, in the order named."""

    def __init__(self, creature: "Authored", name: str, names: list[str], value, blend: LayerSpec) -> None:
        self.creature, self.name, self.value, self.blend = creature, name, value, blend
        self._joints = np.array([i for i, n in enumerate(names) if not n.startswith("voice.")], dtype=int)
        self._voice = [(i, VOICE_PARAMETERS.index(n)) for i, n in enumerate(names) if n.startswith("voice.")]
        joints = [names[i] for i in self._joints]
        if joints and creature.body is None:
            raise ValueError(f"{name!r} moves {', '.join(joints)}: the creature needs a body")
        self.offsets = JointOffsets(creature.body, joints) if joints else None

    def _rotations(self, t: float) -> np.ndarray:
        self.offsets.degrees = self.value(t)[self._joints]
        return self.offsets(t)

    def _parameters(self, t: float) -> np.ndarray:
        out = np.zeros(len(VOICE_PARAMETERS)) if self.blend.offsets else VOICE_REST.copy()
        values = self.value(t)
        for i, p in self._voice:
            out[p] += values[i]
        return out

    def start(self, t: float, fade: float) -> None:
        if self.offsets is not None:
            self.creature.body.layer(self.blend.contribution(self.name, self._rotations, self.offsets.mask, fade), t)
        if self._voice:
            mask = np.zeros(len(VOICE_PARAMETERS))
            mask[[p for _, p in self._voice]] = 1.0
            self.creature.voice_parameters().start(self.blend.contribution(self.name, self._parameters, mask, fade), t)

    def stop(self, t: float) -> None:
        if self.offsets is not None:
            self.creature.body.unlayer(self.name, t)
        if self._voice:
            self.creature.voice_parameters().stop(self.name, t)


class _SkillPart(ActionPart):
    """A skill over named variables: joint variables need the body (checked at load)."""

    @classmethod
    def joints(cls, params):
        return _joints_of(params.variables)

    @classmethod
    def voice_parameters(cls, params) -> list[str]:
        """The voice parameters it drives (a mouth's, checked against the creature at load)."""
        return [n for n in params.variables if n.startswith("voice.")]

    @classmethod
    def turns(cls, params) -> dict[str, float]:
        """The most it asks of each joint (degrees): a variable's depth, or either end of its
        [min, max] or [at 0, at 1] (all of them move together)."""
        ends = {n: v if isinstance(v, tuple) else (v,) for n, v in params.variables.items()}
        return asked_turns([{n: e[min(k, len(e) - 1)] for n, e in ends.items()} for k in range(2)])


class _VariablesParams(Params):
    """The keys every skill over named variables shares; ``variables`` is each one's own."""

    fade: float = Field(0.5, ge=0, le=60, description="seconds the layer eases in and out")
    blend: LayerSpec = blend_field()

    @model_validator(mode="after")
    def _names(self):
        _named(self.variables)
        return self


class _SweepParams(_VariablesParams):
    variables: dict[str, tuple[Bounded, Bounded]] = Field(min_length=1, description="joint variable ('chest.y', "
                                                                               "degrees) or voice parameter "
                                                                               "('voice.gain') → [min, max] offset")
    duration: float = Field(2.0, gt=0, le=3600, description="seconds for current→min→max→current")
    fade: float = Field(0.0, ge=0, le=60, description="seconds the layer eases in and out")

    @model_validator(mode="after")
    def _ordered(self):
        for name, (low, high) in self.variables.items():
            if low > high:
                raise ValueError(f"{name!r}: min {low} is above max {high}")
        return self


@ACTIONS.register
class SweepVariables(_SkillPart):
    """Sweep named variables current→min→max→current at constant velocity, all together over
    ``duration`` (WavesWorld's ``currentMinMaxCurrent``; done when back)."""

    name = "sweep"
    thesis = "blend based motor systems"
    ends = True
    Params = _SweepParams

    def build(self, params, creature, name):
        sweep = Sweep([lo for lo, _ in params.variables.values()], [hi for _, hi in params.variables.values()],
                      params.duration)
        layers = Variables(creature, name, list(params.variables), sweep.value, params.blend)

        class SweepAction(Action):
            def start(self, t, tuple_):
                sweep.start(np.zeros(len(params.variables)), t)  # the layer's own offsets start at 0
                layers.start(t, params.fade)

            def stop(self, t, *, interrupted):
                layers.stop(t)

            def done(self, t):
                return 1.0 if sweep.done(t) else 0.0

        return SweepAction(name)


class _OscillateParams(_VariablesParams):
    variables: dict[str, Bounded] = Field(min_length=1, description="joint variable (degrees) or voice parameter → "
                                                                  "the depth it swings either side")
    period: float = Field(2.0, gt=0, le=3600, description="seconds per cycle")


@ACTIONS.register
class Oscillate(_SkillPart):
    """Swing named variables sinusoidally by their depths (a central oscillator: WavesWorld,
    after Gallistel), over the course, while the tuple runs."""

    name = "oscillate"
    thesis = "blend based motor systems"
    Params = _OscillateParams

    def build(self, params, creature, name):
        depths = np.array(list(params.variables.values()), dtype=float)
        began = [0.0]
        layers = Variables(creature, name, list(params.variables),
                           lambda t: depths * math.sin(2.0 * math.pi * (t - began[0]) / params.period), params.blend)

        class OscillateAction(Action):
            def start(self, t, tuple_):
                began[0] = t
                layers.start(t, params.fade)

            def stop(self, t, *, interrupted):
                layers.stop(t)

        return OscillateAction(name)


class _ServoParams(_VariablesParams):
    variables: dict[str, tuple[Bounded, Bounded]] = Field(min_length=1, description="joint variable (degrees) or voice "
                                                                               "parameter → [offset at 0, offset at "
                                                                               "1] of the percept")
    percept: str = Field(description="the percept whose saliency sets the target")
    speed: float = Field(30.0, gt=0, le=1e6, description="units per second each variable moves at most")
    tolerance: float = Field(1.0, ge=0, le=1e6, description="how close counts as there")
    patience: float = Field(4.0, gt=0, le=3600, description="seconds to get within tolerance of a target before "
                                                            "giving up (done)")


@ACTIONS.register
class ServoVariables(_SkillPart):
    """Servo named variables toward a target a percept sets (negative feedback at a bounded
    speed), with patience: still off target ``patience`` seconds after it moved, it gives up
    (done; WavesWorld's servomechanism skill agents)."""

    name = "servo"
    thesis = "blend based motor systems"
    ends = True
    Params = _ServoParams
    refs = {"percept": "percepts"}

    def build(self, params, creature, name):
        ranges = np.array(list(params.variables.values()), dtype=float)
        servo = Servo(len(ranges), rate=params.speed, tolerance=params.tolerance, patience=params.patience)
        percept = creature.percept(params.percept)
        layers = Variables(creature, name, list(params.variables), servo.step, params.blend)

        class ServoAction(Action):
            said = False  # a percept that read NaN has been logged

            def start(self, t, tuple_):
                servo.patience, servo.gave_up = params.patience, False
                layers.start(t, params.fade)
                self.update(t)

            def update(self, t):
                u = percept.evaluate(t)
                if not math.isfinite(u):  # NaN passed the clamp below and every offset went NaN
                    if not self.said:
                        creature.world.emit("servo percept not finite", creature=creature.name, tuple=name,
                                            percept=params.percept)
                        self.said = True
                    return  # the servo keeps its last target
                u = min(max(u, 0.0), 1.0)
                servo.aim(ranges[:, 0] + u * (ranges[:, 1] - ranges[:, 0]), t)

            def stop(self, t, *, interrupted):
                layers.stop(t)

            def done(self, t):
                servo.step(t)
                return 1.0 if servo.gave_up else 0.0

        return ServoAction(name)


# -- adverbs and simple shaping -------------------------------------------------------------
class AdverbModel(FunctionPercept):
    """An Ac percept: a rolling Gaussian model with a prior over one adverb parameter
    (thesis "simple shaping"). The action samples ĥ from it when it starts; a reward for that
    activation pushes ĥ into the model with weight ``reward / full`` (at most 1), so rewarded
    values pull the mean toward themselves and the buffer's length sets the forgetting."""

    def __init__(self, name: str, model: GaussianModel, low: float, high: float, full: float) -> None:
        super().__init__(name, lambda t: 1.0)
        self.model, self.low, self.high, self.full = model, low, high, full

    def sample(self, rng: np.random.Generator) -> float:
        return min(max(self.model.sample(rng), self.low), self.high)

    def reinforce(self, value: float, reward: float) -> None:
        if reward > 0.0:
            self.model.update(value, min(reward / self.full, 1.0))


class _AdverbModelParams(Params):
    prior_mean: float = Field(0.0, ge=-1e6, le=1e6, description="where the adverb starts (the prior's mean)")
    prior_std: float = Field(0.35, gt=0, le=1e6, description="the prior's spread: how widely it explores (the "
                                                              "model never narrows below √prior_weight of it)")
    size: int = Field(4, ge=2, le=4096, description="the rolling buffer: rewards remembered (the plasticity)")
    prior_weight: float = Field(0.1, gt=0, le=1, description="how strongly the prior pulls back")
    range: tuple[float, float] = Field((0.0, 1.0), description="samples are clipped to [low, high]")
    full: float = Field(1.0, gt=0, le=1e6, description="a reward this large counts as one whole observation")


@PERCEPTS.register
class AdverbModelPart(PerceptPart):
    """An Ac percept over an adverb parameter: an ``adverb`` action naming it samples its value
    from it, and rewards shape it (thesis "simple shaping": "beg higher"). Always salient."""

    name = "adverb_model"
    thesis = "simple shaping"
    Params = _AdverbModelParams

    def build(self, params, creature, name):
        low, high = params.range
        if low >= high:
            raise ValueError(f"adverb_model {name!r}: range low {low} must be below high {high}")
        model = GaussianModel(params.prior_mean, params.prior_std, size=params.size, prior_weight=params.prior_weight)
        return AdverbModel(name, model, low, high, params.full)


class AdverbExample(Params):
    """One example animation of an ``adverb``: ``{ at, seconds, keys }``."""

    at: float = Field(ge=-1e6, le=1e6, description="its place on the adverb axis")
    seconds: float = Field(gt=0, le=600, description="how long one cycle of it lasts")
    keys: list[dict[str, float]] = Field(min_length=1, description="key frames, evenly spaced over the cycle, "
                                                                   "each joint variable → degrees (looped)")


class _AdverbParams(Params):
    examples: list[AdverbExample] = Field(min_length=2, description="example animations of one verb at "
                                                                     "points of the adverb axis")
    drive: str | None = Field(None, description="a drive whose level sets the adverb (re-read every cycle)")
    levels: tuple[float, float] = Field((0.0, 1.0), description="two different drive levels, mapped to the "
                                                                "first and last example's place")
    percept: str | None = Field(None, description="an 'adverb_model' percept the adverb is sampled from when "
                                                  "the tuple starts (and that rewards shape)")
    value: float | None = Field(None, ge=-1e6, le=1e6, description="a fixed adverb (neither drive nor percept), "
                                                   "within the examples' places")
    fade: float = Field(1.0, ge=0, le=60, description="seconds the layer eases in and out")
    blend: LayerSpec = blend_field()

    @model_validator(mode="after")
    def _one_source(self):
        _joint_variables(v for e in self.examples for key in e.keys for v in key)
        given = [k for k in ("drive", "percept", "value") if getattr(self, k) is not None]
        if len(given) != 1:
            raise ValueError(f"an adverb takes its value from exactly one of drive, percept or value (got {given or 'none'})")
        if len({e.at for e in self.examples}) != len(self.examples):
            raise ValueError("two examples at one place of the adverb axis")
        low, high = self.levels
        if self.drive is not None and low == high:
            raise ValueError(f"levels [{low:g}, {high:g}] map every level of drive {self.drive!r} to one place: give "
                             "two levels, the first example's and the last's")
        places = [e.at for e in self.examples]
        if self.value is not None and not min(places) <= self.value <= max(places):
            # beyond the examples the RBF weights extrapolate: at 3 over examples at 0 and 1 they
            # are −2 and 3, the cycle lasts 3 × its slow example less 2 × its quick one (at −3 it
            # lasted "1 µs", replayed every tick) and the joints turn 3× as far as any example
            raise ValueError(f"value {self.value:g} lies outside the examples' places [{min(places):g}, "
                             f"{max(places):g}]: an adverb blends between its examples")
        return self


@ACTIONS.register
class PlayAdverb(MotorPart):
    """Play a verb in the manner an adverb sets, over the course: an RBF blend of example
    animations in neutral time, looped, its adverb from a drive or an ``adverb_model`` Ac
    percept (whose model a reward for this tuple shapes)."""

    name = "adverb"
    thesis = "general layering – adverb parameters"
    Params = _AdverbParams
    refs = {"drive": "drives", "percept": "adverb models"}
    leaves_out_joints = True
    """On a body of files the stick figure's joints it names that the body lacks are left out
    (logged), not refused: a creature file written for the stick figure (exchange's bored
    manner) keeps its manner on a body of one's own. Any other joint it lacks is refused."""

    @classmethod
    def joints(cls, params):
        return list(dict.fromkeys(v.rpartition(".")[0] for e in params.examples for key in e.keys for v in key))

    @classmethod
    def turns(cls, params) -> dict[str, float]:
        """The most its examples' key frames ask of each joint (degrees; a blend between the
        examples, within their places, interpolates them)."""
        return asked_turns([key for e in params.examples for key in e.keys])

    def build(self, params, creature, name):
        body = creature.body
        variables = list(dict.fromkeys(v for e in params.examples for key in e.keys for v in key))
        missing = sorted({v for v in variables if v.rpartition(".")[0] not in body.skeleton.names})
        if missing:  # a creature file written for the stick figure, on a body of one's own (checked at
            # load for the shipped figures): the manner leaves those joints out, and the log says so
            creature.world.emit("layer joints missing", creature=creature.name, tuple=name, variables=missing)
            variables = [v for v in variables if v not in missing]
        offsets = JointOffsets(body, variables)
        examples = []
        for e in params.examples:
            frames = []
            for key in [*e.keys, e.keys[0]]:  # each example loops back to its first key
                offsets.degrees = np.array([key.get(v, 0.0) for v in variables])
                frames.append(offsets(0.0))
            times = np.linspace(0.0, e.seconds, len(frames))
            animation = PoseSet.animation(body.skeleton, np.array(frames), np.zeros((len(frames), 3)), times,
                                          f"{name}({e.at:g})")
            examples.append(Example(animation, (float(e.at),)))
        blend = AdverbBlend(examples)
        places = sorted(e.at for e in params.examples)
        percept = creature.percept(params.percept) if params.percept is not None else None
        return AdverbAction(name, creature, blend, offsets.mask, params, (places[0], places[-1]), percept)


class AdverbAction(Action):
    """An adverb played as a loop over the course (see :class:`PlayAdverb`)."""

    FPS = 20.0

    def __init__(self, name: str, creature: "Authored", blend: AdverbBlend, mask: np.ndarray, params,
                 places: tuple[float, float], percept: AdverbModel | None) -> None:
        super().__init__(name)
        self.creature, self.blend, self.mask, self.params = creature, blend, mask, params
        self.places, self.percept = places, percept
        self.sampled: float | None = None
        self.adverb = 0.0
        self._cycle_at, self._frames, self._length = -math.inf, np.empty((0, 0, 4)), 0.0

    def _value(self, t: float) -> float:
        """The adverb now, within the examples' places (a percept's sample too: its model's
        ``range`` may reach past them, and beyond the examples the blend extrapolates)."""
        p = self.params
        if p.drive is not None:
            low, high = p.levels
            u = (self.creature.level(p.drive, t) - low) / (high - low)  # two levels: checked at load
            return self.places[0] + min(max(u, 0.0), 1.0) * (self.places[1] - self.places[0])
        value = self.sampled if p.percept is not None else float(p.value)
        return min(max(value, self.places[0]), self.places[1])

    def _cycle(self, t: float) -> None:
        """A new cycle from ``t`` at the adverb's value now (not changed within a cycle: the
        thesis warns against moving through blend space faster than the animation)."""
        self.adverb = self._value(t)
        length = self.blend.duration(self.blend.weights([self.adverb]))
        times = np.linspace(0.0, length, max(2, int(math.ceil(length * self.FPS)) + 1))
        self._frames, _ = self.blend.sample([self.adverb], times)
        self._cycle_at, self._length = t, length

    def _source(self, t: float) -> np.ndarray:
        if t - self._cycle_at >= self._length:
            self._cycle(t)
        u = (t - self._cycle_at) / self._length * (len(self._frames) - 1)
        i = min(int(u), len(self._frames) - 2)
        return quat.slerp_rows(self._frames[i], self._frames[i + 1], min(u - i, 1.0))

    def start(self, t: float, tuple_: ActionTuple) -> None:
        if self.percept is not None:
            self.sampled = self.percept.sample(self.creature.rng)
        layers = self.creature.body.layers
        if layers is None or self.name not in layers.blend:  # restarted while still in: the cycle goes on
            self._cycle(t)
        self.creature.body.layer(self.params.blend.contribution(self.name, self._source, self.mask, self.params.fade), t)
        low, high = self.places
        clamped = {"sampled": self.sampled} if self.sampled is not None and not low <= self.sampled <= high else {}
        self.creature.world.emit("adverb", creature=self.creature.name, tuple=self.name, adverb=self.adverb,
                                 **clamped)

    def stop(self, t: float, *, interrupted: bool) -> None:
        self.creature.body.unlayer(self.name, t)

    def shape(self, reward: float) -> None:
        """A reward credited to this tuple: its last sample feeds the Ac percept's model."""
        if self.percept is not None and self.sampled is not None:
            self.percept.reinforce(self.sampled, reward)
