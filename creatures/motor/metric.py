"""The BodyPose distance metric (thesis "developing the distance metrics", figure 28).

The weight of a graph edge ``a → b`` is a weighted sum of three terms, each summed over
joints with per-joint mass weights ("weight joints that move more body mass"):

* **pose difference** – the rotation angle between the joints. The thesis writes
  ``acos(1 − (q1·q2))``; we use the shortest-path rotation angle ``2 acos|q1·q2|`` because it is
  a true metric (triangle inequality), which is what lets the pose term serve as an
  admissible A* heuristic (:mod:`creatures.motor.search`).
* **closest transit** ("acceleration") – how far ``b`` lies from the geodesic that ``a``'s
  joint velocities are heading along, at the point of closest approach (appendix ``α̃``).
  Continuing in the same direction costs nothing.
* **source recapture** (time) – zero for the successor frame in the source animation, a
  jump penalty otherwise, plus local inhibition of nearby-but-not-subsequent frames of the
  same source. The *exchange* variant (:func:`ratio_curve`) instead favours time jumps that
  are low-integer ratios of the source length.

All functions broadcast over leading axes, so a whole edge list or a block of all pairs
is one call.

The pose and transit terms read the BodyPose's *content*: the joint rotations (above, the
default) or, for a body that is a line (curve's creatures, a drawing read from SVG), its 3-D
splines (``MetricWeights.content = "spline"``: :mod:`~creatures.motor.line_metric`). The time
term, the transit *time* playback paces a move by and the speed limits stay on the rotations,
which are what playback interpolates on either content.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from fractions import Fraction
from typing import Any

import numba
import numpy as np

from creatures.motor import line_metric, quaternion as quat
from creatures.motor.line_metric import CONTENTS, Content
from creatures.motor.pose import PoseSet


class WeightError(ValueError):
    """A metric weight is unknown or out of range; ``key`` names it (``None``: the table)."""

    def __init__(self, key: str | None, message: str) -> None:
        super().__init__(message)
        self.key = key


_COST_SCALES = ("pose", "transit", "time", "jump")
_SPANS = ("horizon", "inhibition_width", "ratio_tolerance")


@dataclass(frozen=True)
class MetricWeights:
    """The "somewhat arbitrary scale factors" of figure 28, in one place.

    ``horizon`` is the look-ahead (seconds) along the velocity tangent for the transit
    term; ``inhibition_width`` (seconds) is how far local inhibition reaches;
    ``ratios`` switches the time term to the *exchange* low-integer-ratio curve.
    ``content`` is what the pose and transit terms measure: ``"rotations"`` (the joint
    angles, figure 28) or ``"spline"`` (the line the body draws; :mod:`~creatures.motor.line_metric`).
    """

    pose: float = 1.0
    transit: float = 0.3
    time: float = 0.5
    jump: float = 1.0
    horizon: float = 0.1
    inhibition_width: float = 0.3
    ratios: tuple[Fraction, ...] = field(default=())
    ratio_tolerance: float = 0.05
    content: Content = "rotations"

    def __post_init__(self) -> None:
        """Refuse weights that would break the graph: a negative cost scale can make an edge
        cost negative (A* is then no longer exact) and a zero span divides by zero."""
        for name in _COST_SCALES + _SPANS:
            value = getattr(self, name)
            number = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
            if not (number and (value >= 0.0 if name in _COST_SCALES else value > 0.0)):
                sign = "non-negative" if name in _COST_SCALES else "positive"
                raise WeightError(name, f"metric weight {name!r} must be a {sign} finite number (got {value!r:.40})")
        for ratio in self.ratios:
            if not (isinstance(ratio, Fraction) and 0 < ratio <= 1):
                raise WeightError("ratios", f"ratio {ratio!r} must be a fraction in (0, 1]")
        if self.content not in CONTENTS:
            raise WeightError("content", f"metric content {self.content!r:.40} is not one of "
                                         f"{', '.join(map(repr, CONTENTS))}")

    def to_dict(self) -> dict:
        return {
            "pose": self.pose,
            "transit": self.transit,
            "time": self.time,
            "jump": self.jump,
            "horizon": self.horizon,
            "inhibition_width": self.inhibition_width,
            "ratios": [str(r) for r in self.ratios],
            "ratio_tolerance": self.ratio_tolerance,
            "content": self.content,
        }

    @classmethod
    def from_dict(cls, data: Any) -> MetricWeights:
        """Weights from :meth:`to_dict` data; :class:`WeightError` names any bad entry."""
        if not isinstance(data, dict):
            raise WeightError(None, f"metric weights must be an object of names and numbers (got {data!r:.40})")
        known = [f.name for f in fields(cls)]
        for key in data:
            if key not in known:
                raise WeightError(key, f"unknown metric weight {key!r} (known: {', '.join(known)})")
        ratios = data.get("ratios", [])
        if not isinstance(ratios, list):
            raise WeightError("ratios", f"'ratios' must be a list of fractions such as \"2/3\" (got {ratios!r:.40})")
        return cls(**{**data, "ratios": tuple(_fraction(r) for r in ratios)})


def _fraction(text: Any) -> Fraction:
    if isinstance(text, str):
        try:
            return Fraction(text)
        except (ValueError, ZeroDivisionError):
            pass
    raise WeightError("ratios", f"ratio {text!r:.40} must be a fraction such as \"2/3\"")


def low_integer_ratios(limit: int = 4) -> tuple[Fraction, ...]:
    """Fractions ``p/q`` in (0, 1] with ``q ≤ limit``: 1, 1/2, 1/3, 2/3, 1/4, 3/4, ..."""
    return tuple(sorted({Fraction(p, q) for q in range(1, limit + 1) for p in range(1, q + 1)}))


def pose_difference(rot_a: np.ndarray, rot_b: np.ndarray, masses: np.ndarray) -> np.ndarray:
    """Mass-weighted sum of joint rotation angles between poses ``(..., J, 4)``."""
    return quat.angle_between(rot_a, rot_b) @ masses


def pose_gap(poses: PoseSet, rows: np.ndarray, cols: np.ndarray, weights: MetricWeights) -> np.ndarray:
    """The pose term between every ``rows`` pose and every ``cols`` pose (``rows × cols``) on the
    content ``weights`` measure (the nearest pose across two islands of a graph)."""
    if weights.content == "spline":
        return line_metric.pose_difference(poses, rows, cols)
    return pose_difference(poses.rotations[rows][:, None], poses.rotations[cols][None], poses.skeleton.masses)


def closest_transit(
    rot_a: np.ndarray, vel_a: np.ndarray, rot_b: np.ndarray, masses: np.ndarray, horizon: float
) -> tuple[np.ndarray, np.ndarray]:
    """Residual and time of the closest transit from pose ``a`` towards pose ``b`` (figure 29).

    Each joint travels from ``q_a`` along its velocity tangent; ``v = exp(ω·horizon) q_a`` is
    where it would be after ``horizon`` seconds. ``α̃`` (appendix) says how many horizons
    until the geodesic passes closest to ``q_b``. Returns the mass-weighted residual angle
    at that point and the mass-weighted mean transit time in seconds (0 where at rest).
    Heading away from ``b`` (``α̃ < 0``) is treated as not moving, so the residual is the
    whole angle.
    """
    tangent = quat.multiply(quat.exp(vel_a * horizon), rot_a)
    alpha = np.maximum(quat.closest_approach(rot_a, tangent, rot_b), 0.0)
    passing = quat.slerp(rot_a, tangent, alpha)
    residual = quat.angle_between(passing, rot_b) @ masses
    time = (alpha * horizon) @ masses / masses.sum()
    return residual, time


def inhibition_curve(dt: np.ndarray, width: float) -> np.ndarray:
    """Local inhibition: nearby (but not subsequent) frames of one source cost most."""
    return np.exp(-((dt / width) ** 2))


def ratio_curve(dt: np.ndarray, length: np.ndarray, ratios: tuple[Fraction, ...], tolerance: float) -> np.ndarray:
    """*Exchange*: 0 where ``|dt| / length`` is a low-integer ratio, rising to 1 between them."""
    r = np.abs(dt) / np.maximum(length, 1e-9)
    targets = np.array([float(x) for x in ratios])
    gap = np.min(np.abs(r[..., None] - targets), axis=-1)
    return np.minimum(gap / tolerance, 1.0)


def successors(poses: PoseSet) -> np.ndarray:
    """Index of each pose's next frame in its source animation, or −1 at the end."""
    nxt = np.full(len(poses), -1, dtype=np.int64)
    same = poses.source_ids[1:] == poses.source_ids[:-1]
    later = poses.times[1:] > poses.times[:-1]
    idx = np.flatnonzero(same & later)
    nxt[idx] = idx + 1
    return nxt


