"""Parts several creature kinds share: a scanned-string voice and a body on a motor graph.

Kinds compose these rather than inherit them (no framework inside the framework): a kind
that sings has a :class:`Voice`, a kind that moves has a :class:`Body`.
"""

from __future__ import annotations

import functools
import math
from typing import Literal

import numpy as np
from pydantic import BaseModel, Field, model_validator

from audio.coupling import BodyCoupling, BodyShape
from audio.flow import FlowCoupling
from audio.lowpass import LowPass
from audio.scanned import GESTURAL_LIMIT_HZ, StringParameters, UnstableStringError, soft_limit
from audio.voices import VoicePool
from creatures.bounds import FINITE
from creatures.kinds.figures import EFFECTORS, Figure, figure_graph
from creatures.kinds.layers import BodyLayers, BodySpec
from creatures.motor.blend import Contribution
from creatures.motor import quaternion as quat
from creatures.motor.animations import example_animations
from creatures.motor.graph import MotorGraph
from creatures.motor.line_metric import Content
from creatures.motor.metric import MetricWeights
from creatures.motor.note_space import exchange_metric
from creatures.motor.pose import BodyPose, PoseSet
from creatures.motor.playback import Playback
from creatures.motor.programs import MotorSystem
from creatures.motor.root_motion import RootMotion
from creatures.motor.search import PathFinder


class VoiceSpec(BaseModel):
    """``[creature.voice]``: the scanned strings a creature sings with (checked for stability).

    Every string the config accepts is stable (the integrator's bound, checked by
    :class:`audio.scanned.StringParameters`) and gestural: physics at a haptic rate of
    100–1000 Hz and no mode above :data:`audio.scanned.GESTURAL_LIMIT_HZ` (thesis figure 47:
    "lower than 10-15Hz"), so the body moves the string at the speed the string moves.
    """

    model_config = FINITE

    voices: int = Field(6, ge=1, le=32, description="polyphony (strings)")
    masses: int = Field(64, ge=1, le=1024, description="masses per string")
    mass: float = Field(1.0, gt=0, le=1e6, description="mass of each node of the string")
    stiffness: float = Field(800.0, ge=0, le=1e12, description="spring between neighbouring masses")
    centring: float = Field(4.0, ge=0, le=1e12, description="spring of each mass to rest")
    damping: float = Field(0.5, ge=0, le=1e12, description="velocity damping: up to the string's critical "
                                                           "damping, 2·√(mass·(centring + stiffness·π²/(masses + "
                                                           "1)²)) (4.8 with the defaults), more ends a note sooner; "
                                                           "past it the string creeps back and its shape, the timbre "
                                                           "the scan reads, holds longer (from 0.5 to 1 s after a "
                                                           "pluck the defaults' sound falls 65% at damping 5, 20% "
                                                           "at 50, 6% at 500)")
    haptic_rate: float = Field(500.0, ge=100, le=1000, description="string physics updates per second")
    release: float = Field(0.2, gt=0, le=10, description="fade after note-off, seconds")
    gain: float = Field(0.3, ge=0, le=4, description="output gain of the strings before the limiter")
    body_gain: float = Field(40.0, ge=0, le=1e4, description="force per unit joint velocity pushing the strings")
    flow: bool = Field(False, description="limbs push the strings through a motion flow field (movement spreads "
                                          "and reaches farther strings later) instead of directly (thesis, "
                                          "'artificial gestural control', the first connection)")
    body_shape: float = Field(0.0, ge=0, le=1e3, description="the body as the string: each string held in the "
                                                           "shape of the body's line (root to effector) × this, "
                                                           "through a spring; 0 = off (thesis, 'artificial gestural "
                                                           "control', the second connection)")
    bright_hz: float | None = Field(None, ge=20, le=20_000, description="a low-pass on the strings' sound at "
                                                                       "this cutoff (Hz), which a skill's "
                                                                       "voice.cutoff scales (a timbre that follows "
                                                                       "a drive: thesis 'sand:stone'); none: no "
                                                                       "filter")
    interpolation: Literal["linear", "none"] = Field(
        "linear", description="how the scan reads the string: linear between masses and physics frames "
        "(smooth, like Csound's scans; band-limited, see audio.sample_rate) or none, the nearest mass of the "
        "latest frame (brighter and stepped at the haptic rate, like Csound's scantable, and like it not "
        "band-limited: a high note aliases)")

    @model_validator(mode="after")
    def _stable_and_gestural(self) -> "VoiceSpec":
        parameters = self.parameters()  # raises UnstableStringError (a ValueError) naming the bound
        if parameters.highest_mode_hz > GESTURAL_LIMIT_HZ:
            most = parameters.stiffness_for_highest_mode(GESTURAL_LIMIT_HZ)
            advice = (f"use stiffness ≤ {_round_down(most):g}" if most >= 0 else
                      f"use centring ≤ {_round_down(4.0 * most + self.centring):g} and stiffness 0")
            raise ValueError(
                f"stiffness {self.stiffness:g} with centring {self.centring:g} and mass {self.mass:g} puts the "
                f"string's highest mode at {parameters.highest_mode_hz:.3g} Hz, above the gestural limit of "
                f"{GESTURAL_LIMIT_HZ:g} Hz: {advice}, or a larger mass"
            )
        return self

    def parameters(self) -> StringParameters:
        return StringParameters(n_masses=self.masses, mass=self.mass, stiffness=self.stiffness,
                                centring=self.centring, damping=self.damping, haptic_rate=self.haptic_rate,
                                interpolation=self.interpolation)


