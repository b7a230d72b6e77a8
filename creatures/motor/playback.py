"""Playing a graph path out on the body (thesis "moving around the graph", footnote 9).

A path through the motor graph is a list of key-frames; playback interpolates the joint
angles between them with *squad* (graph nodes may be sparser than source frames, so a
higher-order interpolant is used) and the root linearly. Key-frame timing is recaptured
from the source animation where consecutive nodes are consecutive frames, and otherwise
estimated from the joint velocities (:func:`creatures.motor.metric.transit_time`). No
segment plays faster than the source animations themselves ever move
(:attr:`creatures.motor.metric.Timing.max_speed`), so a jump between poses is always
travelled, never popped.

Playback is driven by elapsed clock time: ask for the pose at ``clock.now()`` and it is
the same whatever the frame rate.
"""

from __future__ import annotations

import weakref

import numba
import numpy as np

from creatures.motor import metric
from creatures.motor import quaternion as quat
from creatures.motor.graph import MotorGraph
from creatures.motor.pose import BodyPose
from creatures.motor.search import GraphPosition, Path


def pose_at(graph: MotorGraph, position: GraphPosition) -> tuple[np.ndarray, np.ndarray]:
    """Joint rotations ``(J, 4)`` and root ``(3,)`` at a graph position (slerp along the edge)."""
    poses = graph.poses
    if position.next is None:
        return poses.rotations[position.node], poses.roots[position.node]
    f = position.fraction
    rotations = quat.slerp(poses.rotations[position.node], poses.rotations[position.next], f)
    root = (1.0 - f) * poses.roots[position.node] + f * poses.roots[position.next]
    return rotations, root