def source_lengths(poses: PoseSet) -> np.ndarray:
    """Duration of each source animation, indexed by source id."""
    count = len(poses.sources)
    lo = np.full(count, np.inf)
    hi = np.full(count, -np.inf)
    np.minimum.at(lo, poses.source_ids, poses.times)
    np.maximum.at(hi, poses.source_ids, poses.times)
    return np.maximum(hi - lo, 0.0)


def time_term(
    poses: PoseSet, a: np.ndarray, b: np.ndarray, weights: MetricWeights, next_frame: np.ndarray
) -> np.ndarray:
    """Source-recapture cost of moving from poses ``a`` to ``b`` (broadcast index arrays)."""
    a = np.asarray(a)
    b = np.asarray(b)
    same = poses.source_ids[a] == poses.source_ids[b]
    dt = poses.times[b] - poses.times[a]
    if weights.ratios:
        length = source_lengths(poses)[poses.source_ids[a]]
        within = ratio_curve(dt, length, weights.ratios, weights.ratio_tolerance)
    else:
        within = inhibition_curve(dt, weights.inhibition_width)
    cost = np.where(same, weights.jump * within, weights.jump)
    return np.where(next_frame[a] == b, 0.0, cost)


def edge_costs(
    poses: PoseSet,
    a: np.ndarray,
    b: np.ndarray,
    weights: MetricWeights,
    next_frame: np.ndarray | None = None,
    *,
    chunk: int = 8192,
) -> np.ndarray:
    """Intrinsic metric: weight of the edges ``a[i] → b[i]`` (index arrays, broadcast).

    Edges are costed ``chunk`` at a time; the pose and transit terms run compiled
    (:func:`_pose_and_transit`: as numpy, their per-joint temporaries made a 72,000-frame
    build take a minute), on the rotations or the lines (``weights.content``).
    """
    a, b = np.broadcast_arrays(np.asarray(a), np.asarray(b))
    if next_frame is None:
        next_frame = successors(poses)
    flat_a, flat_b = a.ravel(), b.ravel()
    out = np.empty(flat_a.shape)
    masses = np.ascontiguousarray(poses.skeleton.masses, dtype=float)
    rotations = np.ascontiguousarray(poses.rotations)
    velocities = np.ascontiguousarray(poses.velocities)
    for start in range(0, len(flat_a), chunk):
        i = np.ascontiguousarray(flat_a[start : start + chunk], dtype=np.int64)
        j = np.ascontiguousarray(flat_b[start : start + chunk], dtype=np.int64)
        if weights.content == "spline":
            terms = line_metric.edge_terms(poses, i, j, weights.horizon, weights.pose, weights.transit)
        else:
            terms = _pose_and_transit(rotations, velocities, i, j, masses, weights.horizon, weights.pose, weights.transit)
        out[start : start + chunk] = terms + weights.time * time_term(poses, i, j, weights, next_frame)
    return out.reshape(a.shape)


