"""A body pose as 3-D splines (thesis, "curve (technology)": "a new BodyPose representation
suitable for encoding 3 dimensional splines ... and three new renderers for displaying these
splines").

A line body is its skeleton's chains (:func:`strokes`: each chain from a joint down its first
child, every further child starting a chain of its own), and each chain is a Catmull-Rom spline
through its joints in 3-D: the curve passes through every joint, its tangent at a joint is
parallel to the chord between the joint's neighbours, so a drawn limb bends smoothly where
the motor system's pose has only straight bones. The motor graph keeps joint rotations (its
metric and blends are on those); :class:`SplinePose` is what the body is *as a line* — each
segment an exact cubic Bézier (uniform Catmull-Rom: b1 = p1 + (p2 − p0)/6, b2 = p2 − (p3 −
p1)/6), which SVG's ``C`` and PostScript's ``curveto`` draw natively, in 3-D so that any
orthographic view of it is the same curve's view (a projection keeps Béziers Béziers).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


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


def sample(segments: np.ndarray, per_segment: int = 8) -> np.ndarray:
    """Points along Bézier ``segments`` (S, 4, 3): ``per_segment`` a segment, then the end."""
    u = np.linspace(0.0, 1.0, per_segment, endpoint=False)
    basis = np.stack([(1 - u) ** 3, 3 * u * (1 - u) ** 2, 3 * u ** 2 * (1 - u), u ** 3], axis=1)  # (n, 4)
    return np.concatenate([np.einsum("nk,skd->snd", basis, segments).reshape(-1, 3), segments[-1:, 3]])


def catmull_rom(points: np.ndarray) -> np.ndarray:
    """The uniform Catmull-Rom spline through ``points`` (K ≥ 2, 3) as K − 1 cubic Bézier
    segments (K − 1, 4, 3); the ends continue their last chord (phantom points reflected)."""
    p = np.asarray(points, dtype=float)
    padded = np.concatenate([2 * p[:1] - p[1:2], p, 2 * p[-1:] - p[-2:-1]])
    p0, p1, p2, p3 = padded[:-3], padded[1:-2], padded[2:-1], padded[3:]
    return np.stack([p1, p1 + (p2 - p0) / 6.0, p2 - (p3 - p1) / 6.0, p2], axis=1)
