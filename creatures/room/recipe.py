"""A creature's steering, as data: which behaviours, with what weights, probabilities and
parameters, combined by which policy (a ``[creature.steer]`` table; STYLE.md: behaviour is
data bound to code by name).

:data:`BEHAVIOURS` binds each name to an adapter that resolves the behaviour's target (the
nearest visitor, the nearest loud sound, a point, another creature, a path or flow field of
the director's) for the steering creatures and calls the pure function in :mod:`.steering`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from creatures.room import steering as st
from creatures.room.director import FlowField, Path

Target = str | int | tuple[float, float]
"""What a behaviour aims at: 'visitor' (the nearest), 'player' (where the last note from
outside came from, for a few seconds), 'loud' (the nearest loud sound), 'note' (the nearest
note object on the floor), 'centre' (of the room), an (x, y) point, or an int: another
creature of the crowd."""

NAMED_TARGETS = ("visitor", "player", "loud", "note", "centre")

WANDER_RATE = 2.0
"""Wander's default drift of its angle, rad/√s."""


@dataclass(frozen=True)
class Behaviour:
    """One steering behaviour of a recipe, its ``weight`` (all policies) and ``probability``
    (prioritised dithering), and its parameters (a target, a path's name, …)."""

    name: str
    weight: float = 1.0
    probability: float = 1.0
    params: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.name not in BEHAVIOURS:
            raise ValueError(f"unknown steering behaviour {self.name!r} (choose from {sorted(BEHAVIOURS)})")


@dataclass(frozen=True)
class Recipe:
    """Behaviours in priority order (first = most important), the ``combine`` policy, and the
    neighbourhood (``neighbours`` nearest within ``reach`` m) the flocking behaviours see."""

    behaviours: tuple[Behaviour, ...]
    combine: str = "weighted"
    neighbours: int = 7
    reach: float = 3.0


@dataclass
class Surroundings:
    """What is in the room beside the crowd: visitors (positions, velocities), the player
    (where outside notes came from lately; none or one), loud sounds (positions), the creatures
    of a shared room's other processes, and the director's paths and flow fields by name."""

    visitors: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    visitor_vel: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    player: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    loud: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    notes: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    """Where the room's note objects lie ([[room.notes]])."""
    others: np.ndarray = field(default_factory=lambda: np.zeros((0, 7)))
    """Creatures other processes own in a shared room (creatures/room/share.py), rows of x, y,
    vx, vy, hx, hy, radius: neighbours to separate from and flock with, never steered here."""
    paths: dict[str, Path] = field(default_factory=dict)
    fields: dict[str, FlowField] = field(default_factory=dict)


@dataclass
class Step:
    """One sub-step of steering for one group: the scene, the whole crowd's rows (to find
    another creature), the surroundings, the sub-step's length and the crowd's random state."""

    scene: st.Scene
    crowd_pos: np.ndarray
    crowd_vel: np.ndarray
    crowd_heading: np.ndarray
    around: Surroundings
    dt: float
    rng: np.random.Generator
    wander_angle: np.ndarray  # (N,) of the whole crowd, updated in place for the group


def _nearest(points: np.ndarray, vel: np.ndarray, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Nearest of ``points`` to each of ``pos``: position, velocity, and whether there was any."""
    if len(points) == 0:
        return pos.copy(), np.zeros_like(pos), np.zeros(len(pos), dtype=bool)
    d = ((pos[:, None, :] - points[None]) ** 2).sum(-1)
    i = np.argmin(d, axis=1)
    return points[i], vel[i], np.ones(len(pos), dtype=bool)


def target_of(step: Step, target: Target) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where a behaviour's ``target`` is for each steering creature: (position, velocity,
    present); absent targets (no visitor in the room) give a zero force."""
    s, m = step.scene, len(step.scene.pos)
    if target == "visitor":
        return _nearest(step.around.visitors, step.around.visitor_vel, s.pos)
    if target in ("loud", "player", "note"):
        points = {"loud": step.around.loud, "player": step.around.player, "note": step.around.notes}[target]
        return _nearest(points, np.zeros_like(points), s.pos)
    if target == "centre":
        return np.tile(s.room.size / 2, (m, 1)), np.zeros((m, 2)), np.ones(m, dtype=bool)
    if isinstance(target, int):
        present = s.who != target
        return (np.tile(step.crowd_pos[target], (m, 1)), np.tile(step.crowd_vel[target], (m, 1)), present)
    point = np.asarray(target, dtype=float)
    return np.tile(point, (m, 1)), np.zeros((m, 2)), np.ones(m, dtype=bool)


def _aimed(fn: Callable[..., np.ndarray], with_vel: bool) -> Callable[[Step, dict], np.ndarray]:
    def adapter(step: Step, params: dict) -> np.ndarray:
        params = dict(params)
        where, vel, present = target_of(step, params.pop("target", "visitor"))
        force = fn(step.scene, where, vel, **params) if with_vel else fn(step.scene, where, **params)
        return np.where(present[:, None], force, 0.0)
    return adapter


def _wander(step: Step, params: dict) -> np.ndarray:
    s = step.scene
    rate = params.get("rate", WANDER_RATE) * np.sqrt(step.dt)  # a random walk in angle: tick-independent
    force, angle = st.wander(s, step.wander_angle[s.who], step.rng.standard_normal(len(s.who)), rate=rate,
                             radius=params.get("radius", 0.5), distance=params.get("distance", 1.0))
    step.wander_angle[s.who] = angle
    return force


def _leader(step: Step, params: dict) -> np.ndarray:
    params = dict(params)
    target = params.pop("target", "visitor")
    where, vel, present = target_of(step, target)
    heading = (np.tile(step.crowd_heading[target], (len(where), 1)) if isinstance(target, int)
               else np.tile([1.0, 0.0], (len(where), 1)))
    return np.where(present[:, None], st.leader_following(step.scene, where, vel, heading, **params), 0.0)


def _path(step: Step, params: dict) -> np.ndarray:
    params = dict(params)
    path = step.around.paths[params.pop("path")]
    return st.path_following(step.scene, path.points, path.radius, **params)


def _flow(step: Step, params: dict) -> np.ndarray:
    params = dict(params)
    flow = step.around.fields[params.pop("field")]
    return st.flow_following(step.scene, flow.directions, flow.cell, **params)


def _plain(fn: Callable[..., np.ndarray]) -> Callable[[Step, dict], np.ndarray]:
    return lambda step, params: fn(step.scene, **params)


BEHAVIOURS: dict[str, Callable[[Step, dict], np.ndarray]] = {
    "seek": _aimed(st.seek, False),
    "flee": _aimed(st.flee, False),
    "arrival": _aimed(st.arrival, False),
    "pursuit": _aimed(st.pursuit, True),
    "evasion": _aimed(st.evasion, True),
    "wander": _wander,
    "separation": _plain(st.separation),
    "cohesion": _plain(st.cohesion),
    "alignment": _plain(st.alignment),
    "obstacle_avoidance": _plain(st.obstacle_avoidance),
    "wall_avoidance": _plain(st.wall_avoidance),
    "agent_avoidance": _plain(st.agent_avoidance),
    "path_following": _path,
    "flow_following": _flow,
    "leader_following": _leader,
}
"""Every steering behaviour by the name a recipe gives."""
