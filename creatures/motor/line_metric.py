"""The BodyPose metric of a line body, measured on its 3-D splines (thesis, "curve (technology)":
"a new BodyPose representation suitable for encoding 3 dimensional splines"; "(void*)": "only
the very lowest level representation (the content and metrics for BodyPose) need be changed").

A graph whose ``MetricWeights.content`` is ``"spline"`` keeps every other part of
:mod:`~creatures.motor.metric` — the time term, the edges each pose makes, A*, the transit
times playback paces moves by — and changes only the two terms figure 28 builds from the
pose itself, read from :class:`~creatures.motor.spline.LineShapes` instead of the joint
rotations:

* **pose difference** – the mean distance between the two lines, point for point along their
  length (each point weighted by its share of the line), the root joints laid on each other.
  On rotations a turn of the root and a turn of the tip cost the same angle; on the line the
  first swings the whole line and the second its last bone, which is what an eye (and a
  creature perceiving shapes, and a string held in the line's shape) sees. It is a sum of
  norms, so it is a true metric, as the rotation term is.
* **closest transit** – the line's points move on along their velocities; ``α`` is how many
  horizons until the moving line passes closest to the other (one ``α`` for the whole line:
  its points are one shape and share one time, where the thesis's joints each had their own)
  and the term is the distance left there. Heading away (``α < 0``) is standing still.

Both are scaled by ``Σ masses / reach`` (reach: the rest line's mean distance from its root),
so that turning the whole resting line by a small angle θ costs about θ · Σ masses, what the
rotation metric charges for turning every joint's mass by θ: the time term's jump and the
other weights keep their meaning on either content.
"""

from __future__ import annotations

from typing import Literal, get_args

import numba
import numpy as np

from creatures.motor.pose import PoseSet

Content = Literal["rotations", "spline"]
"""The BodyPose contents a metric can measure (``MetricWeights.content``; ``[creature.body] metric``)."""

CONTENTS: tuple[str, ...] = get_args(Content)


def scale(poses: PoseSet) -> float:
    """The factor that puts a line distance (m) on the rotation metric's scale (see module doc)."""
    return float(poses.skeleton.masses.sum() / poses.lines.reach)


def edge_terms(poses: PoseSet, a: np.ndarray, b: np.ndarray, horizon: float, w_pose: float,
               w_transit: float) -> np.ndarray:
    """``w_pose · pose difference + w_transit · transit residual`` of edges ``a[e] → b[e]`` (flat
    int64 arrays) on the lines."""
    lines = poses.lines
    return scale(poses) * _edge_terms(lines.points, lines.velocities, np.ascontiguousarray(a, dtype=np.int64),
                                      np.ascontiguousarray(b, dtype=np.int64), lines.weights, horizon, w_pose,
                                      w_transit)


def pose_difference(poses: PoseSet, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """The pose term between every ``rows`` pose and every ``cols`` pose (``rows × cols``)."""
    lines = poses.lines
    return scale(poses) * _pairs(lines.points[rows], lines.points[cols], lines.weights)


def features(poses: PoseSet) -> np.ndarray:
    """Each pose as one flat vector (N, 3P) whose Euclidean distances stand in for the pose term
    (the approximate nearest-pose search's KD-tree)."""
    lines = poses.lines
    return (lines.points * lines.weights[:, None]).reshape(len(poses), -1) * scale(poses)


@numba.njit(cache=True)
def _edge_terms(points, velocities, a, b, weights, horizon, w_pose, w_transit):  # pragma: no cover - compiled
    """See :func:`edge_terms` (unscaled). ``α`` minimises the weighted squared distance between
    the line moved on by ``α`` horizons and the other line."""
    out = np.empty(a.shape[0])
    for e in range(a.shape[0]):
        i, j = a[e], b[e]
        along = 0.0
        speed = 0.0
        for s in range(weights.shape[0]):
            for c in range(3):
                v = velocities[i, s, c] * horizon
                along += weights[s] * (points[j, s, c] - points[i, s, c]) * v
                speed += weights[s] * v * v
        alpha = max(along / speed, 0.0) if speed > 1e-300 else 0.0
        pose = 0.0
        residual = 0.0
        for s in range(weights.shape[0]):
            gap = 0.0
            left = 0.0
            for c in range(3):
                d = points[j, s, c] - points[i, s, c]
                r = d - alpha * velocities[i, s, c] * horizon
                gap += d * d
                left += r * r
            pose += weights[s] * np.sqrt(gap)
            residual += weights[s] * np.sqrt(left)
        out[e] = w_pose * pose + w_transit * residual
    return out


@numba.njit(cache=True)
def _pairs(rows, cols, weights):  # pragma: no cover - compiled
    """Unscaled pose term between every line of ``rows`` (A, P, 3) and of ``cols`` (B, P, 3)."""
    out = np.empty((rows.shape[0], cols.shape[0]))
    for i in range(rows.shape[0]):
        for j in range(cols.shape[0]):
            total = 0.0
            for s in range(weights.shape[0]):
                gap = 0.0
                for c in range(3):
                    d = cols[j, s, c] - rows[i, s, c]
                    gap += d * d
                total += weights[s] * np.sqrt(gap)
            out[i, j] = total
    return out
