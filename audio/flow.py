"""A motion flow field between bodies and strings: the first of the thesis's two connections
("artificial gestural control": "we can have the nearby movement of a character's limbs affect
a number of synthetic strings … by embedding both character and string inside a motion flow
simulation – a particularly cheap fluid dynamics system which discretely simulate a dispersion
and propagation of movement throughout a plane"; figure 48).

The field is the movement along the strings' transverse axis, on a grid over the plane the
strings lie in (their length and that axis), a margin around them. Each limb drags the fluid
where it is toward its own velocity (a Gaussian splat of ``radius``); the field diffuses
(``diffusion`` m²/s: dispersion, so movement reaches farther strings later and weaker) and
decays (half-life ``memory`` s), integrated on clock time in stable sub-steps; each string
mass is pushed by the field where it lies. So a limb moving a metre away still moves a
string, after the time the movement takes to spread there, where direct coupling
(:class:`~audio.coupling.BodyCoupling`) reaches only ``radius``.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from audio.coupling import BodyCoupling, PoseLike

CELL = 0.05
"""Grid spacing, metres."""
MARGIN = 1.0
"""Metres of field beyond the strings on every side."""


class FlowCoupling(BodyCoupling):
    """:class:`BodyCoupling`'s interface, with the limbs' movement carried by a flow field."""

    def __init__(self, node_positions: np.ndarray, *, diffusion: float = 0.2, memory: float = 0.5,
                 **kwargs) -> None:
        super().__init__(node_positions, **kwargs)
        if not (diffusion > 0 and memory > 0):
            raise ValueError(f"diffusion and memory must be positive (got {diffusion}, {memory})")
        self.diffusion, self.memory = float(diffusion), float(memory)
        along = self.nodes[-1] - self.nodes[0]
        norm = np.linalg.norm(along)
        self.along = along / norm if norm > 1e-12 else np.cross(self.axis, [0.0, 0.0, 1.0])
        plane = self._plane(self.nodes)
        self.low = plane.min(axis=0) - MARGIN
        size = np.ceil((plane.max(axis=0) + MARGIN - self.low) / CELL).astype(int) + 1
        self.field = np.zeros((size[0], size[1]))  # movement along the axis, m/s
        self._nodes_in_field = self._bilinear((plane - self.low) / CELL)  # the strings never move in it

    def _plane(self, points: np.ndarray) -> np.ndarray:
        """Coordinates of ``points`` (N, 3) in the strings' plane: along them, along the axis."""
        return np.stack([points @ self.along, points @ self.axis], axis=1)

    def forces(self, pose: PoseLike) -> np.ndarray:
        moved = self._motion(pose)
        if moved is None:
            return np.zeros(len(self.nodes))
        positions, step, dt = moved
        self._drag(self._plane(positions), step @ self.axis / dt)
        self._spread(dt)
        i, j, weights = self._nodes_in_field
        f = self.field
        return self.gain * (weights[0] * f[i, j] + weights[1] * f[i + 1, j] + weights[2] * f[i, j + 1]
                            + weights[3] * f[i + 1, j + 1])

    def _drag(self, places: np.ndarray, speeds: np.ndarray) -> None:
        """Each limb pulls the fluid near it toward its own speed (compiled: a curve tick's
        costliest part was this, one Gaussian over the field per limb)."""
        nx, ny = self.field.shape
        xs = self.low[0] + CELL * np.arange(nx)
        ys = self.low[1] + CELL * np.arange(ny)
        _drag(self.field, xs, ys, np.ascontiguousarray(places, dtype=float), np.asarray(speeds, dtype=float),
              self.radius)

    def _spread(self, dt: float) -> None:
        """Diffuse and decay over ``dt`` seconds (explicit, stable sub-steps; edges absorb)."""
        steps = max(1, math.ceil(dt * self.diffusion / (0.2 * CELL * CELL)))
        rate = self.diffusion * (dt / steps) / (CELL * CELL)
        _spread(self.field, steps, rate, 0.5 ** (dt / self.memory))

    def _bilinear(self, cells: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Where fractional grid ``cells`` read the field: each one's lower corner ``(i, j)`` and
        its four corners' bilinear weights ``(4, N)`` (in the order i,j; i+1,j; i,j+1; i+1,j+1)."""
        nx, ny = self.field.shape
        i = np.clip(np.floor(cells[:, 0]).astype(int), 0, nx - 2)
        j = np.clip(np.floor(cells[:, 1]).astype(int), 0, ny - 2)
        a = np.clip(cells[:, 0] - i, 0, 1)
        b = np.clip(cells[:, 1] - j, 0, 1)
        return i, j, np.stack([(1 - a) * (1 - b), a * (1 - b), (1 - a) * b, a * b])


@numba.njit(cache=True)
def _drag(field, xs, ys, places, speeds, radius):  # pragma: no cover - compiled
    """:meth:`FlowCoupling._drag`'s loop: field += exp(-½((x−xᵢ)² + (y−yᵢ)²)/r²) (speedᵢ − field)."""
    for k in range(places.shape[0]):
        wx = np.exp(-0.5 * ((xs - places[k, 0]) / radius) ** 2)
        wy = np.exp(-0.5 * ((ys - places[k, 1]) / radius) ** 2)
        if wx.max() < 1e-3 or wy.max() < 1e-3:
            continue  # outside the field
        for i in range(field.shape[0]):
            for j in range(field.shape[1]):
                field[i, j] += wx[i] * wy[j] * (speeds[k] - field[i, j])


@numba.njit(cache=True)
def _spread(field, steps, rate, decay):  # pragma: no cover - compiled
    """Explicit 5-point diffusion ``steps`` times (edges absorb), then decay."""
    nx, ny = field.shape
    lap = np.empty_like(field)
    for _ in range(steps):
        for i in range(nx):
            for j in range(ny):
                value = -4.0 * field[i, j]
                if i > 0:
                    value += field[i - 1, j]
                if i < nx - 1:
                    value += field[i + 1, j]
                if j > 0:
                    value += field[i, j - 1]
                if j < ny - 1:
                    value += field[i, j + 1]
                lap[i, j] = value
        field += rate * lap
    field *= decay
