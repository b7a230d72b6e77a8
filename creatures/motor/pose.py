"""BodyPose, the node of the motor graph (thesis "graph-based motor systems", p. 123).

Each BodyPose holds what the thesis lists: a complete set of joint angles (unit
quaternions, the key-frames interpolated at run time), joint velocities (for the
closest-transit term and higher-order interpolation), a time and source label (so timing
between key-frames can be recaptured from the source animation), and optional labels plus
precalculated world-space joint positions (for end-effector goals such as "get my hand to
that note"). A line body's poses also carry the lines they draw (:attr:`PoseSet.lines`: 3-D
splines and how they move, thesis "curve (technology)"), which its metric measures instead of
the joint angles.

:class:`PoseSet` is the same data for many poses stacked into arrays, which is what the
metric, the graph and A* work on.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import Sequence

import numpy as np

from creatures.motor import quaternion as quat
from creatures.motor.skeleton import Skeleton
from creatures.motor.spline import LineShapes

LOW_ENERGY = "low energy"
"""Label of poses the body can rest in (thesis "enforcing physical constraints")."""


@dataclass(eq=False)
class BodyPose:
    """One key-frame of a body: rotations, angular velocities, root, timing and labels.

    ``velocities`` are angular velocities (radians per second, rotation vectors in the
    parent frame): over a short ``dt`` a joint moves to ``exp(ω dt) q``. ``positions`` is
    filled by forward kinematics when omitted (then ``skeleton`` is required).
    """

    rotations: np.ndarray
    velocities: np.ndarray
    root: np.ndarray
    time: float = 0.0
    source: str = ""
    labels: frozenset[str] = frozenset()
    positions: np.ndarray | None = None
    skeleton: Skeleton | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        self.rotations = quat.normalize(self.rotations)
        self.velocities = np.asarray(self.velocities, dtype=float)
        self.root = np.asarray(self.root, dtype=float)
        self.labels = frozenset(self.labels)
        joints = self.rotations.shape[0]
        if self.rotations.shape != (joints, 4) or self.velocities.shape != (joints, 3):
            raise ValueError(
                f"BodyPose needs rotations (J,4) and velocities (J,3);"
                f" got {self.rotations.shape} and {self.velocities.shape}"
            )
        if self.skeleton is not None and self.skeleton.joint_count != joints:
            raise ValueError(f"pose has {joints} joints, skeleton has {self.skeleton.joint_count}")
        if self.positions is None:
            if self.skeleton is None:
                raise ValueError("BodyPose needs either precomputed positions or a skeleton")
            self.positions = self.skeleton.forward_kinematics(self.rotations, self.root)
        self.positions = np.asarray(self.positions, dtype=float)

    @classmethod
    def made(cls, rotations: np.ndarray, velocities: np.ndarray, root: np.ndarray, positions: np.ndarray, *,
             time: float, source: str, labels: frozenset[str]) -> "BodyPose":
        """A pose from arrays a caller has just made right (unit float rotations ``(J, 4)``,
        velocities ``(J, 3)``, positions by forward kinematics), without checking or copying
        them again: a body's blended frame, once per tick, where the checks cost more than
        the frame's own arithmetic."""
        pose = object.__new__(cls)
        pose.rotations, pose.velocities, pose.root, pose.positions = rotations, velocities, root, positions
        pose.time, pose.source, pose.labels, pose.skeleton = time, source, labels, None
        return pose

    def end_effector(self, name: str) -> np.ndarray:
        """World position of the named joint (usually one of ``skeleton.end_effectors``)."""
        if self.skeleton is None:
            raise ValueError("end_effector() needs the pose's skeleton to look up joint names")
        return self.positions[self.skeleton.index(name)]


