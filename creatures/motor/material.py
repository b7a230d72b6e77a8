"""A body's source material from files (thesis "re-editing animation data").

The thesis's creatures were built from an animator's takes, labelled, re-edited and
exported back. Here a body is a skeleton (a BVH hierarchy or the skeleton JSON/TOML of
:mod:`~creatures.motor.skeleton`) and any number of BVH animations, each with labels over
ranges of its frames, brought into the framework's conventions: y up, metres, and a fixed
root unless the body walks (``root_motion``). A rest pose can be added for material that
never stands still. The result is one :class:`~creatures.motor.pose.PoseSet` from which a
motor graph is built.

Every node keeps where it came from: its source (the animation's name) and its frame in
that file (``time / frame_time``), which is how graph edits name nodes
(:mod:`~creatures.motor.graph_edits`) without depending on node indices.

Errors are :class:`MaterialError`; the message names the file (and line where there is one),
and ``key`` says which config key it belongs to, so the installation loader can add the
config's own line.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from creatures.motor import quaternion as quat
from creatures.motor.bvh import BVHError, Take, read_bvh
from creatures.motor.drawing import is_drawing, read_drawing
from creatures.motor.pose import LOW_ENERGY, PoseSet
from creatures.motor.skeleton import Skeleton, SkeletonFileError

WALKING_FAVOUR = 0.1
"""Scale of the cost of a walking take's own frame-to-frame steps (a graph edit, thesis
"re-editing"). A gait's successive frames differ a lot (the legs swing), so the metric alone
would rather jump out of the walk and back; but only the source's own steps carry its travel,
and any other route moves the legs while the body stands still, which is foot sliding."""

REST_SOURCE = "rest"
"""Source name of the rest pose added for material without a still frame."""

UP = {"y": np.array([1.0, 0.0, 0.0, 0.0]), "z": quat.from_axis_angle(np.array([1.0, 0.0, 0.0]), -np.pi / 2)}
"""The turn that brings a file's up axis to the framework's +y (z-up files turn −90° about x)."""


class MaterialError(ValueError):
    """Source material that cannot make a body; ``key`` is the config key path it came from."""

    def __init__(self, message: str, key: tuple[str | int, ...] = ()) -> None:
        super().__init__(message)
        self.key = key


@dataclass(frozen=True)
class Animation:
    """One BVH take: ``labels`` maps a label to inclusive ``(first, last)`` frame ranges;
    ``step`` keeps every ``step``-th frame as a node (labelled frames are always kept)."""

    file: Path
    labels: dict[str, tuple[tuple[int, int], ...]] = field(default_factory=dict)
    name: str | None = None
    step: int = 1

    @property
    def source(self) -> str:
        return self.name or self.file.stem


@dataclass(frozen=True)
class Conventions:
    """How a file's numbers become the framework's: ``scale`` (file units → metres),
    ``up_axis`` and whether the root's recorded translation is kept (``root_motion``)."""

    scale: float = 1.0
    up_axis: str = "y"
    root_motion: bool = False


@dataclass
class Material:
    """Poses ready for a motor graph, with each source's seconds per file frame."""

    poses: PoseSet
    frame_times: dict[str, float]

    def frames(self) -> np.ndarray:
        """Each node's frame number in its own source file."""
        step = np.array([self.frame_times[s] for s in self.poses.sources])[self.poses.source_ids]
        return np.rint(self.poses.times / step).astype(np.int64)


def walking_in_place(poses: PoseSet) -> tuple[PoseSet, np.ndarray]:
    """Root motion taken out of the poses and kept as steps (thesis "graph-based motor systems":
    a node is a pose, wherever it was recorded): each node's horizontal step ``(N, 3)`` to its
    source successor (zero at a take's last frame), and the poses with their horizontal root
    where the first take began (height kept). A body then walks by adding the steps of the source
    steps it takes (:class:`~creatures.motor.root_motion.RootMotion`), so any route through the
    graph, and any jump between takes, starts from where the body stands instead of teleporting
    it to where the take was recorded."""
    from creatures.motor.metric import successors

    following = successors(poses)
    steps = np.zeros_like(poses.roots)
    walking = np.flatnonzero(following >= 0)
    for axis in (0, 2):
        steps[walking, axis] = poses.roots[following[walking], axis] - poses.roots[walking, axis]
    roots = poses.roots.copy()
    roots[:, [0, 2]] = poses.roots[0, [0, 2]]
    return PoseSet(poses.skeleton, poses.rotations, poses.velocities, roots, poses.times, poses.source_ids,
                   list(poses.sources), list(poses.labels)), steps


def fingerprint(skeleton: Skeleton) -> str:
    """Short hash of a skeleton's joint names and parents: edit files carry it, so one
    written for another body is refused rather than applied to the wrong joints."""
    text = ";".join(f"{n}<{p}" for n, p in zip(skeleton.names, skeleton.parents.tolist()))
    return hashlib.sha256(text.encode()).hexdigest()[:12]


def load_skeleton(path: Path, conventions: Conventions) -> Skeleton:
    """A skeleton from a BVH file (its hierarchy) or a skeleton JSON/TOML file, in metres, y up."""
    try:
        if is_drawing(path):
            skeleton = read_drawing(path).skeleton
        else:
            skeleton = read_bvh(path).skeleton if path.suffix.lower() == ".bvh" else Skeleton.load(path)
    except (BVHError, SkeletonFileError) as exc:
        raise MaterialError(str(exc), ("skeleton",)) from None
    return convert_skeleton(skeleton, conventions)


