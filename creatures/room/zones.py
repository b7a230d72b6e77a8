"""Zones (REACT's ActionBoxes, REACT 3.3.5: "as soon as the agent enters one of these boxes
it will try to change the agent's attributes"): a rectangle of floor that, on entry, sets
drives, overrides body keys and switches tuples on or off, and on leaving puts back what was
there before.

A tuple a zone ``enable``s is off everywhere else (the zone is where it can happen); one it
``disable``s is off inside it.

Zones may overlap. A creature's zones are a stack in the order it entered them: a body key or
a drive takes the value of the latest zone it is still in that sets it, and the value from
before the first such zone once it has left them all, whatever order it leaves them in. A
tuple is on where any of its zones enables it and off where any disables it. (Each zone once
kept its own undo, so leaving the first of two overlapping zones put back the value from
outside while the creature stood in the second.)
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


def _vehicle_unit(key: str, value: float) -> float:
    """A zone's ``spec`` value in the vehicle's own unit (``max_turn`` is given in degrees per
    second, kept in radians)."""
    return float(np.radians(value)) if key == "max_turn" else value


class Zones:
    """The zones of a room and who is inside each."""

    def __init__(self, zones: list[ZoneSpec], creatures: list["CreatureKind"]) -> None:
        self.zones = zones
        self.creatures = creatures
        self.inside = np.zeros((len(zones), len(creatures)), dtype=bool)
        self._stack: list[list[int]] = [[] for _ in creatures]  # the zones each is in, in entry order
        self._base: list[dict[str, dict[str, float]]] = [{"body": {}, "drives": {}} for _ in creatures]
        self._enabled = {name for zone in zones for name in zone.enable}
        self._managed = self._enabled | {name for zone in zones for name in zone.disable}
        for i in range(len(creatures)):
            self._switch(i)

    def update(self, t: float, v: Vehicles, emit) -> None:
        """Apply the zones entered and undo the ones left since the last update."""
        for z, zone in enumerate(self.zones):
            now = contains(zone, v.pos)
            for i in np.nonzero(now != self.inside[z])[0]:
                (self._enter if now[i] else self._leave)(t, z, int(i), v)
                emit("zone", zone=zone.name, creature=self.creatures[i].name, inside=bool(now[i]))
            self.inside[z] = now

    def _enter(self, t: float, z: int, i: int, v: Vehicles) -> None:
        zone, stack, base = self.zones[z], self._stack[i], self._base[i]
        motivation = getattr(self.creatures[i], "motivation", None)
        for key, value in zone.spec.items():
            base["body"].setdefault(key, float(getattr(v, key)[i]))
            getattr(v, key)[i] = _vehicle_unit(key, value)
        if motivation is not None:
            for name, level in zone.drives.items():
                if name in motivation.names:  # a zone sets the drives a creature has
                    base["drives"].setdefault(name, motivation.level(name, t))
                    motivation.perturb(t, name, level - motivation.level(name, t))
        stack.append(z)
        self._switch(i)

    def _leave(self, t: float, z: int, i: int, v: Vehicles) -> None:
        zone, stack, base = self.zones[z], self._stack[i], self._base[i]
        body_on_top = {key: self._latest(stack, "spec", key) == z for key in zone.spec}
        drive_on_top = {name: self._latest(stack, "drives", name) == z for name in zone.drives}
        stack.remove(z)
        for key in zone.spec:
            if body_on_top[key]:
                under = self._latest(stack, "spec", key)
                getattr(v, key)[i] = base["body"].pop(key) if under is None else _vehicle_unit(key, self.zones[under].spec[key])
        motivation = getattr(self.creatures[i], "motivation", None)
        if motivation is not None:
            for name in zone.drives:
                if drive_on_top[name] and name in base["drives"]:
                    under = self._latest(stack, "drives", name)
                    level = base["drives"].pop(name) if under is None else self.zones[under].drives[name]
                    motivation.perturb(t, name, level - motivation.level(name, t))
        self._switch(i)

    def _latest(self, stack: list[int], field: str, key: str) -> int | None:
        """The last-entered zone of ``stack`` whose ``field`` (spec or drives) sets ``key``."""
        return next((z for z in reversed(stack) if key in getattr(self.zones[z], field)), None)

    def _switch(self, i: int) -> None:
        """Creature ``i``'s zone-managed tuples on or off for the zones it is in now."""
        inside = [self.zones[z] for z in self._stack[i]]
        on = {name for zone in inside for name in zone.enable}
        off = (self._enabled - on) | {name for zone in inside for name in zone.disable}
        for group in groups_of(self.creatures[i]):
            group.disabled.difference_update(self._managed)
            group.disabled.update(off)