VOICE_READ_ONCE = {
    f"voice.{name}": "[creature.voice] is built at the first audio block: its strings keep what they were built "
                     "from, but for voice.gain, which changes at once (change the config and restart the run)"
    for name in VoiceSpec.model_fields if name != "gain"}
"""``READ_ONCE`` entries of a kind with a :class:`Voice`: each key of ``[creature.voice]`` but
``gain`` (:meth:`Voice.render` takes it each block) is built into its strings."""


def _round_down(value: float, digits: int = 4) -> float:
    """``value`` cut to ``digits`` significant figures, rounding down: an advised upper bound
    that, typed back into the config, is itself accepted."""
    if value <= 0.0:
        return 0.0
    scale = 10.0 ** (digits - 1 - math.floor(math.log10(value)))
    return math.floor(value * scale) / scale


def _fall_due(items: list[tuple], t: float) -> tuple[list[tuple], list[tuple]]:
    """``items`` (each timed by its first field) split into those due by ``t`` and the rest."""
    due = [item for item in items if item[0] <= t]
    return due, [item for item in items if item[0] > t] if due else items


class Voice:
    """A creature's scanned strings: notes start them, the body pushes them, a limiter ends them."""

    def __init__(self, spec: VoiceSpec, sample_rate: int, block_size: int = 4096) -> None:
        try:
            parameters = spec.parameters()
        except UnstableStringError as exc:  # validated already; kept for direct construction
            raise ValueError(str(exc)) from None
        self.spec = spec
        self.pool = VoicePool(spec.voices, parameters, sample_rate=sample_rate, release=spec.release,
                              block_size=block_size)
        self._strings, self._tuning = parameters, (1.0, 1.0)
        self.sample_rate = sample_rate
        self._ends: list[tuple[float, int, float]] = []  # (end, voice, its note's stamp in the pool)
        self._starts: list[tuple[float, int, int, float]] = []  # (start, pitch, velocity, end), not yet sounding
        self.coupling: BodyCoupling | None = None
        self.shape: BodyShape | None = None
        self.lowpass = LowPass(sample_rate) if spec.bright_hz is not None else None

    def couple(self, node_positions: np.ndarray, joints: list[int]) -> None:
        """Lay the strings in space at ``node_positions`` so ``joints`` moving nearby push them."""
        kind = FlowCoupling if self.spec.flow else BodyCoupling
        self.coupling = kind(node_positions, radius=0.25, gain=self.spec.body_gain, joints=joints)

    def play(self, pitch: int, velocity: int, end: float, *, start: float | None = None) -> None:
        """Sound ``pitch`` until clock time ``end``: at once, or from ``start`` (a note handed
        over ahead of its time starts in the block that reaches it, not when it was handed over)."""
        if start is None:
            index = self.pool.note_on(pitch, velocity / 127.0)
            self._ends.append((end, index, self.pool.started[index]))  # this note's end, not its pitch's
        else:
            self._starts.append((start, pitch, velocity, end))

    def shape_as(self, joints: list[int]) -> None:
        """Hold the strings in the shape of the body's line through ``joints`` (:class:`BodyShape`)."""
        self.shape = BodyShape(joints, self.spec.masses, gain=self.spec.body_shape, centring=self.spec.centring)

    def feel(self, pose: BodyPose, *, push: float = 1.0, own: BodyPose | None = None) -> None:
        """Push every sounding string with the movement since the last pose, ``push`` times as
        hard (a skill's ``voice.push``), and hold it in the shape of the body (``own``, when the
        pushing ``pose`` holds other bodies too: curve's room), when the voice is the body."""
        if self.coupling is None and self.shape is None:
            return
        force = self.coupling.forces(pose) * push if self.coupling is not None else np.zeros(self.spec.masses)
        if self.shape is not None:
            force = force + self.shape.forces(pose if own is None else own)
        if force.any():
            self.pool.bank.push(np.flatnonzero(self.pool.pitch >= 0), force)

    def retune(self, tension: float, damping: float) -> None:
        """The strings' stiffness × ``tension`` and damping × ``damping`` from the next block
        (a skill's ``voice.tension`` and ``voice.damping``), within the bounds the config is held
        to (:meth:`audio.scanned.StringParameters.retuned`)."""
        if (tension, damping) != self._tuning:
            self._tuning = (tension, damping)
            self.pool.bank.parameters = self._strings.retuned(tension, damping)

    def render(self, out: np.ndarray, t: float, *, cutoff: float = 1.0, gain: float | None = None) -> None:
        """Fill ``out`` with the voice up to clock time ``t`` (note-offs that fell due first),
        through the ``bright_hz`` low-pass at ``cutoff`` × its cutoff (a skill's ``voice.cutoff``),
        at ``gain``: the creature's ``voice.gain`` as its spec says now (a console ``set`` or a
        zone changes it; the strings were built from the spec of their first block), else the
        built spec's."""
        due, self._ends = _fall_due(self._ends, t)
        for _, index, started in due:
            self.pool.release(index, started)
        starting, self._starts = _fall_due(self._starts, t)  # after the note-offs: each sounds a block at least
        for _, pitch, velocity, end in starting:
            self.play(pitch, velocity, end)
        if not self.pool.active and (self.lowpass is None or self.lowpass.resting):
            out[:] = 0.0  # most of a colony's voices are silent most ticks: nothing to render, filter or limit
            return
        self.pool.render(out)
        if self.lowpass is not None:
            out[:] = self.lowpass.run(out, self.spec.bright_hz * cutoff)  # (a silent block costs nothing)
        out *= self.spec.gain if gain is None else gain
        soft_limit(out, out=out)


