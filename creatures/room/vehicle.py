"""The vehicle model (Reynolds 1999, "Steering Behaviors for Autonomous Characters"; REACT
2.2.1 "Locomotion"): each creature is a point mass with a maximum force and a maximum speed,
and a heading that turns toward its velocity at a bounded rate.

Every creature's state is a row of arrays (:class:`Vehicles`) so that one sub-step moves the
whole crowd in a few numpy operations, never a Python loop over creatures.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

EPS = 1e-9


def norms(v: np.ndarray) -> np.ndarray:
    """Lengths of the rows of ``v`` (..., 2) → (...)."""
    return np.hypot(v[..., 0], v[..., 1])  # 2-3x faster than sqrt(sum(v*v)) for (M, 2) rows


def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot products of 2-vectors, broadcast (..., 2) · (..., 2) → (...)."""
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1]


def truncate(v: np.ndarray, limit: np.ndarray | float) -> np.ndarray:
    """``v``'s rows shortened to at most ``limit`` (OpenSteer's ``truncateLength``)."""
    n = norms(v)
    scale = np.minimum(1.0, np.asarray(limit) / np.maximum(n, EPS))
    return v * scale[..., None]


def unit(v: np.ndarray) -> np.ndarray:
    """``v``'s rows as unit vectors (zero rows stay zero)."""
    return v / np.maximum(norms(v), EPS)[..., None]


@dataclass
class Vehicles:
    """The crowd's bodies, one row per creature: position and velocity (m, m/s), unit heading,
    mass (kg), maximum steering force (N), maximum speed (m/s), body radius (m) and maximum
    turn rate (rad/s)."""

    pos: np.ndarray
    vel: np.ndarray
    heading: np.ndarray
    mass: np.ndarray
    max_force: np.ndarray
    max_speed: np.ndarray
    radius: np.ndarray
    max_turn: np.ndarray

    @classmethod
    def at(cls, pos: np.ndarray, heading: np.ndarray | None = None, *, mass: float | np.ndarray = 1.0,
           max_force: float | np.ndarray = 2.0, max_speed: float | np.ndarray = 1.0,
           radius: float | np.ndarray = 0.25, max_turn: float | np.ndarray = 2 * np.pi) -> "Vehicles":
        """Vehicles at rest at ``pos`` (N, 2), facing ``heading`` (default +x)."""
        pos = np.array(pos, dtype=float).reshape(-1, 2)
        n = len(pos)
        h = np.tile([1.0, 0.0], (n, 1)) if heading is None else unit(np.array(heading, dtype=float))

        def col(x: float | np.ndarray) -> np.ndarray:
            return np.broadcast_to(np.asarray(x, dtype=float), (n,)).copy()

        return cls(pos, np.zeros((n, 2)), h, col(mass), col(max_force), col(max_speed), col(radius), col(max_turn))

    def __len__(self) -> int:
        return len(self.pos)

    def speed(self) -> np.ndarray:
        return norms(self.vel)

    def step(self, force: np.ndarray, dt: float | np.ndarray) -> None:
        """Apply ``force`` (N, 2) for ``dt`` seconds (semi-implicit Euler: velocity first, then
        position with the new velocity, which is stable for the stiff spring that arrival is).

        The force is truncated to ``max_force`` and the velocity to ``max_speed`` (Reynolds'
        locomotion layer); the heading then turns toward the velocity by at most
        ``max_turn * dt`` (IViHumans' bounded turning: a body cannot spin on the spot)."""
        dt = np.asarray(dt, dtype=float)
        dtc = dt[..., None] if dt.ndim else dt
        acc = truncate(force, self.max_force) / self.mass[:, None]
        self.vel = truncate(self.vel + acc * dtc, self.max_speed)
        self.pos += self.vel * dtc
        self.face(dt)

    def face(self, dt: float | np.ndarray) -> None:
        """Turn each heading toward its velocity by at most ``max_turn × dt`` radians."""
        moving = norms(self.vel) > 1e-3
        if not moving.any():
            return
        want = np.arctan2(self.vel[:, 1], self.vel[:, 0])
        have = np.arctan2(self.heading[:, 1], self.heading[:, 0])
        turn = (want - have + np.pi) % (2 * np.pi) - np.pi
        limit = self.max_turn * dt
        new = have + np.clip(turn, -limit, limit)
        self.heading = np.where(moving[:, None], np.stack([np.cos(new), np.sin(new)], axis=1), self.heading)