@numba.njit(cache=True)
def _pose_and_transit(rotations, velocities, a, b, masses, horizon, w_pose, w_transit):  # pragma: no cover - compiled
    """``w_pose · pose_difference + w_transit · closest_transit residual`` of edges ``a[e] → b[e]``,
    joint by joint with the single-quaternion forms of the same functions."""
    out = np.empty(a.shape[0])
    for e in range(a.shape[0]):
        i, j = a[e], b[e]
        pose = 0.0
        residual = 0.0
        for k in range(masses.shape[0]):
            qa = (rotations[i, k, 0], rotations[i, k, 1], rotations[i, k, 2], rotations[i, k, 3])
            qb = (rotations[j, k, 0], rotations[j, k, 1], rotations[j, k, 2], rotations[j, k, 3])
            pose += quat.angle_between_one(qa, qb) * masses[k]
            step = (velocities[i, k, 0] * horizon, velocities[i, k, 1] * horizon, velocities[i, k, 2] * horizon)
            tangent = quat.multiply_one(quat.exp_one(step), qa)
            alpha = max(quat.closest_approach_one(qa, tangent, qb), 0.0)
            residual += quat.angle_between_one(quat.slerp_one(qa, tangent, alpha), qb) * masses[k]
        out[e] = w_pose * pose + w_transit * residual
    return out


