"""Walking bodies in the room: the gait's speed and the body's root follow the vehicle.

``[creature.vehicle] gait = "walk"`` names a clip of the creature's body that travels (root
motion, :mod:`creatures.motor.root_motion`). In the room the vehicle decides where the creature
goes (REACT's steering); the body's walk is then played by *distance*, not by time: its phase
moves on by the metres the vehicle covered, so a creature walking twice as fast steps twice as
often, and the foot on the ground stays where it was put (IViHumans' speed-matched
locomotion; the thesis's "graph-based motor systems": a walk's travel is its source's own).
Played by time at the clip's own pace instead, a paw slides by the difference between the
vehicle's speed and the clip's (tests/test_room_gait.py measures both).

The walk's nodes stand in place facing +z (their travel is kept apart as per-node advances),
so a pose is drawn by turning it to the vehicle's heading and putting it at its position:
room (x, y) is the world's floor (x, −z) (:func:`in_room`). Clones of one creature (``count = N``) start at
seeded random phases, so a crowd does not step in lock-step. A creature standing still shows
its own pose (its courses, its layers), and the walk fades in over the first few centimetres
per second of speed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from creatures.config import nearest
from creatures.motor.graph import MotorGraph

STILL = 0.02
"""Speed, m/s, at or under which a creature shows its own pose, not its walk."""
WALKING = 0.1
"""Speed, m/s, from which the walk is the whole pose (a linear fade from :data:`STILL`)."""


@dataclass(frozen=True)
class Walk:
    """One cycle of a walking clip: its nodes' in-place joint positions and the distance walked
    at each (from 0 at the first node to :attr:`stride` at the last)."""

    positions: np.ndarray  # (K + 1, J, 3), facing +z, root over the origin
    along: np.ndarray  # (K + 1,) metres

    @property
    def stride(self) -> float:
        return float(self.along[-1])

    @classmethod
    def of(cls, graph: MotorGraph, clip: str) -> "Walk":
        """The walk of ``graph``'s source ``clip`` (ValueError: no such clip, nearest name given,
        or a clip that does not travel)."""
        poses = graph.poses
        if clip not in poses.sources:
            raise ValueError(f"gait {clip!r} is not a clip of the body{nearest(clip, poses.sources, 'its clips')}")
        nodes = np.nonzero(poses.source_ids == poses.sources.index(clip))[0]
        nodes = nodes[np.argsort(poses.times[nodes], kind="stable")]
        steps = np.linalg.norm(graph.advances[nodes[:-1]][:, [0, 2]], axis=1)
        if len(nodes) < 2 or not steps.sum() > 0:
            raise ValueError(f"gait {clip!r} does not walk: its frames have no root motion (a clip with "
                             "root_motion = true travels)")
        return cls(poses.positions[nodes], np.concatenate(([0.0], np.cumsum(steps))))

    def pose(self, phase: float) -> np.ndarray:
        """Joint positions ``(J, 3)`` in place at ``phase`` metres into the cycle (any value:
        taken modulo the stride). Between two frames the positions are interpolated by distance."""
        d = phase % self.stride
        k = min(int(np.searchsorted(self.along, d, side="right")) - 1, len(self.along) - 2)
        share = (d - self.along[k]) / max(self.along[k + 1] - self.along[k], 1e-12)
        return (1.0 - share) * self.positions[k] + share * self.positions[k + 1]


def in_room(local: np.ndarray, at: np.ndarray, heading: np.ndarray) -> np.ndarray:
    """Body-frame joint positions ``(J, 3)`` (facing +z, its left +x, y up) turned to
    ``heading`` (a unit room vector) and put at room point ``at``. Room (x, y) is the world's
    (x, −z): with y up, that keeps the room's anticlockwise turns anticlockwise seen from above,
    so a body's left is the left of its heading (a creature that turns its head to a sound on
    its left, by :meth:`Stage._bearing`, is drawn looking at it). ``at`` and ``heading`` may
    be ``(N, 2)``: N creatures at once, ``(N, J, 3)`` (a crowd's markers, one call a tick)."""
    at, heading = np.asarray(at, float), np.asarray(heading, float)
    hx, hy = heading[..., 0, None], heading[..., 1, None]
    x, y, z = local[..., 0], local[..., 1], local[..., 2]
    # In room terms local +z goes to (hx, hy) and local +x to its left (−hy, hx).
    return np.stack([-x * hy + z * hx + at[..., 0, None], np.broadcast_to(y, np.broadcast_shapes(y.shape, hx.shape)),
                     -(x * hx + z * hy + at[..., 1, None])], axis=-1)


class Gaits:
    """The walks of a room's creatures and how far each has walked (None: no gait)."""

    def __init__(self, walks: list[Walk | None], pos: np.ndarray, rng: np.random.Generator) -> None:
        self.walks = walks
        self.phase = np.array([0.0 if w is None else rng.uniform(0.0, w.stride) for w in walks])
        self._last = pos.copy()

    def advance(self, pos: np.ndarray, largest: np.ndarray) -> None:
        """The vehicles are now at ``pos``: each walk moves on by the distance covered (straight
        between two ticks), at most ``largest`` (a vehicle's top speed over the time passed)."""
        self.phase += np.minimum(np.linalg.norm(pos - self._last, axis=1), largest)
        self._last = pos.copy()

    def moved(self, i: int, pos: np.ndarray) -> None:
        """Creature ``i`` was put at ``pos`` (its saved place): that is no walk."""
        self._last[i] = pos

    def figure(self, i: int, own: np.ndarray, at: np.ndarray, heading: np.ndarray, speed: float) -> np.ndarray:
        """Creature ``i``'s joints in the room: its walk faded in with speed over its own
        in-place pose ``own`` (all of ``own`` without a gait), turned to ``heading`` at ``at``."""
        walk = self.walks[i]
        local = own
        if walk is not None:
            weight = min(max((speed - STILL) / (WALKING - STILL), 0.0), 1.0)
            local = weight * walk.pose(self.phase[i]) + (1.0 - weight) * own
        return in_room(local, at, heading)
