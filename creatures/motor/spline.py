"""A body pose as 3-D splines (thesis, "curve (technology)": "a new BodyPose representation
suitable for encoding 3 dimensional splines ... and three new renderers for displaying these
splines").

A line body is its skeleton's chains (:func:`strokes`: each chain from a joint down its first
child, every further child starting a chain of its own), and each chain is a Catmull-Rom spline
through its joints in 3-D: the curve passes through every joint, its tangent at a joint is
parallel to the chord between the joint's neighbours, so a drawn limb bends smoothly where
the motor system's pose has only straight bones. :class:`SplinePose` is what one pose is *as a
line* — each segment an exact cubic Bézier (uniform Catmull-Rom: b1 = p1 + (p2 − p0)/6, b2 =
p2 − (p3 − p1)/6), which SVG's ``C`` and PostScript's ``curveto`` draw natively, in 3-D so that
any orthographic view of it is the same curve's view (a projection keeps Béziers Béziers).

:class:`LineShapes` is the same for every node of a motor graph, as the node content a line
body's metric reads (``MetricWeights.content = "spline"``, :mod:`~creatures.motor.line_metric`):
points along each spline with the root at the origin, and their velocities — the thesis's
BodyPose of "joint angles" and "joint velocities", for a body that is a line. The joint
rotations stay in the pose too: they are the key-frames playback interpolates (a chain of rigid
bones turned joint by joint cannot stretch, so between two poses the line stays a line of its
own length), while the splines are what the graph measures.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from creatures.motor import quaternion as quat
from creatures.motor.skeleton import Skeleton


def strokes(parents: np.ndarray) -> list[list[int]]:
    """The bones as chains of joint indices: each chain from a joint down its first child as
    one line, every further child starting a line of its own at its parent."""
    children: dict[int, list[int]] = {}
    for j, p in enumerate(parents):
        if p >= 0:
            children.setdefault(int(p), []).append(j)
    lines: list[list[int]] = []
    starts = [(int(j), None) for j in np.flatnonzero(np.asarray(parents) < 0)]
    while starts:
        joint, parent = starts.pop(0)
        line = [joint] if parent is None else [parent, joint]
        while children.get(line[-1]):
            first, *rest = children[line[-1]]
            starts += [(c, line[-1]) for c in rest]
            line.append(first)
        if len(line) > 1:
            lines.append(line)
    return lines


@dataclass(frozen=True)
class SplinePose:
    """Each chain of a pose as the Bézier segments of a Catmull-Rom spline: (S, 4, 3) each."""

    segments: tuple[np.ndarray, ...]

    @classmethod
    def of(cls, positions: np.ndarray, parents: np.ndarray) -> "SplinePose":
        """The splines of the pose ``positions`` (J, 3) of a skeleton with ``parents``."""
        positions = np.asarray(positions, dtype=float)
        return cls(tuple(catmull_rom(positions[chain]) for chain in strokes(parents)))

    def points(self, per_segment: int = 8) -> list[np.ndarray]:
        """Each chain sampled along its spline (see :func:`sample`)."""
        return [sample(seg, per_segment) for seg in self.segments]


SAMPLES = 3
"""Points a bone's segment of the spline is measured at (the midpoints of equal parameter
steps). Three keep every distance between the stick figure's poses within 1 % of what sixteen
measure (0.4 % at most; two: 1.4 %) at 3/16 of the cost: the all-pairs pose term is most of a
graph's build (tests/test_spline_graph.py)."""

STEP = 1e-3
"""Seconds either side of a pose over which its joint velocities move the line (central
differences: the points' velocities, exact to second order)."""


