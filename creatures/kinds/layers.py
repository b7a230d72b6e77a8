"""Layers over a creature's course: the config side of :mod:`creatures.motor.blend`.

``[creature.body]`` names the layers an embodied kind's body blends over the course it follows
on the motor graph (thesis "general layering"; DESIGN.md "Several actions, one degree of
freedom"). The course is one ``mean`` contributor among others; each layer spec here builds
one :class:`~creatures.motor.blend.Contribution` from plain config data
(:meth:`BreatheSpec.contribution`), so any code holding such data (an authored creature's
body section, a test) instantiates the same layer the TOML key does. :class:`BodyLayers`
resolves them each tick and keeps the frame within the source's joint range and speed.
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Any, Literal

import numpy as np

from pydantic import BaseModel, Field, field_validator, model_validator

from creatures.bounds import FINITE
from creatures.config import nearest
from creatures.kinds.body_source import BodyMaterial, MaterialSpec
from creatures.motor import quaternion as quat
from creatures.motor.animations import creature_skeleton
from creatures.motor.blend import Blend, Contribution, Limits, Oscillator, Policy
from creatures.motor.graph import MotorGraph
from creatures.motor.material import MaterialError
from creatures.motor.pose import BodyPose

BREATHING_JOINTS = {"shoulder_l": (0.0, 0.0, 1.0), "shoulder_r": (0.0, 0.0, -1.0), "chest": (1.0, 0.0, 0.0)}
"""The shipped skeleton's breathing: both shoulders open (the elbows part: the rib cage a
mouth reads, thesis "soundcreatures") and the chest lifts."""


class LayerSpec(BaseModel):
    """``blend = {policy, weight, priority}`` on any layer (a skill, an adverb, the breath): how it
    counts among the others on the joints or voice parameters it drives (creatures/motor/blend.py).

    ``add`` (the default) composes the layer's turns over what is below, as an offset; ``budget``
    does so in falling ``priority`` within ``[creature.body] budget`` (IViHumans' truncated
    running sum); ``mean`` and ``exclusive`` take the layer's values as the joints' own rotations
    from rest (a voice parameter's as its rest value plus the offset): ``mean`` averages them with
    the course by ``weight``, ``exclusive`` holds the joints over everything below, the highest
    ``priority`` outright. ``weight`` scales the layer in every policy."""

    model_config = FINITE

    policy: Literal["add", "mean", "exclusive", "budget"] = Field("add", description="how the layer combines")
    weight: float = Field(1.0, ge=0, le=100, description="how much the layer counts (its mean weight; its "
                                                         "offset's scale)")
    priority: float = Field(0.0, ge=-1e6, le=1e6, description="order among exclusive layers (higher on top) "
                                                               "and budget layers (higher first)")

    @property
    def offsets(self) -> bool:
        """Whether the layer's values are offsets over what is below (``add``, ``budget``)."""
        return self.policy in ("add", "budget")

    def contribution(self, name: str, source, mask: np.ndarray | None, fade: float) -> Contribution:
        return Contribution(name, source, Policy[self.policy.upper()], weight=self.weight, priority=self.priority,
                            mask=mask, fade=fade)


def blend_field() -> Any:
    """The ``blend`` key of a layer's table, described once for every layer that has one."""
    return Field(LayerSpec(), description="{policy (add, budget, mean or exclusive), weight, priority}: "
                                          "how this layer counts among the others on the joints it drives "
                                          "(docs/authoring.md, 'Layers over the course')")


class BreatheSpec(BaseModel):
    """``[creature.body] breathe = {...}``: an oscillator over named joints, added over the course."""

    model_config = FINITE

    period: float = Field(4.0, gt=0, le=60, description="seconds per breath")
    depth: float = Field(0.0, ge=0, le=0.5, description="radians each breathing joint turns at the top of a "
                                                         "breath (0: no breathing layer)")
    fade: float = Field(1.0, ge=0, le=30, description="seconds the breathing eases in over (clock time)")
    blend: LayerSpec = blend_field()
    joints: dict[str, tuple[float, float, float]] = Field(
        default_factory=lambda: dict(BREATHING_JOINTS),
        description="joint name → axis (in the joint's frame) it turns about as the breath fills")

    @field_validator("joints")
    @classmethod
    def _nonzero_axes(cls, joints: dict[str, tuple[float, float, float]]) -> dict[str, tuple[float, float, float]]:
        for name, axis in joints.items():
            if not any(axis):
                raise ValueError(f"joint {name!r} needs a non-zero axis")
        return joints

    def check_joints(self, names: tuple[str, ...]) -> None:
        """Every breathing joint must be the body's (ValueError otherwise)."""
        for name in self.joints:
            if name not in names:
                raise ValueError(f"no joint {name!r} in the body{nearest(name, names, 'joints')}")

    def contribution(self, names: tuple[str, ...]) -> Contribution:
        """The breathing layer for a skeleton with joints ``names``: an ``add`` offset masked
        to the breathing joints."""
        breath = Oscillator(names, self.joints, period=self.period, depth=self.depth)
        return self.blend.contribution("breathe", breath, breath.mask, self.fade)


class BodySpec(MaterialSpec):
    """``[creature.body]``: a body of its own from files (no files: the shipped figure; docs/bodies.md) and layers over its course.

    The material keys are :class:`~creatures.kinds.body_source.MaterialSpec`'s; the layers are
    blended over the course the body follows on the motor graph."""

    breathe: BreatheSpec = BreatheSpec()
    budget: float | None = Field(None, gt=0, le=180, description="degrees each joint's budget layers share "
                                                                 "(blend.policy = \"budget\"; none: unbounded)")

    @model_validator(mode="after")
    def _budgeted(self) -> "BodySpec":
        if self.breathe.blend.policy == "budget" and self.budget is None:
            raise ValueError("breathe.blend.policy 'budget' shares each joint's budget: set budget (degrees)")
        return self

    @model_validator(mode="after")
    def _breathing_joints(self) -> "BodySpec":
        """The shipped figure's joints are known now; a body from files is checked when it loads
        (:meth:`resolve`), and only if it breathes."""
        if not self.custom:
            self.breathe.check_joints(creature_skeleton().names)
        return self

    def resolve(self, base: Path, *, ratios: bool = False) -> BodyMaterial:
        body = super().resolve(base, ratios=ratios)
        if self.breathe.depth > 0.0:
            try:
                self.breathe.check_joints(body.graph.skeleton.names)
            except ValueError as exc:
                raise MaterialError(str(exc), ("breathe", "joints")) from None
        return body

    def contributions(self, names: tuple[str, ...]) -> list[Contribution]:
        """The layers this spec asks for (none: the course alone drives the body, as before)."""
        return [self.breathe.contribution(names)] if self.breathe.depth > 0.0 else []


@functools.lru_cache(maxsize=2)
def source_limits(graph: MotorGraph) -> Limits:
    """The joint range and top speed of a graph's source material (what every blended frame
    keeps within; a skill's own joint limits are held inside them too)."""
    return Limits.of(graph.poses, graph.timing.max_speed)


def held_range(graph: MotorGraph, joint_limits: np.ndarray | None = None) -> np.ndarray:
    """Each joint's range (radians) a body's blended frames are held within: its source
    material's, narrowed by ``[creature.body] joint_limits`` (a body of files)."""
    held = source_limits(graph).range
    return held if joint_limits is None else np.minimum(held, joint_limits)


class BodyLayers:
    """The course plus layers, resolved per tick into the pose the body shows.

    The course (whatever the motor system samples) enters as the ``mean`` contributor
    ``"course"`` at weight 1; layers are started and stopped by name on clock time. Each
    frame is pulled within the source material's joint range and top speed
    (:class:`~creatures.motor.blend.Limits`), measured from the frame shown before.
    """

    def __init__(self, graph: MotorGraph, layers: list[Contribution], t: float = 0.0, *,
                 joint_limits: np.ndarray | None = None, budget: float | None = None) -> None:
        self.skeleton = graph.skeleton
        self.limits = Limits(held_range(graph, joint_limits), source_limits(graph).max_speed)
        self.blend = Blend(self.skeleton.joint_count, budget=np.inf if budget is None else np.radians(budget))
        self._course = quat.identity((self.skeleton.joint_count,))
        self.blend.start(Contribution("course", lambda _t: self._course, fade=0.0), t)
        for layer in layers:
            self.blend.start(layer, t)
        self._shown: BodyPose | None = None

    def start(self, layer: Contribution, t: float) -> Contribution:
        """Add a layer from ``t`` (an action's skill: a look, an adverb, a sweep)."""
        return self.blend.start(layer, t)

    def stop(self, name: str, t: float) -> None:
        """Ease the named layer out from ``t`` (dropped once faded)."""
        self.blend.stop(name, t)

    def shape(self, course: BodyPose, t: float) -> BodyPose:
        """The pose shown at ``t`` given the course's own pose there."""
        self._course = course.rotations
        previous = self._shown
        dt = 0.0 if previous is None else t - previous.time
        blended = self.blend.resolve(t)
        if previous is None or dt <= 0.0:
            rotations = self.limits.apply(blended, None if previous is None else previous.rotations, dt)
            velocities, positions = course.velocities, self.skeleton.forward_kinematics(rotations, course.root)
        else:
            rotations, velocities, positions = self.limits.frame(blended, previous.rotations, dt, self.skeleton,
                                                                 course.root)
        self._shown = BodyPose.made(rotations, velocities, course.root, positions, time=t, source="blend",
                                    labels=course.labels)
        return self._shown

