"""``[creature.body]``'s material keys: a body of one's own from files ("bring your own body").

Without these keys an embodied creature has the shipped 19-joint figure (three procedural
animations, fixed root), exactly as before. With ``animations`` (and optionally
``skeleton``) the body is built from BVH files, edited by ``graph_edits`` files, and its
motor graph is cached beside the config (:mod:`creatures.motor.body_build`). Paths are
relative to the config file that names them. The keys are documented field by field below
and in docs/bodies.md.
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import AfterValidator, BaseModel, Field, PrivateAttr, field_validator, model_validator

from creatures.bounds import FINITE
from creatures.config import nearest
from creatures.motor.body_build import Sources, load_or_build
from creatures.motor.graph import MotorGraph
from creatures.motor.line_metric import Content
from creatures.motor.material import Animation, Conventions, MaterialError, RootMode, read_clips


Degrees = Annotated[float, Field(ge=-3600, le=3600)]
"""A rotation-vector component of a rest pose, in degrees (ten turns either way at most)."""

FrameNumber = Annotated[int, Field(ge=0, le=1_000_000_000)]
"""A frame of a BVH file (0-based)."""


def _turn(limit: float) -> float:
    if not 0 < limit <= math.pi:
        raise ValueError("a limit is a turn from rest in (0, π] radians")
    return limit


JointLimit = Annotated[float, AfterValidator(_turn)]
"""A joint's largest turn from rest, checked where it is written: an error names the joint's own
key and line, not the whole [creature.body] table."""


class AnimationSpec(BaseModel):
    """One ``[[creature.body.animations]]`` table: a BVH take and the labels over its frames."""

    model_config = FINITE

    file: str = Field(description="BVH file, relative to the config")
    labels: dict[str, list[tuple[int, int]]] = Field(
        default_factory=dict, description="label → list of [first, last] frame ranges (inclusive, 0-based) "
                                          "carrying it, e.g. strike = [[40, 44]]")
    name: str | None = Field(None, min_length=1, description="source name the nodes carry (edit files say "
                                                             "name@frame); default the file's stem")
    step: int = Field(1, ge=1, le=1000, description="keep every step-th frame as a node (labelled first "
                                                    "frames are always kept)")
    frames: tuple[FrameNumber, FrameNumber] | None = Field(None, description="[first, last]: the take is these frames of the file "
                                                             "(inclusive, 0-based; labels and edits still count the "
                                                             "file's frames); default all")
    root: RootMode | None = Field(None, description="'fixed' (the root stays where the take begins), 'in place' "
                                                    "(moves as recorded, e.g. hips lowering to sit, but the creature "
                                                    "goes nowhere) or 'walk' (its horizontal travel moves the "
                                                    "creature on); default the body's root_motion: walk, else fixed")

    @field_validator("frames")
    @classmethod
    def _frames_in_order(cls, frames: tuple[int, int] | None) -> tuple[int, int] | None:
        if frames is not None and frames[0] > frames[1]:
            raise ValueError("give [first, last] with first <= last")
        return frames


MATERIAL_KEYS = ("skeleton", "animations", "clips", "graph_edits", "edits", "effectors", "joint_limits", "rest_labels", "rest_pose",
                 "scale", "up_axis", "root_motion", "neighbours", "cache")


class MaterialSpec(BaseModel):
    """The body's own material; all keys absent keeps the shipped figure."""

    model_config = FINITE

    skeleton: str | None = Field(None, description="skeleton file: a BVH file (its hierarchy) or skeleton JSON/TOML; "
                                                   "default the first animation's hierarchy")
    animations: list[AnimationSpec] = Field(default_factory=list, max_length=1024,
                                            description="BVH takes the motor graph is built from")
    clips: str | None = Field(None, description="a clips file (TOML, relative to the config): one BVH of many "
                                                "clips, [[clip]] name and frames (root_motion per clip) and "
                                                "[[label]] ranges, as installations/bodies/dog.labels.toml; "
                                                "its takes come before any animations")
    graph_edits: list[str] = Field(default_factory=list, max_length=256,
                                   description="motor-graph edit files (TOML, see docs/bodies.md), applied as "
                                               "one set: their order does not matter")
    edits: dict[str, list[dict[str, Any]]] = Field(
        default_factory=dict, description="edits written in the config itself, as in an edit file without "
                                          "its skeleton line: forbid, forge, reweight, favour, add, blend → "
                                          "list of tables (docs/bodies.md); merged with graph_edits")
    effectors: list[str] = Field(default_factory=list, max_length=64,
                                 description="joints that strike notes; the first is the one A* takes to a "
                                             "note (default: the skeleton's first end site)")
    joint_limits: dict[str, JointLimit] = Field(default_factory=dict,
                                           description="joint → largest turn from its rest orientation, radians "
                                                       "(0 < limit ≤ π); the body never shows more (nor more than "
                                                       "the source material does)")
    rest_labels: list[str] = Field(default_factory=list, max_length=64,
                                   description="labels of frames the body may rest in (low energy), besides "
                                               "frames found still")
    rest_pose: dict[str, tuple[Degrees, Degrees, Degrees]] | None = Field(
        None, description="a still pose to add for material without one: joint → rotation vector in degrees "
                          "(axis × angle, in the joint's parent frame); joints not named at rest")
    scale: float = Field(1.0, ge=1e-6, le=1e3, description="file units → metres (0.01 for centimetres)")
    up_axis: Literal["y", "z"] = Field("y", description="the files' up axis ('z' for z-up exports)")
    root_motion: bool = Field(False, description="the takes walk: each frame's horizontal step to the next moves "
                                                 "the creature on (its poses stand in place, height kept); false: "
                                                 "the root stays where each take begins")
    neighbours: int = Field(6, ge=1, le=64, description="nearest poses each node joins in the motor graph")
    metric: Content = Field(
        "rotations", description="what the motor graph measures between poses: 'rotations' (the joint angles) or "
                                 "'spline' (the line the body draws, for line bodies: curve's creatures, drawings; "
                                 "creatures/motor/line_metric.py)")
    cache: str = Field(".motor-cache", description="directory for the built motor graph, relative to the config "
                                                   "(rebuilt when any source changes)")

    _body: "BodyMaterial | None" = PrivateAttr(None)

    @property
    def custom(self) -> bool:
        """True when the body is built from files (its own, or a shipped figure's that these keys
        edit) rather than taken as a shipped figure's shared graph."""
        return bool(self.animations or self.clips)

    def shipped_clips(self) -> Path | None:
        """The clips file of the shipped figure these keys edit (none here: see FigureBodySpec)."""
        return None

    def default_effectors(self, graph: MotorGraph) -> tuple[str, ...]:
        """The striking joint when ``effectors`` names none: the skeleton's first end site."""
        return graph.skeleton.end_effectors[:1] or graph.skeleton.names[-1:]

    @model_validator(mode="after")
    def _needs_animations(self) -> "MaterialSpec":
        given = [k for k in MATERIAL_KEYS if k in self.model_fields_set and k not in ("cache", "neighbours")]
        if given and not self.custom:
            raise ValueError(f"{', '.join(given)} describe a body of its own, which needs animations "
                             "([[creature.body.animations]] with a BVH file) or clips; without them the shipped "
                             "figure is used")
        return self

    def resolve(self, base: Path, *, ratios: bool = False) -> "BodyMaterial":
        """Build (or load from cache) the body from files relative to ``base`` (``ratios``: on the
        exchange metric); MaterialError names the file (and line) and ``key`` the config key. Kept
        for :meth:`material`."""
        clips = self.shipped_clips() or (base / self.clips if self.clips else None)
        animations = (*(read_clips(clips) if clips else ()),
                      *(Animation(base / a.file, {k: tuple(map(tuple, v)) for k, v in a.labels.items()}, a.name, a.step,
                                  a.frames, a.root) for a in self.animations))
        sources = Sources(
            animations, skeleton=None if self.skeleton is None else base / self.skeleton,
            edits=tuple(base / p for p in self.graph_edits),
            conventions=Conventions(self.scale, self.up_axis, self.root_motion),
            rest=None if self.rest_pose is None else tuple(sorted(self.rest_pose.items())),
            rest_labels=tuple(self.rest_labels), neighbours=self.neighbours,
            inline=json.dumps(self.edits, sort_keys=True) if self.edits else "", inline_base=base, ratios=ratios,
            metric=self.metric)
        # One cache file per body as configured (its files and every key that shapes its graph,
        # not their contents: a changed take is rebuilt in place); two creatures on the same
        # takes with different edits each keep their own instead of rebuilding each other's.
        shaping = self.model_dump(mode="json", include={"skeleton", "animations", "clips", "graph_edits", "edits",
                                                        "scale", "up_axis", "root_motion", "rest_pose", "rest_labels",
                                                        "neighbours", "figure", "metric"})
        where = hashlib.sha256(json.dumps([str(base.resolve()), shaping, ratios], sort_keys=True).encode()).hexdigest()[:16]
        graph = load_or_build(sources, (base / self.cache / f"body-{where}.npz").resolve())
        names = graph.skeleton.names
        self._check_joints(names, self.joint_limits, "joint_limits")
        self._check_joints(names, dict.fromkeys(self.effectors), "effectors")
        effectors = tuple(self.effectors) or self.default_effectors(graph)
        limits = np.full(len(names), math.pi)
        for name, limit in self.joint_limits.items():
            limits[names.index(name)] = limit
        self._body = BodyMaterial(graph, effectors, limits)
        return self._body

    @staticmethod
    def _check_joints(names: tuple[str, ...], given: dict, key: str) -> None:
        for name in given:
            if name not in names:
                raise MaterialError(f"no joint {name!r} in the body{nearest(name, names, 'joints')}", (key, name))

    def material(self) -> "BodyMaterial":
        """The body resolved at config load (RuntimeError if it never was)."""
        if self._body is None:
            raise RuntimeError("[creature.body] names files but was not resolved against its config "
                               "(load the installation with creatures.runtime.schema.load_installation, "
                               "or call resolve(config_dir))")
        return self._body


@dataclass(frozen=True)
class BodyMaterial:
    """A body built from files: its motor graph, striking joints and per-joint limits (radians)."""

    graph: MotorGraph
    effectors: tuple[str, ...]
    limits: np.ndarray
