"""Each pose's ``k`` metric-nearest poses: the automatic topology of a motor graph.

The edge metric (:mod:`creatures.motor.metric`) is not a Euclidean distance, so no index
answers "k nearest" for it directly. Two searches serve:

* **exact**, up to :data:`EXACT_BELOW` candidate poses: every edge costs at least its pose
  and time terms (the transit term is never negative); a bound on those is cheap for all
  pairs, and the full metric is evaluated only where the bound is below a pose's k-th best
  cost so far, since nothing else can be nearer.
* **approximate**, for larger graphs, where even the bound over all pairs is too slow: a
  KD-tree on a PCA projection of the mass-weighted quaternions proposes ``oversample × k``
  candidates per pose, re-ranked with the full metric (near ``O(N log N)``; it misses a
  few true neighbours, ~4% at 2,000 nodes).

Both read the BodyPose content the metric measures (``weights.content``): on a line body's
splines the bound is the pose term itself and the KD-tree's points are the lines' points
(:mod:`~creatures.motor.line_metric`).
"""

from __future__ import annotations

from typing import Callable, Iterator

import numba
import numpy as np
from scipy.spatial import cKDTree

from creatures.motor import line_metric, metric
from creatures.motor.metric import MetricWeights
from creatures.motor.pose import PoseSet

EXACT_BELOW = 5000
"""Largest number of candidate poses searched exactly (~1.5 s CPU at 5,000 nodes, growing as N²;
the approximate search takes ~0.9 s there)."""

Pairs = tuple[np.ndarray, np.ndarray, np.ndarray]
"""Candidate edges as flat arrays: from-nodes, to-nodes and their full edge costs."""


def nearest_edges(
    poses: PoseSet, rows: np.ndarray, cols: np.ndarray, k: int, weights: MetricWeights, oversample: int = 3
) -> dict[tuple[int, int], float]:
    """Edges from each ``rows`` node to its ``k`` metric-nearest ``cols`` nodes and its successor."""
    a, b, cost = nearest_edge_arrays(poses, rows, cols, k, weights, oversample)
    return dict(zip(zip(a.tolist(), b.tolist()), cost.tolist()))


def nearest_edge_arrays(
    poses: PoseSet, rows: np.ndarray, cols: np.ndarray, k: int, weights: MetricWeights, oversample: int = 3
) -> Pairs:
    """:func:`nearest_edges` as flat arrays (each edge once, by from-node): a whole take's
    graph is built without a Python object per edge."""
    next_frame = metric.successors(poses)
    if len(cols) <= EXACT_BELOW:
        found = _exact(poses, rows, cols, k, weights, next_frame)
    else:
        found = _approximate(poses, rows, cols, k, weights, next_frame, oversample)
    a, b, cost = (np.concatenate(x) for x in zip(*found))
    keep = (a != b) & np.isfinite(cost)
    a, b, cost = a[keep], b[keep], cost[keep]
    order = np.lexsort((cost, a))  # by node, then cheapest first
    a, b, cost = a[order], b[order], cost[order]
    rank = np.arange(len(a)) - np.searchsorted(a, a)
    best = rank < k
    a, b, cost = a[best], b[best], cost[best]
    with_next = rows[next_frame[rows] >= 0]
    if len(with_next):  # the successor edge at the metric's full cost, replacing a nearest one to it
        succ = next_frame[with_next]
        costs = metric.edge_costs(poses, with_next, succ, weights, next_frame)
        keep = next_frame[a] != b
        a, b, cost = np.concatenate((a[keep], with_next)), np.concatenate((b[keep], succ)), np.concatenate((cost[keep], costs))
        order = np.argsort(a, kind="stable")
        a, b, cost = a[order], b[order], cost[order]
    return a.astype(np.int64), b.astype(np.int64), cost.astype(float)


