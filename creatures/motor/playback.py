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

import numpy as np

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
        durations = graph.transit_times(nodes[:-1], nodes[1:])
        self.key_nodes = nodes
        self.keys = quat.hemisphere_align(np.concatenate((rotations[None], graph.poses.rotations[nodes])))
        self.controls = quat.squad_controls(self.keys)
        self.roots = np.concatenate((root[None], graph.poses.roots[nodes]))
        # Squad bends each segment towards its neighbours, so next to a sharp turn it can
        # outrun the edge's own timing: slow such a segment to the speed limit. A run of
        # source frames never needs this (the limit is the source's own played speed).
        turns = quat.squad_rate(self.keys[:-1], self.keys[1:], self.controls[:-1], self.controls[1:]).max(axis=-1)
        gaps = np.maximum(np.concatenate(([first_gap], durations)), turns / graph.timing.max_speed)
        self.key_times = start_time + np.concatenate(([0.0], np.cumsum(gaps / speed)))

    @staticmethod
    def _first_gap(graph: MotorGraph, start: GraphPosition, first: int) -> float:
        """Seconds from the start position to the first path node."""
        if start.next is None or start.fraction in (0.0, 1.0):
            return 0.0
        whole = float(graph.transit_times(np.array([start.node]), np.array([start.next]))[0])
        share = 1.0 - start.fraction if first == start.next else start.fraction
        return share * whole

    @property
    def end_time(self) -> float:
        return float(self.key_times[-1])

    def done(self, t: float) -> bool:
        return t >= self.end_time

    def _segments(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        seg = np.clip(np.searchsorted(self.key_times, times, side="right") - 1, 0, max(len(self.keys) - 2, 0))
        if len(self.keys) == 1:
            return seg, np.zeros_like(times)
        span = self.key_times[seg + 1] - self.key_times[seg]
        u = np.where(span > 0.0, (times - self.key_times[seg]) / np.where(span > 0.0, span, 1.0), 1.0)
        return seg, np.clip(u, 0.0, 1.0)

    def sample_rotations(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rotations ``(T, J, 4)`` and roots ``(T, 3)`` at many clock times at once."""
        times = np.asarray(times, dtype=float)
        seg, u = self._segments(times)
        if len(self.keys) == 1:
            return np.broadcast_to(self.keys[0], (len(times), *self.keys[0].shape)).copy(), np.tile(self.roots[0], (len(times), 1))
        alpha = u[:, None]
        rotations = quat.squad(
            self.keys[seg], self.keys[seg + 1], self.controls[seg], self.controls[seg + 1], alpha
        )
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
