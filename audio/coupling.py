"""Bodies driving synthesis: thesis "artificial gestural control" and *soundcreatures*.

Two connections, both reading only ``pose.positions`` (world joint positions, ``(J, 3)``)
and ``pose.time`` — any BodyPose-like object will do:

* :class:`BodyCoupling` — the "nearby movement of a character's limbs affect a number of
  synthetic strings": a string lies in space, and each moving joint pushes the nodes near
  it along the string's transverse axis. Only *movement* pushes (force ∝ joint velocity),
  so a still body leaves the string to ring down — the motion-flow reading of the thesis,
  not a static obstacle.
* :class:`BodyControl` — *soundcreatures*' "labelled positions on the animated body
  control parameters such as amplitude modulation (e.g. rib cage) and a simple low-pass
  filter (e.g. back angle)": a body feature (a distance or an angle) mapped linearly and
  clamped into a parameter range.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable, Protocol

import numpy as np
from numpy.typing import ArrayLike

from creatures.motor.spline import catmull_rom, sample


class PoseLike(Protocol):
    """What coupling needs of a BodyPose (see ``creatures/motor/pose.py``)."""

    positions: np.ndarray
    time: float


class BodyCoupling:
    """Joint velocities near a string's nodes become forces on those nodes.

    Parameters
    ----------
    node_positions : (N, 3) array
        Rest position in space of each string mass.
    axis : (3,) array
        Transverse direction in which the string moves; only velocity along it pushes.
    radius : float
        Gaussian reach of a joint (same units as positions).
    gain : float
        Force per unit velocity at zero distance.
    joints : sequence of int, optional
        Which joints couple (default all), e.g. a creature's hands only.
    """

    def __init__(self, node_positions: np.ndarray, *, axis: ArrayLike = (0.0, 1.0, 0.0), radius: float = 0.2,
                 gain: float = 50.0, joints: np.ndarray | list[int] | None = None) -> None:
        self.nodes = np.asarray(node_positions, dtype=float)
        if self.nodes.ndim != 2 or self.nodes.shape[1] != 3:
            raise ValueError(f"node_positions must be (N, 3), got {self.nodes.shape}")
        axis = np.asarray(axis, dtype=float)
        norm = np.linalg.norm(axis)
        if axis.shape != (3,) or not norm > 0:
            raise ValueError(f"axis must be a non-zero 3-vector, got {axis!r}")
        if not radius > 0:
            raise ValueError(f"radius must be > 0, got {radius!r}")
        self.axis = axis / norm
        self.radius = float(radius)
        self.gain = float(gain)
        self.joints = None if joints is None else np.asarray(joints, dtype=np.int64)
        self._last: tuple[np.ndarray, float] | None = None

    @classmethod
    def along(cls, start: ArrayLike, end: ArrayLike, n_masses: int, **kwargs: Any) -> BodyCoupling:
        """A string stretched in a straight line from ``start`` to ``end``."""
        t = np.linspace(0.0, 1.0, n_masses)[:, None]
        return cls((1.0 - t) * np.asarray(start, float) + t * np.asarray(end, float), **kwargs)

    def _motion(self, pose: PoseLike) -> tuple[np.ndarray, np.ndarray, float] | None:
        """The coupled joints' positions ``(J, 3)``, their step since the previous pose and the
        clock time between; ``None`` for the first pose, one at the same time, or a changed body."""
        positions = np.asarray(pose.positions, dtype=float)
        if self.joints is not None:
            positions = positions[self.joints]
        t = float(pose.time)
        last, self._last = self._last, (positions.copy(), t)
        if last is None or last[0].shape != positions.shape or not t > last[1]:
            return None
        return positions, positions - last[0], t - last[1]

    def forces(self, pose: PoseLike) -> np.ndarray:
        """Per-node force ``(N,)`` from the joints' motion since the previous pose.

        Velocities are differences of ``positions`` over elapsed ``pose.time`` (clock time,
        never tick counts); the first pose, or one at the same time, pushes nothing.
        """
        moved = self._motion(pose)
        if moved is None:
            return np.zeros(len(self.nodes))
        positions, step, dt = moved
        velocity = step / dt  # (J, 3)
        offsets = positions[None, :, :] - self.nodes[:, None, :]  # (N, J, 3)
        weights = np.exp(-0.5 * np.einsum("njk,njk->nj", offsets, offsets) / self.radius**2)
        return self.gain * weights @ (velocity @ self.axis)


class BodyShape:
    """The body *as* the string (thesis, "artificial gestural control": "Secondly we can relate
    the body of a creature to the body of the string itself through the *curve* extensions …
    either directly or through a spring system. Thus our body pose representations become
    timbral representations").

    The body's line (``joints``, e.g. the chain from the root to the effector) is the spline
    the line renderer draws through them (:mod:`creatures.motor.spline`), resampled by arc
    length to the string's masses, and its bend — each point's distance from the chord
    between its ends, along the line's main transverse direction, per unit length — becomes a
    per-mass force of ``gain × centring``: with the string's own centring spring that is a
    spring from each mass to the body's line (the string's rest shape *is* the body, ×
    ``gain``), so the scan reads the body's shape and the timbre follows the pose. A straight
    body leaves the string at rest; a bent one holds a steady, shaped waveform.
    """

    def __init__(self, joints: np.ndarray | list[int], n_masses: int, *, gain: float, centring: float) -> None:
        self.joints = np.asarray(joints, dtype=np.int64)
        if len(self.joints) < 2:
            raise ValueError("a body's line needs at least two joints")
        self.n = int(n_masses)
        self.scale = float(gain) * float(centring)
        # The spline the line renderer draws is linear in the joints it passes through: its
        # sampled points are one fixed matrix times them (each curve tick bends the string).
        basis = np.zeros((len(self.joints), len(self.joints), 3))
        basis[np.arange(len(self.joints)), np.arange(len(self.joints)), 0] = 1.0
        self._spline = np.stack([sample(catmull_rom(b))[:, 0] for b in basis], axis=1)  # (points, joints)
        self._at = np.linspace(0.0, 1.0, self.n)

    def bend(self, positions: np.ndarray) -> np.ndarray:
        """The line's transverse bend at each mass, per unit of its length ``(n,)``."""
        points = self._spline @ np.asarray(positions, dtype=float)[self.joints]  # the line as drawn: a spline
        step = points[1:] - points[:-1]
        along = np.empty(len(points))
        along[0] = 0.0
        np.cumsum(np.sqrt(np.einsum("ij,ij->i", step, step)), out=along[1:])
        if not along[-1] > 0:
            return np.zeros(self.n)
        at = self._at * along[-1]
        line = np.column_stack((np.interp(at, along, points[:, 0]), np.interp(at, along, points[:, 1]),
                                np.interp(at, along, points[:, 2])))
        chord = line[-1] - line[0]
        length = math.sqrt(chord @ chord)
        u = chord / length if length > 1e-12 else np.array([1.0, 0.0, 0.0])
        offset = line - line[0]
        residual = offset - np.outer(offset @ u, u)
        if not np.abs(residual).max() > 1e-12:
            return np.zeros(self.n)
        # the main transverse direction: the residual's first right singular vector, the top
        # eigenvector of its 3 × 3 scatter (an SVD of the n × 3 residual cost twice as much)
        _, vectors = np.linalg.eigh(residual.T @ residual)
        axis = vectors[:, -1]
        side = axis[0] * u[1] - axis[1] * u[0]  # axis · (u × z)
        normal = axis if side >= 0 else -axis  # one sign across poses
        return residual @ normal / along[-1]

    def forces(self, pose: PoseLike) -> np.ndarray:
        """Per-mass force holding the string in the body's shape."""
        return self.scale * self.bend(pose.positions)


