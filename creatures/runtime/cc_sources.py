"""What an ``[[output.cc]]`` stream reads each tick: a drive's level, or a feature of the
creature's body (thesis: "graph-based motor systems" — the body is as much the creature's
expression as its notes, so a synth's filter may follow the hand as well as boredom).

``source`` is ``<creature>.<drive>`` or ``<creature>.body.<feature>``; :func:`check_source`
checks it at load (the creature's kind says which drives it has and whether it has a body),
:func:`reader` builds the per-tick reading once the creature exists.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Callable

import numpy as np

from creatures.config import nearest

if TYPE_CHECKING:
    from creatures.kinds.base import CreatureKind

AXES = {"effector_x": 0, "effector_y": 1, "effector_z": 2, "effector_height": 1}
"""Body features that are one coordinate of the end-effector's world position (y is up, as in
the note space: ``effector_height`` is ``effector_y``)."""

BODY_FEATURES = (*AXES, "speed")
"""Every body feature a stream may read; ``speed`` is the end-effector's speed, units a second."""

Reader = Callable[[float], float]


def parse(source: str) -> tuple[str, str | None, str]:
    """``(creature, "body" or None, drive or feature)`` of a source the schema's pattern passed."""
    parts = source.split(".")
    return (parts[0], None, parts[1]) if len(parts) == 2 else (parts[0], parts[1], parts[2])


def check_source(source: str, drives: tuple[str, ...], has_body: bool) -> str | None:
    """Why ``source`` cannot be read from a creature with these ``drives`` and body, or None."""
    name, body, what = parse(source)
    if body is None:
        if what in drives:
            return None
        return f"{name} has no drive {what!r}{nearest(what, drives, 'drives')}"
    if body != "body":
        return f"{body!r} is not 'body': use '<creature>.<drive>' or '<creature>.body.<feature>'"
    if not has_body:
        return f"{name} has no body (its kind draws none); a stream may read its drives ({', '.join(drives) or 'none'})"
    if what not in BODY_FEATURES:
        return f"no body feature {what!r}{nearest(what, BODY_FEATURES, 'body features')}"
    return None


def reader(creature: "CreatureKind", source: str) -> Reader:
    """The per-tick reading of a source :func:`check_source` accepted for this creature."""
    _, body, what = parse(source)
    if body is None:
        motivation = creature.motivation  # type: ignore[attr-defined]  # a kind with drives has one
        return lambda t: motivation.level(what, max(t, motivation.time))
    if what == "speed":
        return EffectorSpeed(creature)
    axis = AXES[what]
    return lambda t: float(_effector(creature)[axis])


class EffectorSpeed:
    """The end-effector's speed between two readings (0 at the first, and when no time passed)."""

    def __init__(self, creature: "CreatureKind") -> None:
        self.creature = creature
        self.last: tuple[float, np.ndarray] | None = None

    def __call__(self, t: float) -> float:
        here = _effector(self.creature)
        last, self.last = self.last, (t, here.copy())
        if last is None or t <= last[0]:
            return 0.0
        return float(np.linalg.norm(here - last[1]) / (t - last[0]))


def _effector(creature: "CreatureKind") -> np.ndarray:
    here = creature.effector()
    if here is None:  # check_source passed it: the kind said it has a body
        raise RuntimeError(f"{creature.name} reports no end-effector although its kind has a body")
    return here
