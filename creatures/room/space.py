"""The room: a rectangle of floor with walls and round obstacles (REACT's REACTBarrier and
REACTObstacle), and the one rule everything inside obeys: nothing leaves it.

Coordinates are metres on the floor plane, x across (0..width) and y deep (0..depth); the
height of bodies and speakers is not modelled (a room's sound and sight are planar here).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Obstacle:
    """A round obstacle (a pillar, a plinth): centre and radius, metres."""

    x: float
    y: float
    radius: float


@dataclass(frozen=True)
class Room:
    """A ``width`` × ``depth`` m room and its obstacles."""

    width: float
    depth: float
    obstacles: tuple[Obstacle, ...] = field(default_factory=tuple)

    def __post_init__(self) -> None:
        if not (self.width > 0 and self.depth > 0):
            raise ValueError(f"a room needs a positive size (got {self.width} x {self.depth} m)")

    @property
    def size(self) -> np.ndarray:
        return np.array([self.width, self.depth])

    @property
    def centres(self) -> np.ndarray:
        """Obstacle centres, (O, 2)."""
        return np.array([[o.x, o.y] for o in self.obstacles], dtype=float).reshape(-1, 2)

    @property
    def radii(self) -> np.ndarray:
        """Obstacle radii, (O,)."""
        return np.array([o.radius for o in self.obstacles], dtype=float)

    def contain(self, pos: np.ndarray, vel: np.ndarray, radius: np.ndarray) -> None:
        """Keep bodies of ``radius`` inside the walls and out of the obstacles, in place.

        Steering (wall and obstacle avoidance) is what keeps creatures away; this is the hard
        constraint beneath it, so that no force setting can put a creature through a wall: a
        body that reaches a wall stops there and loses the velocity into it (an inelastic
        contact, which looks like a creature pausing against the wall rather than bouncing)."""
        r = radius[:, None]
        low, high = r, self.size[None, :] - r
        out_low, out_high = pos < low, pos > high
        np.clip(pos, low, high, out=pos)
        vel[out_low & (vel < 0)] = 0.0
        vel[out_high & (vel > 0)] = 0.0
        if self.obstacles:
            self._push_out(pos, vel, radius)

    def _push_out(self, pos: np.ndarray, vel: np.ndarray, radius: np.ndarray) -> None:
        """Bodies overlapping an obstacle are moved to its rim and lose the velocity into it."""
        d = pos[:, None, :] - self.centres[None, :, :]  # (N, O, 2)
        dist = np.hypot(d[..., 0], d[..., 1])
        reach = radius[:, None] + self.radii[None, :]
        inside = dist < reach
        if not inside.any():
            return
        for i, o in zip(*np.nonzero(inside)):
            normal = d[i, o] / dist[i, o] if dist[i, o] > 1e-12 else np.array([1.0, 0.0])
            pos[i] = self.centres[o] + normal * reach[i, o]
            into = vel[i] @ normal
            if into < 0:
                vel[i] -= into * normal
        r = radius[:, None]
        np.clip(pos, r, self.size[None, :] - r, out=pos)

    def standing_room(self, radius: float) -> np.ndarray:
        """The places where a body of ``radius`` may stand, inside the walls and off every
        obstacle, (K, 2); none (K = 0) when the obstacles cover the floor.

        Not a sample: if any such place exists, one is a corner of the free floor (a corner of
        the walls, a wall crossing an obstacle's reach, or two reaches crossing), since the
        free floor is what lies outside round discs, whose arcs bulge into it. Those are the
        candidates kept, so a gap of a few centimetres is found where random draws miss it."""
        low, high = np.full(2, radius), self.size - radius
        reach = self.radii + radius
        points = [np.array([[x, y] for x in (low[0], high[0]) for y in (low[1], high[1])])]
        for axis, wall in itertools.product(range(2), (0, 1)):
            at = (low, high)[wall][axis]
            off = at - self.centres[:, axis]
            half = np.sqrt(np.clip(reach ** 2 - off ** 2, 0.0, None))[off ** 2 <= reach ** 2]
            along = self.centres[off ** 2 <= reach ** 2, 1 - axis]
            for sign in (-1.0, 1.0):
                p = np.empty((len(half), 2))
                p[:, axis], p[:, 1 - axis] = at, along + sign * half
                points.append(p)
        a, b = np.triu_indices(len(reach), 1)
        gap = self.centres[b] - self.centres[a]
        d = np.hypot(gap[:, 0], gap[:, 1])
        meet = (d > 0) & (d <= reach[a] + reach[b]) & (d >= np.abs(reach[a] - reach[b]))
        a, b, gap, d = a[meet], b[meet], gap[meet], d[meet]
        along = (reach[a] ** 2 - reach[b] ** 2 + d ** 2) / (2 * d)
        across = np.sqrt(np.clip(reach[a] ** 2 - along ** 2, 0.0, None))
        mid = self.centres[a] + gap * (along / d)[:, None]
        normal = np.stack([-gap[:, 1], gap[:, 0]], axis=1) / d[:, None]
        points += [mid + normal * across[:, None], mid - normal * across[:, None]]
        p = np.concatenate(points)
        p = p[np.all((p >= low - 1e-9) & (p <= high + 1e-9), axis=1)]
        if len(reach):
            dist = np.hypot(*(p[:, None, :] - self.centres[None, :, :]).transpose(2, 0, 1))
            p = p[np.all(dist >= reach[None, :] - 1e-9, axis=1)]
        return np.clip(p, low, high)

    def inside(self, pos: np.ndarray) -> np.ndarray:
        """Which points are on the floor (walls included), (N,) bool."""
        return np.all((pos >= 0) & (pos <= self.size[None, :]), axis=1)
