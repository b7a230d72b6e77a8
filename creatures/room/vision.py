"""Sight in the room (REACT 3.3.5, "Interpret percept": the organizer answers an agent's
range search over its vision cone; obstacles hide what is behind them).

:func:`visible` says which of K things each of M eyes sees: within ``range`` m, within half
of ``fov`` degrees of the eye's heading, and with no obstacle across the line between them.
"""

from __future__ import annotations

import numpy as np

from creatures.room.space import Room
from creatures.room.vehicle import EPS, dot, norms


def occluded(a: np.ndarray, b: np.ndarray, room: Room) -> np.ndarray:
    """(M, K): whether the segment from each ``a`` (M, 2) to each ``b`` (K, 2) passes through
    an obstacle (closer than its radius to the centre at some point of the segment)."""
    if not room.obstacles:
        return np.zeros((len(a), len(b)), dtype=bool)
    ab = b[None, :, None, :] - a[:, None, None, :]  # (M, K, 1, 2)
    ac = room.centres[None, None, :, :] - a[:, None, None, :]  # (M, 1, O, 2)
    t = np.clip(dot(ac, ab) / np.maximum(dot(ab, ab), EPS), 0.0, 1.0)  # (M, K, O)
    closest = ab * t[..., None] - ac
    return (norms(closest) < room.radii[None, None, :]).any(-1)


def visible(eye: np.ndarray, heading: np.ndarray, things: np.ndarray, room: Room, *, fov: float = 120.0,
            range_: float = 10.0) -> np.ndarray:
    """(M, K): which ``things`` (K, 2) each eye (M, 2; unit ``heading`` (M, 2)) sees: in
    range, inside the cone of ``fov`` degrees, and not behind an obstacle."""
    rel = things[None, :, :] - eye[:, None, :]
    d = norms(rel)
    facing = dot(rel, heading[:, None, :]) >= np.cos(np.radians(fov) / 2) * d
    seen = (d <= range_) & facing & (d > EPS)
    if seen.any():
        seen &= ~occluded(eye, things, room)
    return seen