def joint_distance(a: int, b: int) -> Callable[[np.ndarray], float]:
    """Feature: distance between joints ``a`` and ``b`` (e.g. rib-cage expansion)."""
    return lambda positions: float(np.linalg.norm(positions[a] - positions[b]))


def joint_angle(a: int, vertex: int, b: int) -> Callable[[np.ndarray], float]:
    """Feature: angle in radians at ``vertex`` between the bones to ``a`` and ``b`` (e.g. back angle)."""

    def angle(positions: np.ndarray) -> float:
        u, w = positions[a] - positions[vertex], positions[b] - positions[vertex]
        cos = u @ w / max(np.linalg.norm(u) * np.linalg.norm(w), 1e-12)
        return float(np.arccos(np.clip(cos, -1.0, 1.0)))

    return angle


@dataclass
class BodyControl:
    """A body feature mapped linearly from ``[low, high]`` onto ``[out_low, out_high]``, clamped."""

    feature: Callable[[np.ndarray], float]
    low: float
    high: float
    out_low: float
    out_high: float

    def __post_init__(self) -> None:
        if self.high == self.low:
            raise ValueError(f"BodyControl needs low != high, got {self.low!r}")

    def __call__(self, pose: PoseLike) -> float:
        u = (self.feature(np.asarray(pose.positions, dtype=float)) - self.low) / (self.high - self.low)
        return self.out_low + min(max(u, 0.0), 1.0) * (self.out_high - self.out_low)