def estimate_velocities(rotations: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Angular velocities ``(N, J, 3)`` of a key-frame sequence ``(N, J, 4)`` by differences.

    Central differences inside, one-sided at the ends; a single frame is at rest. Used when
    source material (BVH, procedural) gives angles but no velocities.
    """
    rotations = quat.hemisphere_align(np.asarray(rotations, dtype=float))
    times = np.asarray(times, dtype=float)
    if len(rotations) < 2:
        return np.zeros((*rotations.shape[:-1], 3))
    steps = quat.log(quat.multiply(rotations[1:], quat.conjugate(rotations[:-1])))
    dt = np.maximum(np.diff(times), 1e-9)[:, None, None]
    rates = steps / dt
    velocities = np.empty((*rotations.shape[:-1], 3))
    velocities[0] = rates[0]
    velocities[-1] = rates[-1]
    velocities[1:-1] = 0.5 * (rates[1:] + rates[:-1])
    return velocities


@dataclass(eq=False)
class PoseSet:
    """Many BodyPoses as stacked arrays: the node store of a motor graph.

    ``source_ids[i]`` indexes ``sources`` (the animation node ``i`` came from) and
    ``times[i]`` is its time within that animation.
    """

    skeleton: Skeleton
    rotations: np.ndarray  # (N, J, 4)
    velocities: np.ndarray  # (N, J, 3)
    roots: np.ndarray  # (N, 3)
    times: np.ndarray  # (N,)
    source_ids: np.ndarray  # (N,) int
    sources: list[str]
    labels: list[frozenset[str]]
    positions: np.ndarray | None = None  # (N, J, 3), FK when omitted

    def __post_init__(self) -> None:
        self.rotations = quat.normalize(self.rotations)
        self.velocities = np.asarray(self.velocities, dtype=float)
        self.roots = np.asarray(self.roots, dtype=float)
        self.times = np.asarray(self.times, dtype=float)
        self.source_ids = np.asarray(self.source_ids, dtype=np.int64)
        self.labels = [frozenset(x) for x in self.labels]
        if self.positions is None:
            self.positions = self.skeleton.forward_kinematics(self.rotations, self.roots)
        count = len(self.rotations)
        if not (
            len(self.velocities) == len(self.roots) == len(self.times) == count
            and len(self.source_ids) == len(self.labels) == len(self.positions) == count
        ):
            raise ValueError("PoseSet arrays must all have one entry per pose")

    @property
    def every_label(self) -> frozenset[str]:
        """Every motor label some pose carries: what a label named in a config, a program or an
        edit must be one of."""
        return frozenset().union(*self.labels)

    @classmethod
    def from_checked(cls, skeleton: Skeleton, rotations: np.ndarray, velocities: np.ndarray, roots: np.ndarray,
                     times: np.ndarray, source_ids: np.ndarray, sources: list[str],
                     labels: list[frozenset[str]], positions: np.ndarray) -> PoseSet:
        """Arrays that are a pose set's already (unit quaternions, C order, one entry per pose, the
        positions their forward kinematics), as the motor-graph cache reads them back after its
        checksums: no second normalisation nor kinematics (half of a 72,000-frame reload)."""
        poses = cls.__new__(cls)
        poses.skeleton, poses.rotations, poses.velocities, poses.roots = skeleton, rotations, velocities, roots
        poses.times, poses.source_ids, poses.sources, poses.labels = times, source_ids, sources, labels
        poses.positions = positions
        count = len(rotations)
        if not (rotations.shape == (count, skeleton.joint_count, 4) and velocities.shape == (count, skeleton.joint_count, 3)
                and positions.shape == (count, skeleton.joint_count, 3) and roots.shape == (count, 3)
                and len(times) == len(source_ids) == len(labels) == count):
            raise ValueError("PoseSet arrays must all have one entry per pose")
        return poses

    def __len__(self) -> int:
        return len(self.rotations)

    @cached_property
    def lines(self) -> LineShapes:
        """Every pose as its line (the splines through its chains, and how they move): what a
        line body's metric measures (``MetricWeights.content = "spline"``). Made on first use
        from the rotations and velocities, which a pose set never changes in place."""
        return LineShapes.of(self.skeleton, self.rotations, self.velocities)

    @classmethod
    def animation(
        cls,
        skeleton: Skeleton,
        rotations: np.ndarray,
        roots: np.ndarray,
        times: np.ndarray,
        source: str,
        labels: Sequence[frozenset[str]] | None = None,
    ) -> PoseSet:
        """One source animation from key-frame rotations ``(N, J, 4)`` over ``times``, its
        angular velocities estimated by differences (BVH files, procedural and blended
        animations all arrive this way)."""
        times = np.asarray(times, dtype=float)
        return cls(
            skeleton=skeleton,
            rotations=rotations,
            velocities=estimate_velocities(rotations, times),
            roots=roots,
            times=times,
            source_ids=np.zeros(len(times), dtype=np.int64),
            sources=[source],
            labels=[frozenset()] * len(times) if labels is None else labels,
        )

    @classmethod
    def concatenate(cls, sets: Sequence[PoseSet]) -> PoseSet:
        """Join pose sets over one skeleton; equal source names become one source."""
        sources: list[str] = []
        for s in sets:
            sources += [name for name in s.sources if name not in sources]
        ids = [np.array([sources.index(name) for name in s.sources])[s.source_ids] for s in sets]
        return cls(
            skeleton=sets[0].skeleton,
            rotations=np.concatenate([s.rotations for s in sets]),
            velocities=np.concatenate([s.velocities for s in sets]),
            roots=np.concatenate([s.roots for s in sets]),
            times=np.concatenate([s.times for s in sets]),
            source_ids=np.concatenate(ids),
            sources=sources,
            labels=[label for s in sets for label in s.labels],
            positions=np.concatenate([s.positions for s in sets]),
        )

    def subset(self, indices: Sequence[int] | np.ndarray) -> PoseSet:
        """The poses at ``indices`` (e.g. a path taken, to save as new animation material)."""
        indices = np.asarray(indices, dtype=np.int64)
        return PoseSet(
            skeleton=self.skeleton,
            rotations=self.rotations[indices],
            velocities=self.velocities[indices],
            roots=self.roots[indices],
            times=self.times[indices],
            source_ids=self.source_ids[indices],
            sources=list(self.sources),
            labels=[self.labels[i] for i in indices.tolist()],
            positions=self.positions[indices],
        )

    def pose(self, index: int) -> BodyPose:
        """Node ``index`` as a :class:`BodyPose`."""
        return BodyPose(
            rotations=self.rotations[index],
            velocities=self.velocities[index],
            root=self.roots[index],
            time=float(self.times[index]),
            source=self.sources[self.source_ids[index]],
            labels=self.labels[index],
            positions=self.positions[index],
            skeleton=self.skeleton,
        )

    def labelled(self, label: str) -> np.ndarray:
        """Indices of poses carrying ``label``."""
        return np.array([i for i, labels in enumerate(self.labels) if label in labels], dtype=np.int64)