def _exact(
    poses: PoseSet, rows: np.ndarray, cols: np.ndarray, k: int, weights: MetricWeights, next_frame: np.ndarray
) -> Iterator[Pairs]:
    """Candidates that surely include each row's ``k`` nearest (see module doc).

    The ``2k + 1`` columns of lowest bound are costed first; their k-th best cost can only
    fall as more are costed, so every column whose bound is below it is costed too, and
    no other column can be among the nearest.
    """
    pose_bound, slack = _pose_bound_of(poses, weights)
    first = min(len(cols), 2 * k + 1)
    block = max(1, 1_000_000 // len(cols))  # rows per block: ~8 MB per (rows × cols) array
    for start in range(0, len(rows), block):
        a = rows[start : start + block]
        bound = weights.pose * pose_bound(a, cols)
        bound += weights.time * metric.time_term(poses, a[:, None], cols[None], weights, next_frame)
        bound[cols[None] == a[:, None]] = np.inf
        lowest = np.argpartition(bound, first - 1, axis=1)[:, :first]
        b = cols[lowest]
        cost = metric.edge_costs(poses, a[:, None], b, weights, next_frame)
        yield np.repeat(a, first), b.ravel(), cost.ravel()
        kth = np.sort(np.where(b == a[:, None], np.inf, cost), axis=1)[:, min(k, first) - 1]
        rest = bound <= kth[:, None] + slack
        np.put_along_axis(rest, lowest, False, axis=1)
        row, col = np.nonzero(rest)
        yield a[row], cols[col], metric.edge_costs(poses, a[row], cols[col], weights, next_frame)


def _pose_bound_of(poses: PoseSet, weights: MetricWeights) -> tuple[Callable[[np.ndarray, np.ndarray], np.ndarray], float]:
    """A lower bound on the pose term between ``rows × cols`` poses, and the slack to allow its
    rounding: on the lines the term itself (:func:`line_metric.pose_difference`, cheap as the
    rotations' bound); on the rotations the chord bound over the joints that move."""
    if weights.content == "spline":
        return (lambda a, cols: line_metric.pose_difference(poses, a, cols)), 1e-9 * weights.pose * line_metric.scale(poses)
    rotations, masses = poses.rotations, poses.skeleton.masses
    moving = np.flatnonzero(np.ptp(rotations, axis=0).max(axis=-1) > 0.0)  # the others add nothing
    # The bound's dot products are summed in another order than the metric's, and near
    # |q·p| = 1 the square root magnifies a rounding of 1e-16 to ~3e-8 rad per joint.
    slack = 1e-7 * weights.pose * masses[moving].sum()
    return (lambda a, cols: _pose_bound(rotations[a][:, moving], rotations[cols][:, moving], masses[moving])), slack


@numba.njit(cache=True)
def _pose_bound(rot_a, rot_b, masses):  # pragma: no cover - compiled
    """A lower bound on :func:`metric.pose_difference` for all pairs ``(A, J, 4) × (B, J, 4)``.

    Per joint the chord ``2√(2(1 − |q·p|))`` is at most the angle ``2 acos|q·p|`` (as
    ``cos t ≥ 1 − t²/2``) and within 1% of it below 1 rad. Compiled, one pass without
    temporaries: as numpy (matrix products, then in-place passes) it took 80% of a
    2,000-node build.
    """
    out = np.zeros((rot_a.shape[0], rot_b.shape[0]))
    for i in range(rot_a.shape[0]):
        for j in range(rot_b.shape[0]):
            total = 0.0
            for joint in range(masses.shape[0]):
                dot = 0.0
                for c in range(4):
                    dot += rot_a[i, joint, c] * rot_b[j, joint, c]
                total += masses[joint] * np.sqrt(max(2.0 * (1.0 - abs(dot)), 0.0))
            out[i, j] = 2.0 * total
    return out


def _approximate(
    poses: PoseSet, rows: np.ndarray, cols: np.ndarray, k: int, weights: MetricWeights, next_frame: np.ndarray,
    oversample: int,
) -> Iterator[Pairs]:
    """KD-tree candidates (``oversample × k`` per row) with their full costs (``inf`` for those
    that cannot be among a row's ``k`` nearest: :func:`metric.nearest_costs`)."""
    features = line_metric.features(poses) if weights.content == "spline" else _features(poses)
    sample = features[cols[:: max(1, len(cols) // 2000)]]
    centre = sample.mean(axis=0)
    # Principal axes from the small covariance matrix (eigh): LAPACK's SVD of the tall
    # sample matrix is orders of magnitude slower on this machine's OpenBLAS.
    spread = np.cov(sample - centre, rowvar=False) if len(sample) > 1 else np.eye(features.shape[1])
    _, vectors = np.linalg.eigh(np.atleast_2d(spread))
    basis = vectors[:, ::-1][:, :12]
    tree = cKDTree((features[cols] - centre) @ basis)
    count = min(len(cols), oversample * k + 1)
    _, found = tree.query((features[rows] - centre) @ basis, k=count)
    candidates = cols[np.asarray(found).reshape(len(rows), count)]
    block = max(1, 50_000 // count)
    for start in range(0, len(rows), block):
        a = rows[start : start + block]
        b = candidates[start : start + block]
        yield np.repeat(a, count), b.ravel(), metric.nearest_costs(poses, a, b, weights, next_frame, k).ravel()


def _features(poses: PoseSet) -> np.ndarray:
    """Mass-weighted quaternions in one hemisphere (w ≥ 0), flattened: a Euclidean stand-in."""
    q = np.where(poses.rotations[..., :1] < 0.0, -poses.rotations, poses.rotations)
    return (q * poses.skeleton.masses[:, None]).reshape(len(poses), -1)
