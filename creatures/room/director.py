"""The director's controls (REACT 3.3.5, "Control movement, behaviour, states and styles":
explicit control laid over the agents' own choices): paths with a radius the crowd may
deviate by (REACTPath) and painted flow fields (REACTFlowfield); the zones that change a
creature while it is inside them (REACTActionBox) are :mod:`.zones`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Path:
    """A polyline of ``points`` (P ≥ 2, metres) and the ``radius`` (m) the crowd may stray from it."""

    points: np.ndarray
    radius: float

    def __post_init__(self) -> None:
        if len(self.points) < 2:
            raise ValueError("a path needs at least two points")


@dataclass(frozen=True)
class FlowField:
    """Directions over a grid of ``cell``-metre squares from the room's corner, (rows, cols, 2)."""

    directions: np.ndarray
    cell: float | tuple[float, float]
    """A square cell's side, or (across, deep) for a painted field stretched over the room."""

    @classmethod
    def uniform(cls, room_size: np.ndarray, cell: float, direction: tuple[float, float]) -> "FlowField":
        """One direction everywhere."""
        rows, cols = (int(np.ceil(room_size[1] / cell)), int(np.ceil(room_size[0] / cell)))
        return cls(np.broadcast_to(np.asarray(direction, float), (rows, cols, 2)).copy(), cell)

    @classmethod
    def painted(cls, room_size: np.ndarray, rows: list[str]) -> "FlowField":
        """A director's plan of the room in arrows (``FlowSpec.rows``: the first row along the
        back wall), stretched over the floor: REACTFlowfield's painted field, written as text
        so that it reads like the room seen from above with the audience at the bottom."""
        arrows = {">": (1.0, 0.0), "<": (-1.0, 0.0), "^": (0.0, 1.0), "v": (0.0, -1.0), ".": (0.0, 0.0)}
        grid = np.array([[arrows[c] for c in row] for row in reversed(rows)], dtype=float)  # row 0 at y = 0
        return cls(grid, (float(room_size[0]) / grid.shape[1], float(room_size[1]) / grid.shape[0]))

    @classmethod
    def vortex(cls, room_size: np.ndarray, cell: float, clockwise: bool = False) -> "FlowField":
        """Circulation around the room's centre (a crowd that mills round the room)."""
        rows, cols = (int(np.ceil(room_size[1] / cell)), int(np.ceil(room_size[0] / cell)))
        y, x = np.mgrid[0:rows, 0:cols]
        rel = np.stack([(x + 0.5) * cell - room_size[0] / 2, (y + 0.5) * cell - room_size[1] / 2], axis=-1)
        tangent = np.stack([-rel[..., 1], rel[..., 0]], axis=-1) * (-1 if clockwise else 1)
        return cls(tangent / np.maximum(np.linalg.norm(tangent, axis=-1, keepdims=True), 1e-9), cell)
