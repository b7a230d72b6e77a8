"""Zones (REACT's ActionBoxes, REACT 3.3.5: "as soon as the agent enters one of these boxes
it will try to change the agent's attributes"): a rectangle of floor that, on entry, sets
drives, overrides vehicle keys and spec keys and switches tuples on or off, and on leaving puts
back what was there before. A spec key is any the remote console may set (``gain``,
``hears_input``, ``voice.gain``, …), set through the same validation
(:mod:`creatures.kinds.spec_keys`); a creature whose spec has no such key is not changed by it.

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

import difflib
from typing import TYPE_CHECKING, Any, Iterable

import numpy as np

from creatures.kinds.spec_keys import SpecKeyError, has, keys, read, with_key
from creatures.room.spec import BODY_KEYS, ZoneSpec
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


def _vehicle_unit(key: str, value: Any) -> Any:
    """A zone's ``spec`` value in the vehicle's own unit (``max_turn`` is given in degrees per
    second, kept in radians); a spec key's value as it is."""
    return float(np.radians(value)) if key == "max_turn" else value


def spec_problem(zone: ZoneSpec, specs: list) -> tuple[str, str] | None:
    """(key, why) of the first of ``zone``'s spec keys that no creature has (a typo: the
    nearest key is named) or that a creature's schema refuses with the zone's value; None
    when every one will do. Checked when the config loads, so that entering a zone cannot fail."""
    for key, value in zone.spec.items():
        if key in BODY_KEYS:
            continue
        if key.split(".")[0] == "vehicle":
            return key, (f"zone {zone.name!r}: the vehicle's keys are set by their own names ({', '.join(BODY_KEYS)}); "
                         "the rest of [creature.vehicle] is read once, when the room is built")
        having = [spec for spec in specs if has(spec, key)]
        if not having:
            known = sorted({*BODY_KEYS, *(k for spec in specs for k in keys(spec))})
            close = difflib.get_close_matches(key, known, n=1)
            return key, (f"zone {zone.name!r}: spec key {key!r} is neither a vehicle key ({', '.join(BODY_KEYS)}) nor "
                         "any creature's spec key" + (f" (did you mean {close[0]!r}?)" if close else ""))
        for spec in having:
            try:
                with_key(spec, key, value, spec.name)
            except SpecKeyError as error:
                return key, f"zone {zone.name!r}, creature {spec.name!r}: {error}"
    return None


class Zones:
    """The zones of a room and who is inside each."""

    def __init__(self, zones: list[ZoneSpec], creatures: list["CreatureKind"]) -> None:
        self.zones = zones
        self.creatures = creatures
        self.inside = np.zeros((len(zones), len(creatures)), dtype=bool)
        self._stack: list[list[int]] = [[] for _ in creatures]  # the zones each is in, in entry order
        # What each zone-set key and drive was before the first zone that set it.
        self._base: list[dict[str, dict[str, Any]]] = [{"keys": {}, "drives": {}} for _ in creatures]
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
            if self._has(i, key):
                base["keys"].setdefault(key, self._get(i, key, v))
                self._put(i, key, _vehicle_unit(key, value), v)
        if motivation is not None:
            for name, level in zone.drives.items():
                if name in motivation.names:  # a zone sets the drives a creature has
                    base["drives"].setdefault(name, motivation.level(name, t))
                    motivation.perturb(t, name, level - motivation.level(name, t))
        stack.append(z)
        self._switch(i)

    def _leave(self, t: float, z: int, i: int, v: Vehicles) -> None:
        zone, stack, base = self.zones[z], self._stack[i], self._base[i]
        key_on_top = {key: self._latest(stack, "spec", key) == z for key in zone.spec}
        drive_on_top = {name: self._latest(stack, "drives", name) == z for name in zone.drives}
        stack.remove(z)
        for key in zone.spec:
            if key_on_top[key] and key in base["keys"]:
                under = self._latest(stack, "spec", key)
                self._put(i, key, base["keys"].pop(key) if under is None else
                          _vehicle_unit(key, self.zones[under].spec[key]), v)
        motivation = getattr(self.creatures[i], "motivation", None)
        if motivation is not None:
            for name in zone.drives:
                if drive_on_top[name] and name in base["drives"]:
                    under = self._latest(stack, "drives", name)
                    level = base["drives"].pop(name) if under is None else self.zones[under].drives[name]
                    motivation.perturb(t, name, level - motivation.level(name, t))
        self._switch(i)

    def _has(self, i: int, key: str) -> bool:
        return key in BODY_KEYS or has(self.creatures[i].spec, key)

    def _get(self, i: int, key: str, v: Vehicles) -> Any:
        """Creature ``i``'s ``key`` now: a vehicle key (in the vehicle's unit) or a spec key."""
        return float(getattr(v, key)[i]) if key in BODY_KEYS else read(self.creatures[i].spec, key)

    def _put(self, i: int, key: str, value: Any, v: Vehicles) -> None:
        """Creature ``i``'s ``key`` set to ``value``: a vehicle's column, or its spec through the
        console's validation (checked when the config loaded: :func:`spec_problem`)."""
        if key in BODY_KEYS:
            getattr(v, key)[i] = value
        else:
            creature = self.creatures[i]
            creature.spec = with_key(creature.spec, key, value, creature.name)

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