def convert_skeleton(skeleton: Skeleton, conventions: Conventions) -> Skeleton:
    offsets = skeleton.offsets * conventions.scale
    offsets[skeleton.parents < 0] = quat.rotate(UP[conventions.up_axis], offsets[skeleton.parents < 0])
    return Skeleton(skeleton.names, skeleton.parents, offsets, skeleton.masses, skeleton.end_effectors)


def read_take(animation: Animation, key: tuple[str | int, ...] = ()) -> Take:
    """The take's file as parsed (its own skeleton and frames): a BVH file, or a drawing
    (:mod:`creatures.motor.drawing`); MaterialError at ``key``."""
    try:
        return read_drawing(animation.file) if is_drawing(animation.file) else read_bvh(animation.file)
    except BVHError as exc:
        raise MaterialError(str(exc), (*key, "file")) from None


def read_animation(animation: Animation, skeleton: Skeleton, conventions: Conventions, *,
                   key: tuple[str | int, ...] = (), parsed: Take | None = None) -> tuple[PoseSet, float]:
    """One take as poses on ``skeleton`` (joints matched by name) and its frame time
    (``parsed``: the file already read, e.g. for its skeleton).

    The file's hierarchy must be the skeleton's: the same joints with the same parents
    (offsets come from the skeleton). Labels must name frames the file has.
    """
    take = read_take(animation, key) if parsed is None else parsed
    names = take.skeleton.names
    if set(names) != set(skeleton.names):
        missing = sorted(set(skeleton.names) - set(names))
        extra = sorted(set(names) - set(skeleton.names))
        raise MaterialError(f"{animation.file}: hierarchy is not the body's skeleton (missing joints: "
                            f"{', '.join(missing) or 'none'}; unknown joints: {', '.join(extra) or 'none'})",
                            (*key, "file"))
    order = np.array([names.index(n) for n in skeleton.names])
    for j, name in enumerate(skeleton.names):
        mine = skeleton.parents[j]
        theirs = take.skeleton.parents[order[j]]
        if (mine < 0) != (theirs < 0) or (mine >= 0 and names[theirs] != skeleton.names[mine]):
            parent = "none" if theirs < 0 else names[theirs]
            raise MaterialError(f"{animation.file}: joint {name!r} has parent {parent!r} here, not the skeleton's",
                                (*key, "file"))
    count = len(take)
    frame_time = take.frame_time
    kept = set(range(0, count, animation.step))
    labels: list[set[str]] = [set() for _ in range(count)]
    for label, ranges in animation.labels.items():
        for first, last in ranges:
            if not 0 <= first <= last < count:
                raise MaterialError(f"label {label!r} covers frames {first}..{last}, but {animation.file} has "
                                    f"frames 0..{count - 1}", (*key, "labels", label))
            kept.add(first)
            for frame in range(first, last + 1):
                labels[frame].add(label)
    frames = np.array(sorted(kept))
    rotations = take.rotations[frames][:, order]
    roots = take.roots[frames] * conventions.scale
    up = UP[conventions.up_axis]
    root = np.flatnonzero(skeleton.parents < 0)
    rotations[:, root] = quat.multiply(up, rotations[:, root])
    roots = quat.rotate(up, roots)
    if not conventions.root_motion:
        roots = np.broadcast_to(roots[0], roots.shape).copy()  # the body stands where its take began
    poses = PoseSet.animation(skeleton, rotations, roots, frames * frame_time, animation.source,
                              [frozenset(labels[f]) for f in frames])
    return poses, frame_time


def rest_pose(skeleton: Skeleton, turns: dict[str, tuple[float, float, float]], root: np.ndarray,
              labels: frozenset[str]) -> PoseSet:
    """A still pose from ``joint → rotation vector in degrees`` (joints not named at rest),
    labelled low energy: the place to rest for material that never stands still."""
    rotations = quat.identity((1, skeleton.joint_count))
    for name, vector in turns.items():
        if name not in skeleton.names:
            raise MaterialError(f"no joint {name!r} in the body (joints: {', '.join(skeleton.names)})",
                                ("rest_pose", name))
        xyzw = Rotation.from_rotvec(np.radians(vector)).as_quat()
        rotations[0, skeleton.index(name)] = xyzw[[3, 0, 1, 2]]
    return PoseSet.animation(skeleton, rotations, root[None], np.zeros(1), REST_SOURCE, [labels | {LOW_ENERGY}])


def load_material(skeleton: Skeleton, animations: list[Animation], conventions: Conventions, *,
                  rest: dict[str, tuple[float, float, float]] | None = None,
                  rest_labels: tuple[str, ...] = (), first: Take | None = None) -> Material:
    """Every take (and the rest pose) on one skeleton; sources named twice are refused.
    ``first``: the first take's file, already parsed."""
    sets: list[PoseSet] = []
    frame_times: dict[str, float] = {}
    for i, animation in enumerate(animations):
        if animation.source in frame_times or animation.source == REST_SOURCE:
            raise MaterialError(f"two animations are named {animation.source!r} (give one a 'name')",
                                ("animations", i, "name"))
        poses, frame_times[animation.source] = read_animation(animation, skeleton, conventions,
                                                              key=("animations", i), parsed=first if i == 0 else None)
        sets.append(poses)
    if rest is not None:
        first = sets[0].roots[0] if sets else np.zeros(3)
        sets.append(rest_pose(skeleton, rest, first, frozenset(rest_labels[:1])))
        frame_times[REST_SOURCE] = 1.0
    if not sets:
        raise MaterialError("a body needs at least one animation", ("animations",))
    return Material(PoseSet.concatenate(sets), frame_times)
