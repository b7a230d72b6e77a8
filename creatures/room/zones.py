"""Zones (REACT's ActionBoxes, REACT 3.3.5: "as soon as the agent enters one of these boxes
it will try to change the agent's attributes"): a rectangle of floor that, on entry, sets
drives, overrides body keys and switches tuples on or off, and on leaving puts back what was
there before.

A tuple a zone ``enable``s is off everywhere else (the zone is where it can happen); one it
``disable``s is off inside it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Iterable

import numpy as np

from creatures.room.spec import ZoneSpec
from creatures.room.vehicle import Vehicles

if TYPE_CHECKING:
    from creatures.kinds.base import CreatureKind

def groups_of(creature: "CreatureKind") -> Iterable[Any]:
    """Every action-group of a creature (authored creatures have several, other kinds one)."""
    groups = getattr(creature, "groups", None)
    if isinstance(groups, dict):
        return groups.values()
    group = getattr(creature, "group", None)
    return [] if group is None else [group]


def contains(zone: ZoneSpec, pos: np.ndarray) -> np.ndarray:
    """Which of ``pos`` (N, 2) are inside ``zone`` (corners in either order), (N,) bool."""
    low, high = np.minimum(zone.low, zone.high), np.maximum(zone.low, zone.high)
    return np.all((pos >= low) & (pos <= high), axis=1)


class Zones:
    """The zones of a room and who is inside each."""

    def __init__(self, zones: list[ZoneSpec], creatures: list["CreatureKind"]) -> None:
        self.zones = zones
        self.creatures = creatures
        self.inside = np.zeros((len(zones), len(creatures)), dtype=bool)
        self._saved: dict[tuple[int, int], dict[str, Any]] = {}
        for zone in zones:
            for creature in creatures:
                for group in groups_of(creature):
                    group.disabled.update(zone.enable)

    def update(self, t: float, v: Vehicles, emit) -> None:
        """Apply the zones entered and undo the ones left since the last update."""
        for z, zone in enumerate(self.zones):
            now = contains(zone, v.pos)
            for i in np.nonzero(now != self.inside[z])[0]:
                if now[i]:
                    self._enter(t, z, int(i), v)
                else:
                    self._leave(t, z, int(i), v)
                emit("zone", zone=zone.name, creature=self.creatures[i].name, inside=bool(now[i]))
            self.inside[z] = now

    def _enter(self, t: float, z: int, i: int, v: Vehicles) -> None:
        zone, creature = self.zones[z], self.creatures[i]
        motivation = getattr(creature, "motivation", None)
        saved: dict[str, Any] = {"body": {k: float(getattr(v, k)[i]) for k in zone.spec}, "drives": {}}
        for key, value in zone.spec.items():
            getattr(v, key)[i] = np.radians(value) if key == "max_turn" else value
        if motivation is not None:
            for name, level in zone.drives.items():
                if name not in motivation.names:
                    continue  # a zone sets the drives a creature has
                saved["drives"][name] = motivation.level(name, t)
                motivation.perturb(t, name, level - motivation.level(name, t))
        for group in groups_of(creature):
            group.disabled.difference_update(zone.enable)
            group.disabled.update(zone.disable)
        self._saved[(z, i)] = saved

    def _leave(self, t: float, z: int, i: int, v: Vehicles) -> None:
        zone, creature = self.zones[z], self.creatures[i]
        saved = self._saved.pop((z, i), {"body": {}, "drives": {}})
        for key, value in saved["body"].items():
            getattr(v, key)[i] = value
        motivation = getattr(creature, "motivation", None)
        if motivation is not None:
            for name, level in saved["drives"].items():
                motivation.perturb(t, name, level - motivation.level(name, t))
        for group in groups_of(creature):
            group.disabled.update(zone.enable)
            group.disabled.difference_update(zone.disable)