@dataclass(frozen=True)
class LineShapes:
    """Every pose of a pose set as its line: ``points`` (N, P, 3) along the splines, the root
    joint at the origin (the rotation metric ignores where the root stands too; its turn is
    the whole line's turn, and counts), their ``velocities`` (N, P, 3) in m/s, and each point's
    share of the line's length ``weights`` (P,), summing to one. Bones keep their length, so
    the shares are the skeleton's: a point stands for its segment's length over
    :data:`SAMPLES`, and a long bone counts for more of the line than a short one."""

    points: np.ndarray
    velocities: np.ndarray
    weights: np.ndarray
    reach: float
    """Mean distance of the line from its root in the skeleton's rest pose (m): the metric's
    length scale, a constant of the body (:mod:`~creatures.motor.line_metric`)."""

    @classmethod
    def of(cls, skeleton: Skeleton, rotations: np.ndarray, velocities: np.ndarray) -> "LineShapes":
        """The lines of poses ``rotations`` (N, J, 4) turning at ``velocities`` (N, J, 3) (angular,
        parent frame, as a BodyPose's) on ``skeleton``."""
        chains = strokes(skeleton.parents)
        if not chains:
            raise ValueError("a skeleton of one joint draws no line: measure its poses on their rotations")
        root = int(np.flatnonzero(np.asarray(skeleton.parents) < 0)[0])

        def lines(rot: np.ndarray) -> np.ndarray:
            joints = skeleton.forward_kinematics(rot, np.zeros(3))
            joints = joints - joints[..., root:root + 1, :]
            return np.concatenate([midpoints(catmull_rom(joints[..., chain, :])) for chain in chains], axis=-2)

        ahead, behind = (quat.multiply(quat.exp(velocities * step), rotations) for step in (STEP, -STEP))
        lengths = np.concatenate([np.repeat(np.linalg.norm(skeleton.offsets[chain[1:]], axis=-1), SAMPLES)
                                  for chain in chains])
        weights = lengths / lengths.sum() if lengths.sum() > 0 else np.full(len(lengths), 1.0 / len(lengths))
        rest = lines(quat.identity((skeleton.joint_count,)))
        return cls(lines(rotations), (lines(ahead) - lines(behind)) / (2 * STEP), weights,
                   float(max(np.linalg.norm(rest, axis=-1) @ weights, 1e-9)))


def midpoints(segments: np.ndarray) -> np.ndarray:
    """The points (..., S · SAMPLES, 3) at the midpoints of :data:`SAMPLES` equal parameter steps
    of each Bézier of ``segments`` (..., S, 4, 3): a midpoint rule along the line."""
    along = bernstein((np.arange(SAMPLES) + 0.5) / SAMPLES) @ segments  # (n, 4) @ (..., S, 4, 3)
    return along.reshape(*segments.shape[:-3], -1, 3)


def sample(segments: np.ndarray, per_segment: int = 8) -> np.ndarray:
    """Points along Bézier ``segments`` (S, 4, 3): ``per_segment`` a segment, then the end."""
    u = np.linspace(0.0, 1.0, per_segment, endpoint=False)
    along = bernstein(u) @ segments  # (n, 4) @ (S, 4, 3)
    return np.concatenate([along.reshape(-1, 3), segments[-1:, 3]])


def bernstein(u: np.ndarray) -> np.ndarray:
    """The cubic Bernstein weights (n, 4) at parameters ``u`` (n,): a Bézier point is their sum
    over its four control points."""
    return np.stack([(1 - u) ** 3, 3 * u * (1 - u) ** 2, 3 * u ** 2 * (1 - u), u ** 3], axis=1)


def catmull_rom(points: np.ndarray) -> np.ndarray:
    """The uniform Catmull-Rom spline through ``points`` (..., K ≥ 2, 3) as K − 1 cubic Bézier
    segments (..., K − 1, 4, 3); the ends continue their last chord (phantom points reflected)."""
    p = np.asarray(points, dtype=float)
    padded = np.concatenate([2 * p[..., :1, :] - p[..., 1:2, :], p, 2 * p[..., -1:, :] - p[..., -2:-1, :]], axis=-2)
    p0, p1, p2, p3 = padded[..., :-3, :], padded[..., 1:-2, :], padded[..., 2:-1, :], padded[..., 3:, :]
    return np.stack([p1, p1 + (p2 - p0) / 6.0, p2 - (p3 - p1) / 6.0, p2], axis=-2)