def couple_to_hands(voice: Voice, body: "Body") -> None:
    """Lay a voice's strings along the diagonal of the box the effector reaches, pushed by both
    hands (so striking and reaching visibly shake what sounds); a figure without a left hand
    pushes them with its effector alone."""
    reach = body.reach()
    low, high = reach.min(axis=0), reach.max(axis=0)
    line = np.linspace(0.0, 1.0, voice.spec.masses)[:, None]
    voice.couple(low + line * (high - low), body.touching)
    if voice.spec.body_shape > 0:
        voice.shape_as(body.line())


@functools.lru_cache(maxsize=1)
def shared_material() -> PoseSet:
    """The shipped source animations (sway, reach, strike) as one pose set."""
    return PoseSet.concatenate(example_animations())


@functools.lru_cache(maxsize=4)
def shared_graph(ratios: bool = False, metric: Content = "rotations") -> MotorGraph:
    """One motor graph per process (and per metric), built once from the shipped animations
    (read-only). ``ratios`` builds it with the *exchange* metric, whose time term favours
    jumps at low-integer ratios of the source animation's length (thesis "exchange");
    ``metric = "spline"`` measures the poses as the lines they draw (curve's creatures)."""
    weights = MetricWeights(content=metric)
    graph = MotorGraph.build(shared_material(), k=6, weights=exchange_metric(weights) if ratios else weights)
    graph.annotate_low_energy()
    return graph


BODY_RATE = 60.0
"""Poses per second sampled along a course (interpolation finer than any tick)."""

BODY_BLOCK = 8
"""Samples of a course computed together, when a tick first looks among them."""