def nearest_costs(
    poses: PoseSet, rows: np.ndarray, candidates: np.ndarray, weights: MetricWeights, next_frame: np.ndarray, k: int
) -> np.ndarray:
    """Edge costs ``rows[r] → candidates[r, c]`` exact for each row's ``k`` cheapest (itself
    excluded) and ``inf`` for candidates that cannot be among them.

    Every cost is at least its pose and time terms (the transit residual is never negative),
    so candidates are costed in order of that bound and a row stops once the bound passes
    its k-th best full cost: the closest-transit term, four fifths of the metric's work, is
    evaluated only where it can matter. On the lines (``weights.content = "spline"``) both terms
    cost about the same, so every candidate is costed in full.
    """
    if weights.content == "spline":
        return edge_costs(poses, np.asarray(rows)[:, None], candidates, weights, next_frame)
    rows = np.ascontiguousarray(rows, dtype=np.int64)
    candidates = np.ascontiguousarray(candidates, dtype=np.int64)
    time = np.ascontiguousarray(weights.time * time_term(poses, rows[:, None], candidates, weights, next_frame))
    return _nearest_costs(np.ascontiguousarray(poses.rotations), np.ascontiguousarray(poses.velocities), rows,
                          candidates, np.ascontiguousarray(poses.skeleton.masses, dtype=float), weights.horizon,
                          weights.pose, weights.transit, time, k)


@numba.njit(cache=True)
def _transit_residual(rotations, velocities, i, j, masses, horizon):  # pragma: no cover - compiled
    """The closest-transit residual of ``i → j`` (see :func:`closest_transit`)."""
    residual = 0.0
    for k in range(masses.shape[0]):
        qa = (rotations[i, k, 0], rotations[i, k, 1], rotations[i, k, 2], rotations[i, k, 3])
        qb = (rotations[j, k, 0], rotations[j, k, 1], rotations[j, k, 2], rotations[j, k, 3])
        step = (velocities[i, k, 0] * horizon, velocities[i, k, 1] * horizon, velocities[i, k, 2] * horizon)
        tangent = quat.multiply_one(quat.exp_one(step), qa)
        alpha = max(quat.closest_approach_one(qa, tangent, qb), 0.0)
        residual += quat.angle_between_one(quat.slerp_one(qa, tangent, alpha), qb) * masses[k]
    return residual


@numba.njit(cache=True)
def _nearest_costs(rotations, velocities, rows, candidates, masses, horizon, w_pose, w_transit, time, k):  # pragma: no cover - compiled
    """:func:`nearest_costs` (``inf`` where skipped)."""
    out = np.full(candidates.shape, np.inf)
    lower = np.empty(candidates.shape[1])
    for r in range(rows.shape[0]):
        i = rows[r]
        for c in range(candidates.shape[1]):
            j = candidates[r, c]
            pose = 0.0
            for joint in range(masses.shape[0]):
                qa = (rotations[i, joint, 0], rotations[i, joint, 1], rotations[i, joint, 2], rotations[i, joint, 3])
                qb = (rotations[j, joint, 0], rotations[j, joint, 1], rotations[j, joint, 2], rotations[j, joint, 3])
                pose += quat.angle_between_one(qa, qb) * masses[joint]
            lower[c] = w_pose * pose
        best = np.full(k, np.inf)
        for c in np.argsort(lower + time[r]):
            if lower[c] + time[r, c] > best.max():
                break
            j = candidates[r, c]
            cost = (lower[c] + w_transit * _transit_residual(rotations, velocities, i, j, masses, horizon)) + time[r, c]
            out[r, c] = cost
            if j != i:
                worst = np.argmax(best)
                if cost < best[worst]:
                    best[worst] = cost
    return out


def pairwise(poses: PoseSet, rows: np.ndarray, cols: np.ndarray, weights: MetricWeights) -> np.ndarray:
    """All-pairs edge costs ``rows × cols`` (the extrinsic metric between any two poses)."""
    rows = np.asarray(rows)
    cols = np.asarray(cols)
    return edge_costs(poses, rows[:, None], cols[None, :], weights)


@dataclass(frozen=True)
class Timing:
    """What :func:`transit_time` needs from the whole pose set, computed once per graph.

    ``typical_speed`` (rad/s) paces a move from rest; ``max_speed`` (rad/s) is the speed
    limit no joint exceeds on an estimated move (nor, in :mod:`~creatures.motor.playback`,
    anywhere on the interpolated curve). :meth:`of` takes both from the source material.
    """

    next_frame: np.ndarray
    typical_speed: float
    max_speed: float

    @classmethod
    def of(cls, poses: PoseSet) -> Timing:
        next_frame = successors(poses)
        return cls(next_frame, typical_speed(poses), fastest_speed(poses, next_frame))