class Playback:
    """A path laid out in time from ``start_time``: sample it at any clock time.

    ``keys`` holds the key-frame rotations (the start pose first, then each path node),
    ``key_times`` their absolute times. ``origin`` (rotations, root) overrides the start
    pose — pass the pose actually shown when a course is replaced mid-way, so the body
    does not jump from the interpolated curve to the straight edge.
    """

    def __init__(
        self,
        graph: MotorGraph,
        path: Path,
        start_time: float,
        *,
        speed: float = 1.0,
        origin: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> None:
        if not speed > 0.0:
            raise ValueError(f"playback speed must be positive (got {speed!r})")
        self.graph = graph
        self.path = path
        start = path.start
        rotations, root = pose_at(graph, start) if origin is None else origin
        nodes = np.asarray(path.nodes, dtype=np.int64)
        first_gap = self._first_gap(graph, start, int(nodes[0]))
        durations = np.concatenate(([first_gap], transit_times(graph, nodes[:-1], nodes[1:])))
        self.key_nodes = nodes
        self.keys = quat.hemisphere_align(np.concatenate((rotations[None], graph.poses.rotations[nodes])))
        self.controls = quat.squad_controls(self.keys)
        self.roots = np.concatenate((root[None], graph.poses.roots[nodes]))
        gaps = np.maximum(durations, self._turns(durations, graph.timing.max_speed) / graph.timing.max_speed)
        gaps = np.maximum(gaps, self._slides(graph, start, nodes) / metric.CONTACT_SPEED)
        self.key_times = start_time + np.concatenate(([0.0], np.cumsum(gaps / speed)))

    SLIDE_SAMPLES = 8
    """Points along each segment's squad curve at which :meth:`_slides` looks at the joints."""

    def _slides(self, graph: MotorGraph, start: GraphPosition, nodes: np.ndarray) -> np.ndarray:
        """Peak slide of a joint in contact with the ground along each segment that is not a
        source step (metres per whole segment; 0 for source steps, whose root motion carries
        the body over its planted feet, and where nothing touches the ground).

        Sampled on the squad curve playback draws, not the straight slerp: next to a jump the
        controls bend a folding leg so that its paw swings out and back, measured at twice the
        straight pace on the dog between sit and walk."""
        following = graph.timing.next_frame
        before = np.concatenate(([start.node], nodes[:-1]))
        moved = following[before] != nodes
        # the first segment is no jump when it starts on its first node or along its source step
        moved[0] &= nodes[0] != (start.node if start.next is None else -1) and not (
            start.next == nodes[0] and following[start.node] == start.next)
        out = np.zeros(len(nodes))
        jumps = np.flatnonzero(moved)
        if not len(jumps):
            return out
        u = np.tile(np.linspace(0.0, 1.0, self.SLIDE_SAMPLES + 1), len(jumps))
        seg = np.repeat(jumps, self.SLIDE_SAMPLES + 1)
        rotations = quat.squad_keys(self.keys, self.controls, seg, u)
        roots = (1.0 - u[:, None]) * self.roots[seg] + u[:, None] * self.roots[seg + 1]
        at = graph.skeleton.forward_kinematics(rotations, roots)
        out[jumps] = metric.contact_rate(at.reshape(len(jumps), self.SLIDE_SAMPLES + 1, *at.shape[1:]))
        return out

    def _turns(self, durations: np.ndarray, max_speed: float) -> np.ndarray:
        """Peak turning rate of each segment's squad curve, where it could break the limit.

        Squad bends each segment towards its neighbours, so next to a sharp turn it can
        outrun the edge's own timing: such a segment is slowed to the speed limit. A run of
        source frames never needs this (the limit is the source's own played speed). Joints
        whose :func:`~creatures.motor.quaternion.squad_rate_bound` keeps them within what
        their segment's duration allows are not sampled and count as 0: they could not
        lengthen it.
        """
        q1, q2, s1, s2 = self.keys[:-1], self.keys[1:], self.controls[:-1], self.controls[1:]
        return quat.squad_rate(q1, q2, s1, s2, above=(durations * max_speed)[:, None]).max(axis=-1)

    @staticmethod
    def _first_gap(graph: MotorGraph, start: GraphPosition, first: int) -> float:
        """Seconds from the start position to the first path node."""
        if start.next is None or start.fraction in (0.0, 1.0):
            return 0.0
        whole = float(transit_times(graph, np.array([start.node]), np.array([start.next]))[0])
        share = 1.0 - start.fraction if first == start.next else start.fraction
        return share * whole

    @property
    def end_time(self) -> float:
        return float(self.key_times[-1])

    def done(self, t: float) -> bool:
        return t >= self.end_time

    def _segments(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Segment index and the fraction ``u`` along it for each time (compiled: a tick asks
        for one or two times, where numpy's per-call overhead was most of the cost)."""
        return _segments(self.key_times, np.ascontiguousarray(times, dtype=float))

    def sample_rotations(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rotations ``(T, J, 4)`` and roots ``(T, 3)`` at many clock times at once."""
        times = np.asarray(times, dtype=float)
        seg, u = self._segments(times)
        if len(self.keys) == 1:
            return np.broadcast_to(self.keys[0], (len(times), *self.keys[0].shape)).copy(), np.tile(self.roots[0], (len(times), 1))
        rotations = quat.squad_keys(self.keys, self.controls, seg, u)
        alpha = u[:, None]
        roots = (1.0 - alpha) * self.roots[seg] + alpha * self.roots[seg + 1]
        return rotations, roots

    def sample(self, t: float, *, dt: float = 1e-3) -> BodyPose:
        """The BodyPose at clock time ``t`` (held at the ends); velocities by differencing."""
        rotations, roots = self.sample_rotations(np.array([t, t + dt]))
        position = self.position(t)
        return BodyPose(
            rotations=rotations[0],
            velocities=quat.log(quat.multiply(rotations[1], quat.conjugate(rotations[0]))) / dt,
            root=roots[0],
            time=t,
            source="playback",
            labels=self.graph.poses.labels[position.node] if position.next is None else frozenset(),
            skeleton=self.graph.skeleton,
        )

    def position(self, t: float) -> GraphPosition:
        """Where on the graph the body is at time ``t`` ("this far between node n and m")."""
        seg, u = self._segments(np.array([t]))
        seg, u = int(seg[0]), float(u[0])
        if t >= self.end_time or len(self.keys) == 1:
            return GraphPosition(int(self.key_nodes[-1]))
        if seg == 0:
            start = self.path.start
            if start.next is None or start.fraction in (0.0, 1.0):
                return GraphPosition(int(self.key_nodes[0]))
            first = int(self.key_nodes[0])
            if first == start.next:
                return GraphPosition(start.node, start.next, start.fraction + u * (1.0 - start.fraction))
            return GraphPosition(start.node, start.next, start.fraction * (1.0 - u))
        a, b = int(self.key_nodes[seg - 1]), int(self.key_nodes[seg])
        return GraphPosition(a, b, u) if u > 0.0 else GraphPosition(a)

    def visited(self, t: float) -> list[int]:
        """Path nodes reached by time ``t`` (what a BodyMemory records)."""
        return self.key_nodes[: int(np.searchsorted(self.key_times[1:], t, side="right"))].tolist()


_TRANSITS: weakref.WeakKeyDictionary[MotorGraph, tuple[int, dict[tuple[int, int], float]]] = (
    weakref.WeakKeyDictionary()
)


def transit_times(graph: MotorGraph, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``graph.transit_times(a, b)``, remembered per graph version.

    A transit time depends only on its two nodes, and courses keep stepping along the same
    edges (the soak sets thousands of courses over the shared graph's ~1,400 edges), so each
    pair is estimated once; any edit to the graph starts the memo afresh.
    """
    version, known = _TRANSITS.get(graph, (-1, {}))
    if version != graph.version:
        known = {}
        _TRANSITS[graph] = (graph.version, known)
    pairs = list(zip(np.asarray(a).tolist(), np.asarray(b).tolist()))
    missing = list(dict.fromkeys(pair for pair in pairs if pair not in known))
    if missing:
        new = np.array(missing, dtype=np.int64)
        known.update(zip(missing, graph.transit_times(new[:, 0], new[:, 1]).tolist()))
    return np.array([known[pair] for pair in pairs], dtype=float)


@numba.njit(cache=True)
def _segments(key_times, times):  # pragma: no cover - compiled
    """For each time, the key segment it falls in (clamped to the ends) and how far along."""
    last = max(key_times.shape[0] - 2, 0)
    segments = np.empty(times.shape[0], dtype=np.int64)
    fractions = np.zeros(times.shape[0])
    for i in range(times.shape[0]):
        k = min(max(np.searchsorted(key_times, times[i], side="right") - 1, 0), last)
        segments[i] = k
        if key_times.shape[0] > 1:
            span = key_times[k + 1] - key_times[k]
            fractions[i] = min(max((times[i] - key_times[k]) / span, 0.0), 1.0) if span > 0.0 else 1.0
    return segments, fractions