class _Trajectory:
    """A course sampled on a :data:`BODY_RATE` grid, a block of :data:`BODY_BLOCK` samples
    at a time (squad + forward kinematics vectorised over the block), so a tick only looks
    a pose up. Blocks are computed where a tick first looks: a 0.04 s tick looks at most
    of them, a 0.5 s tick at one in four, and a course replaced half-way never pays for
    the rest. Sample ``i`` moves at the turn from ``i`` to ``i + 1`` (the last at the turn
    into it), whichever block computed it."""

    STEP = 1.0 / BODY_RATE

    def __init__(self, playback: Playback, skeleton, travel: RootMotion | None = None,
                 offset: np.ndarray | None = None) -> None:
        self.start = float(playback.key_times[0])
        self.count = int(np.ceil((playback.end_time - self.start) / self.STEP)) + 2
        self.playback = playback
        self.skeleton = skeleton
        self.offset = np.zeros(3) if offset is None else offset
        self._travel = None
        if travel is not None:  # where the body has walked to at each key, from where this course began
            start = playback.path.start
            self._travel = self.offset + travel.along(start.node, playback.key_nodes,
                                                      start.fraction if start.next is not None else 0.0)
        self._blocks: dict[int, tuple[int, np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = {}

    def travel(self, t: float) -> np.ndarray:
        """The body's walked offset at ``t`` (linear between keys, like the root)."""
        if self._travel is None:
            return self.offset
        times = self.playback.key_times
        return np.array([np.interp(t, times, self._travel[:, c]) for c in range(3)])

    def _block(self, block: int) -> tuple[int, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(first, rotations, velocities, roots, positions)`` of samples ``first`` onwards
        covering the block (one sample before it when the block holds only the last)."""
        if block not in self._blocks:
            first = min(block * BODY_BLOCK, self.count - 2)
            indices = np.arange(first, min((block + 1) * BODY_BLOCK, self.count - 1) + 1)
            times = self.start + self.STEP * indices
            rotations, roots = self.playback.sample_rotations(times)
            if self._travel is not None:
                roots = roots + np.stack([np.interp(times, self.playback.key_times, self._travel[:, c])
                                          for c in range(3)], axis=1)
            elif self.offset.any():
                roots = roots + self.offset
            turn = quat.log(quat.multiply(rotations[1:], quat.conjugate(rotations[:-1]))) / self.STEP
            velocities = np.concatenate((turn, turn[-1:])) if indices[-1] == self.count - 1 else turn
            positions = self.skeleton.forward_kinematics(rotations, roots)
            self._blocks[block] = (first, rotations, velocities, roots, positions)
        return self._blocks[block]

    def pose(self, t: float) -> BodyPose:
        i = min(max(int(round((t - self.start) * BODY_RATE)), 0), self.count - 1)
        first, rotations, velocities, roots, positions = self._block(i // BODY_BLOCK)
        k = i - first
        return BodyPose(rotations[k], velocities[k], roots[k], time=t, source="playback", positions=positions[k])


class Body:
    """A creature's body on a motor graph, with its own position and course.

    ``figure`` picks a shipped body (:mod:`creatures.kinds.figures`: the stick figure, the dog,
    the bird); ``effector`` defaults to the joint that figure strikes notes with. A figure with
    root motion walks: the offset it has travelled is kept across courses. When ``spec``
    (``[creature.body]``) names files, the body is built from them at config load instead
    (:class:`~creatures.kinds.body_source.MaterialSpec`: its effectors strike, and its joint
    limits always hold, so such a body is always layered, as are the dog and the bird). With
    layers in ``spec`` the course is one contributor among them (:class:`~creatures.kinds.layers.BodyLayers`); without, the
    course alone is the pose.
    """

    def __init__(self, rng: np.random.Generator, *, effector: str | None = None, ratios: bool = False,
                 spec: BodySpec | None = None, figure: Figure = "stick") -> None:
        spec = spec or BodySpec()
        own = spec.material() if spec.custom else None
        self.figure = figure
        self.graph = figure_graph(figure, ratios, spec.metric) if own is None else own.graph
        self.finder = PathFinder(self.graph)
        self.finder.prepare()  # its landmark tables (~10 ms) before the first tick, not in it
        self._owns_graph = False  # the figure's graph is shared until an edit (own_graph)
        self._budget = spec.budget  # [creature.body] budget, for layers made later (layer)
        start = int(rng.integers(len(self.graph)))
        self.motor = MotorSystem(self.graph, start=start, finder=self.finder)
        self.effectors = (effector or EFFECTORS[figure],) if own is None else own.effectors
        self.effector = self.effectors[0]
        self.skeleton = self.graph.skeleton
        self.effector_index = self.skeleton.names.index(self.effector)
        self._striking = [self.skeleton.names.index(name) for name in self.effectors]
        # The joints that push the voice's strings: the figure's free hand (if it has one) and
        # its effector, or every effector of a body of one's own.
        pushing = (("hand_l",) if "hand_l" in self.skeleton.names else ()) + self.effectors if own is None else own.effectors
        self.touching = [self.skeleton.index(name) for name in dict.fromkeys(pushing)]
        self.root_motion = RootMotion.of(self.graph)
        self.travelled = np.zeros(3)
        """Where root motion had taken the body when its last course began or ended."""
        self.offset = np.zeros(3)
        """Where root motion has taken the pose shown now: the world offset of the body's own
        frame, in which its graph, its reach and the notes in its space are laid out."""
        self._trajectory: _Trajectory | None = None
        self._pose: BodyPose = self._rest_pose(start, 0.0)
        layers = spec.contributions(self.skeleton.names)
        if own is not None:
            self.layers: BodyLayers | None = BodyLayers(self.graph, layers, joint_limits=own.limits, budget=spec.budget)
        elif layers or figure != "stick":
            # The generated bodies are held to their source's range and top speed as a body from
            # files is: a squad curve between two keys overshot a knee by 3 mrad in a hop.
            self.layers = BodyLayers(self.graph, layers, budget=spec.budget)
        else:
            self.layers = None

    def own_graph(self) -> MotorGraph:
        """The body's graph made its own before an edit (complex shaping dispatches new
        material into it): the figure's graph is shared by every body of that figure."""
        if not self._owns_graph:
            self.graph = self.graph.copy()
            self.finder = PathFinder(self.graph)
            self.motor.graph, self.motor.finder = self.graph, self.finder
            if self.motor.playback is not None:
                self.motor.playback.graph = self.graph
            self._owns_graph = True
        return self.graph

    def _rest_pose(self, node: int, t: float) -> BodyPose:
        poses = self.graph.poses
        return BodyPose(poses.rotations[node], np.zeros_like(poses.velocities[node]), poses.roots[node] + self.travelled,
                        time=t, source="rest", labels=poses.labels[node],
                        positions=poses.positions[node] + self.travelled)

    def update(self, t: float) -> BodyPose:
        """Advance the body to clock time ``t`` and return the pose there."""
        self.motor.arrived(t)
        playback = self.motor.playback
        if playback is None:
            if self._trajectory is not None:
                self.travelled = self._trajectory.travel(t)
            self._trajectory = None
            self._pose = self._rest_pose(self.motor.position(t).node, t)
        else:
            if self._trajectory is None or self._trajectory.playback is not playback:
                if self._trajectory is not None:  # a course replaced mid-way walks on from where it was
                    # when it was replaced (the new course's start), not at this tick: the old
                    # course's keys walked on past it, and the paws planted there slid with it
                    self.travelled = self._trajectory.travel(float(playback.key_times[0]))
                self._trajectory = _Trajectory(playback, self.skeleton, self.root_motion, self.travelled.copy())
            self._pose = self._trajectory.pose(t)
        self.offset = self.travelled if self._trajectory is None else self._trajectory.travel(t)
        if self.layers is not None:
            self._pose = self.layers.shape(self._pose, t)
        return self._pose

    @property
    def pose(self) -> BodyPose:
        return self._pose

    def layer(self, contribution: Contribution, t: float) -> Contribution:
        """Blend ``contribution`` over the course from ``t``: an action's layer (a look, an
        adverb, a sweep; creatures/authored/skills.py). A body without layers gets them now,
        so one that never layers anything pays nothing for blending."""
        if self.layers is None:
            self.layers = BodyLayers(self.graph, [], t, budget=self._budget)
        return self.layers.start(contribution, t)

    def unlayer(self, name: str, t: float) -> None:
        """Ease the named layer out from ``t``."""
        if self.layers is not None:
            self.layers.stop(name, t)

    def hand(self) -> np.ndarray:
        return self._pose.positions[self.effector_index]

    def strikers_in_place(self) -> np.ndarray:
        """Every striking joint (``[creature.body] effectors``; the first is the one A* takes to
        a note) in the body's own frame (where :meth:`reach` and its notes are), ``(E, 3)``: any
        of them passing a note strikes it."""
        return self._pose.positions[self._striking] - self.offset

    def line(self) -> list[int]:
        """The body's line: joints from the root to the effector (a drawn body: all of it)."""
        chain = [self.effector_index]
        while self.skeleton.parents[chain[-1]] >= 0:
            chain.append(int(self.skeleton.parents[chain[-1]]))
        return chain[::-1]

    def reach(self) -> np.ndarray:
        """Every place the effector can be in the source material ``(N, 3)``."""
        return self.graph.poses.positions[:, self.effector_index]