def transit_time(
    poses: PoseSet, a: np.ndarray, b: np.ndarray, weights: MetricWeights, timing: Timing | None = None
) -> np.ndarray:
    """Seconds to move ``a → b``: source timing for successors, else estimated from velocity.

    The estimate is the closest-transit time; when the joints are at rest (or heading
    away) it falls back to the pose angle covered at ``timing.typical_speed``. Closest
    approach is not arrival, so the estimate alone can be near zero for a large move
    (playback would then jump); every estimate is therefore lengthened until no joint
    turns faster than ``timing.max_speed``.
    """
    a = np.asarray(a)
    b = np.asarray(b)
    timing = Timing.of(poses) if timing is None else timing
    masses = poses.skeleton.masses
    rot_a, rot_b = poses.rotations[a], poses.rotations[b]
    _, estimate = closest_transit(rot_a, poses.velocities[a], rot_b, masses, weights.horizon)
    at_rest = pose_difference(rot_a, rot_b, masses) / (timing.typical_speed * masses.sum())
    estimate = np.minimum(np.where(estimate > 1e-6, estimate, at_rest), 2.0)
    limited = quat.angle_between(rot_a, rot_b).max(axis=-1, initial=0.0) / timing.max_speed
    return np.where(timing.next_frame[a] == b, poses.times[b] - poses.times[a], np.maximum(estimate, limited))


CONTACT_HEIGHT = 0.005
"""Metres above the ground (``y = 0`` of the body's frame) within which a joint touches it."""

CONTACT_SPEED = 0.12
"""Metres per second a joint touching the ground may slide over it while the body moves
between poses that are not successive source frames.

Such a move carries the root nowhere (root motion advances only along the source), so a paw
planted at both ends slides by the difference of its places, however fast the move:
playback lengthens the move until no planted joint slides faster than this. 0.12 m/s is
8 mm a frame at the shipped bodies' 15 fps, under the 1 cm a frame a planted foot may move
(issue 16), with room for the pace the sampled curve misses between its samples."""


def contact_rate(at: np.ndarray) -> np.ndarray:
    """Peak sliding rate of a joint in contact with the ground along each of ``M`` moves,
    sampled at ``S + 1`` evenly spaced points ``at`` ``(M, S + 1, J, 3)``: metres per whole
    move at its fastest step (0 where no joint touches the ground in two samples running)."""
    planted = (at[:, 1:, :, 1] < CONTACT_HEIGHT) & (at[:, :-1, :, 1] < CONTACT_HEIGHT)
    steps = np.where(planted, np.linalg.norm(np.diff(at, axis=1), axis=-1), 0.0)
    return steps.reshape(len(at), -1).max(axis=-1, initial=0.0) * (at.shape[1] - 1)


def typical_speed(poses: PoseSet) -> float:
    """Median mass-weighted joint angular speed over the pose set (rad/s, at least 0.1)."""
    masses = poses.skeleton.masses
    speed = np.linalg.norm(poses.velocities, axis=-1) @ masses / masses.sum()
    return float(max(np.median(speed), 0.1))


def fastest_speed(poses: PoseSet, next_frame: np.ndarray) -> float:
    """Fastest any joint turns while the source animations play (rad/s, at least 0.1).

    Each source step is measured along the squad curve playback draws through it (with
    its neighbouring frames as controls), so a path that stays on a source animation
    is never slowed by the limit this sets. Recorded velocities count too, for pose sets
    without source steps.
    """
    a = np.flatnonzero(next_frame >= 0)
    b = next_frame[a]
    before = np.arange(len(poses))
    before[b] = a
    after = np.where(next_frame >= 0, next_frame, np.arange(len(poses)))
    rot = poses.rotations
    controls = quat.squad_control_at(rot, before, after)
    seconds = poses.times[b] - poses.times[a]
    # A step turns at least its straight angle, so only joints whose bound beats the
    # fastest straight step can be the fastest: sampling just those is ~10× quicker.
    floor = np.max(quat.angle_between(rot[a], rot[b]).max(axis=-1, initial=0.0) / seconds, initial=0.0)
    above = floor * seconds[:, None]
    turns = quat.squad_rate(rot[a], rot[b], controls[a], controls[b], above=above).max(axis=-1, initial=0.0)
    played = np.max(turns / seconds, initial=0.0)
    recorded = np.linalg.norm(poses.velocities, axis=-1).max(initial=0.0)
    return float(max(played, recorded, 0.1))
