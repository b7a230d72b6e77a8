"""A session's room (``[room]``): every creature's vehicle in one :class:`Crowd`, the
visitors from the tracker's sensors, hearing across the room, and where each voice sounds.

The :class:`~creatures.runtime.session.Session` builds one when the config has a ``[room]``
and calls it on the one way through a tick: :meth:`Stage.tick` (visitors → zones → sub-steps
of steering) before the world delivers notes, :meth:`Stage.emit` for each note that starts
(instead of giving it to every ear at once), :meth:`Stage.due` for what each ear hears now,
and :meth:`Stage.place` to set each voice's speaker gains.
"""

from __future__ import annotations

import itertools
import json
from typing import TYPE_CHECKING, Any, Callable

import numpy as np
from scipy.spatial import cKDTree

from creatures import bounds
from creatures.clock import clock_gap, next_on_grid
from creatures.config import nearest
from creatures.kinds.figures import body_graph
from creatures.room.director import FlowField, Path
from creatures.room.hearing import DistanceLaw, Ears, Masking, arrivals, db_velocity, velocity_db
from creatures.room.gait import Gaits, Walk, in_room
from creatures.room.lod import Audibility, LevelOfDetail, Sounding, overdue_first
from creatures.room.motion import Crowd
from creatures.room.recipe import NAMED_TARGETS, Behaviour, Recipe, Surroundings
from creatures.room.space import Obstacle, Room
from creatures.room.spec import AIMED, RoomSection, VehicleSpec, VisitorSpec
from creatures.room.speakers import DOME, Dome, azimuth, ring, stereo, vbap
from creatures.room.steering import project
from creatures.room.vehicle import Vehicles, norms
from creatures.room.vision import visible
from creatures.room.zones import Zones, spec_problem
from midi.notes import NoteEvent

if TYPE_CHECKING:
    from creatures.behaviour.state_object import StateObject
    from creatures.kinds.base import CreatureKind
    from creatures.room.share import RoomShare
    from creatures.runtime.world import World

LOUD_FOR = 1.0
"""Seconds a loud note stays a 'loud' steering target after it starts."""

PLAYER_FOR = 4.0
"""Seconds the place an outside note came from stays the 'player' target after it starts
(a phrase's gaps must not scatter a crowd gathered round whoever plays)."""


MARKER = np.array([[0.0, 0.0, 0.0], [0.0, 0.6, 0.0], [0.0, 0.6, 0.25]])
"""How a creature without a body is drawn in a room, in its own frame (facing +z, y up): a post
0.6 m high where its vehicle stands, and at its top a 0.25 m arm pointing where it heads. A
crowd of singers without bodies (installations/flock.toml) was drawn nowhere: no frames, no
poses in the log, nothing in the live view or the body stream, so nobody could see it flock."""
MARKER_PARENTS = np.array([-1, 0, 1])
MARKER_JOINTS = ("floor", "top", "heading")
"""The marker's joints by name (the body stream's hello names them)."""


LARGEST_FIELD = 1_000_000
"""Most cells of a uniform or vortex flow field (a painted one's: 1000 rows of 1000): 0.02 m
cells over a 1000 m room were 2.5e9 cells, 40 GB, asked for when the run began."""


class StageError(ValueError):
    """A ``[creature.vehicle]`` that names what is not there; ``key`` is the path under the creature."""

    def __init__(self, creature: int, key: tuple, message: str) -> None:
        super().__init__(message)
        self.creature, self.key = creature, key


class RoomError(ValueError):
    """A ``[room]`` key that cannot work with these creatures; ``key`` is its path under room."""

    def __init__(self, key: tuple, message: str) -> None:
        super().__init__(message)
        self.key = key


def walk(spec, i: int) -> Walk:
    """Creature ``i``'s ``[creature.vehicle] gait`` on its body's graph (:class:`StageError`: no
    body, or no such walking clip)."""
    body = getattr(spec, "body", False)
    if not body:
        raise StageError(i, ("vehicle", "gait"), f"gait {spec.vehicle.gait!r} needs a body that walks "
                         "([creature.body] figure = \"dog\", or files with a root_motion clip)")
    try:
        return Walk.of(body_graph(body), spec.vehicle.gait)
    except ValueError as error:
        raise StageError(i, ("vehicle", "gait"), str(error)) from None


def floor(section: RoomSection) -> Room:
    """The walls and obstacles of a ``[room]`` table."""
    return Room(section.width, section.depth, tuple(Obstacle(o.at[0], o.at[1], o.radius) for o in section.obstacles))


def _standing_room(section: RoomSection, specs: list, room: str) -> None:
    """Obstacles that leave no floor where a creature with no ``at`` could start (:class:`RoomError`):
    it started inside one, and the walls and the obstacle held it in a corner all run. The
    largest such body is the one checked: a place for it is a place for any smaller one."""
    unplaced = [(spec.vehicle.radius, spec.name) for spec in specs if spec.vehicle.at is None]
    if not unplaced or not section.obstacles:
        return
    radius, name = max(unplaced)
    if len(floor(section).standing_room(radius)):
        return
    alone = [n for n, o in enumerate(section.obstacles)
             if not len(Room(section.width, section.depth, (Obstacle(o.at[0], o.at[1], o.radius),)).standing_room(radius))]
    key = ("obstacles", alone[0], "radius") if alone else ("obstacles",)
    which = f"obstacle {alone[0]} (radius {section.obstacles[alone[0]].radius:g} m) covers" if alone else \
        "the obstacles cover"
    raise RoomError(key, f"{which} the whole floor of the {room}: no place where {name!r} (radius {radius:g} m) "
                         "could start")


def check_places(section: RoomSection, specs: list, drives: list[tuple[str, ...]]) -> None:
    """Every place named is on the floor, and every zone's drives, tuples and spec keys are some
    creature's, with values its schema takes (:class:`StageError`, :class:`RoomError`; a
    zone's change to a creature without that drive, tuple or key does nothing to it, but a name
    no creature has is a typo)."""
    size = (section.width, section.depth)

    def off(point: tuple[float, float] | None) -> bool:
        return point is not None and not (0 <= point[0] <= size[0] and 0 <= point[1] <= size[1])

    room = f"{size[0]:g} x {size[1]:g} m room"
    _check_floor(section, off, room)
    _standing_room(section, specs, room)
    for i, spec in enumerate(specs):
        vehicle = spec.vehicle
        if off(vehicle.at):
            raise StageError(i, ("vehicle", "at"), f"start {list(vehicle.at)} is outside the {room}")
        if 2 * vehicle.radius > min(size):
            raise StageError(i, ("vehicle", "radius"), f"a body of radius {vehicle.radius:g} m does not fit in the "
                             f"{room} (the walls would hold it outside the room)")
        if (inside := _in_obstacle(section, vehicle.at)) is not None:
            raise StageError(i, ("vehicle", "at"), f"start {list(vehicle.at)} is inside {inside}")
        for b, steer in enumerate(vehicle.steer):
            if not isinstance(steer.target, str) and off(steer.target):
                raise StageError(i, ("vehicle", "steer", b, "target"), f"target {list(steer.target)} is outside "
                                 f"the {room}: the creature would press against the wall")
            if not isinstance(steer.target, str) and (inside := _in_obstacle(section, steer.target)) is not None:
                raise StageError(i, ("vehicle", "steer", b, "target"), f"target {list(steer.target)} is inside "
                                 f"{inside}: the creature would press against it")
        if vehicle.gait is not None:
            walk(spec, i)
    for n, note in enumerate(section.notes):
        if off(note.at):
            raise RoomError(("notes", n, "at"), f"note object {list(note.at)} is outside the "
                            f"{size[0]:g} x {size[1]:g} m room")
        if (inside := _in_obstacle(section, note.at, note.radius)) is not None:
            raise RoomError(("notes", n, "at"), f"note object {list(note.at)} (radius {note.radius:g} m) lies "
                            f"inside {inside}: no creature could step onto it")
    for key in ("listener", "input_at"):
        if off(getattr(section, key)):
            raise RoomError((key,), f"{key} {list(getattr(section, key))} is outside the {size[0]:g} x {size[1]:g} m room")
    all_drives = {d for names in drives for d in names}
    all_tuples = {t for spec in specs for t in (getattr(spec, "tuples", None) or {})}
    for z, zone in enumerate(section.zones):
        for name in zone.drives:
            if name not in all_drives:
                raise RoomError(("zones", z, "drives", name), f"zone {zone.name!r}: no creature has a drive "
                                f"{name!r}{nearest(name, sorted(all_drives), 'drives')}")
        for key in ("enable", "disable"):
            for name in getattr(zone, key):
                if name not in all_tuples:
                    raise RoomError(("zones", z, key), f"zone {zone.name!r}: no creature has a tuple "
                                    f"{name!r}{nearest(name, sorted(all_tuples), 'tuples')}")
        if (problem := spec_problem(zone, specs)) is not None:
            raise RoomError(("zones", z, "spec", problem[0]), problem[1])


def _in_obstacle(section: RoomSection, point: tuple[float, float] | None, reach: float = 0.0) -> str | None:
    """The first obstacle that holds ``point`` and everything within ``reach`` m of it, said as
    an error names it, or None."""
    if point is None:
        return None
    for n, o in enumerate(section.obstacles):
        if np.hypot(point[0] - o.at[0], point[1] - o.at[1]) + reach < o.radius:
            return f"obstacle {n} (at {list(o.at)}, radius {o.radius:g} m)"
    return None


def _check_floor(section: RoomSection, off: Callable[[tuple[float, float] | None], bool], room: str) -> None:
    """What the director lays on the floor is on it (:class:`RoomError`): a zone no one can stand
    in (off the floor, or of no area), an obstacle wholly off it, a path with a point off it or
    a line through an obstacle (its followers would press against the wall or the obstacle, the
    path pulling them back onto its line), a body key of a zone that no room would hold,
    and two zones, paths or flow fields of one name (a path or field named twice was the last
    one; a zone's events could not say which)."""
    size = (section.width, section.depth)
    for key in ("zones", "paths", "flows"):
        seen: set[str] = set()
        for n, item in enumerate(getattr(section, key)):
            if item.name in seen:
                raise RoomError((key, n, "name"), f"two [[room.{key}]] are named {item.name!r}")
            seen.add(item.name)
    for z, zone in enumerate(section.zones):
        low, high = np.minimum(zone.low, zone.high), np.maximum(zone.low, zone.high)
        if (low >= high).any():
            raise RoomError(("zones", z, "high"), f"zone {zone.name!r} from {list(zone.low)} to {list(zone.high)} "
                            "has no area: no creature could stand in it")
        if (low >= size).any():
            raise RoomError(("zones", z, "low"), f"zone {zone.name!r} from {list(zone.low)} to {list(zone.high)} "
                            f"lies outside the {room}: no creature could stand in it")
        if 2 * zone.spec.get("radius", 0.0) > min(size):
            raise RoomError(("zones", z, "spec", "radius"), f"zone {zone.name!r}: a body of radius "
                            f"{zone.spec['radius']:g} m does not fit in the {room}")
    for n, o in enumerate(section.obstacles):
        if np.hypot(*(np.clip(o.at, 0.0, size) - o.at)) >= o.radius:  # the floor's nearest point is not in it
            raise RoomError(("obstacles", n, "at"), f"obstacle {list(o.at)} of radius {o.radius:g} m lies "
                            f"outside the {room}")
    for n, flow in enumerate(section.flows):
        cells = int(np.ceil(size[0] / flow.cell)) * int(np.ceil(size[1] / flow.cell))
        if flow.shape != "painted" and cells > LARGEST_FIELD:
            raise RoomError(("flows", n, "cell"), f"flow {flow.name!r}: cells of {flow.cell:g} m make {cells:.3g} over "
                            f"the {room}, more than {LARGEST_FIELD:.0e} (at least "
                            f"{np.sqrt(size[0] * size[1] / LARGEST_FIELD):.3g} m)")
    for n, path in enumerate(section.paths):
        for point in path.points:
            if off(point):
                raise RoomError(("paths", n, "points"), f"path {path.name!r}: point {list(point)} is outside the "
                                f"{room}: its followers would press against the wall")
        if section.obstacles:  # pure pursuit along the line holds a follower against a pillar on it
            centres = np.array([o.at for o in section.obstacles])
            foot, seg, _ = project(np.array(path.points, dtype=float), centres)
            through = np.hypot(*(foot - centres).T) < [o.radius for o in section.obstacles]
            if through.any():
                o, k = int(np.argmax(through)), int(seg[np.argmax(through)])
                raise RoomError(("paths", n, "points"), f"path {path.name!r}: from {list(path.points[k])} to "
                                f"{list(path.points[k + 1])} it passes through obstacle {o} (at "
                                f"{list(section.obstacles[o].at)}, radius {section.obstacles[o].radius:g} m): its "
                                "followers would press against the obstacle")


UNTRACKED = "track one (two sensors of the input map, named in [[room.visitors]]) or name another"
"""What to do about a creature that steers by, or perceives, a visitor in a room that tracks
none: without [[room.visitors]] there is never one, so it stood still, or read 0, all run."""


def recipes(section: RoomSection, specs: list, index: dict[str, int]
            ) -> tuple[list[Recipe], np.ndarray, list[tuple[int, int, str]]]:
    """One recipe per distinct steering (a crowd's clones share one, so they steer as one
    array), each creature's group, and the (creature, behaviour, percept) of every ``when``.
    ``specs`` are the creatures' specs (``spec.vehicle``, and ``spec.percepts`` for ``when``);
    :class:`StageError` for a name that is not there (checked when the config loads)."""
    keys: dict[str, int] = {}
    out: list[Recipe] = []
    groups = np.zeros(len(specs), dtype=np.intp)
    when: list[tuple[int, int, str]] = []
    paths, flows = {p.name for p in section.paths}, {f.name for f in section.flows}
    for i, spec in enumerate(specs):
        s = spec.vehicle
        behaviours = []
        for b, steer in enumerate(s.steer):
            params = steer.params()
            target = params.get("target")
            if target == "note" and not section.notes:
                raise StageError(i, ("vehicle", "steer", b, "target"), "target \"note\" steers to the nearest "
                                 "note object, and the room has none ([[room.notes]])")
            if isinstance(target, str) and target not in NAMED_TARGETS:
                if target not in index:  # a slip of a named target ("visiter") or of a creature's name
                    raise StageError(i, ("vehicle", "steer", b, "target"), f"no creature named {target!r} to steer "
                                     f"by{nearest(target, [*NAMED_TARGETS, *index, '[x, y]'], 'targets')}")
                params["target"] = index[target]
            need = {"path_following": ("path", paths, "[[room.paths]]"),
                    "flow_following": ("field", flows, "[[room.flows]]")}.get(steer.behaviour)
            if need is not None and params.get(need[0]) not in need[1]:
                key, names, table = need
                raise StageError(i, ("vehicle", "steer", b, key), f"{steer.behaviour} needs {key} = one of the "
                                 f"room's {table} names, got {params.get(key)!r}"
                                 f"{nearest(params.get(key), sorted(names), table)}")
            if steer.when is not None:
                percepts = getattr(spec, "percepts", None)
                if percepts is None or steer.when not in percepts:
                    raise StageError(i, ("vehicle", "steer", b, "when"), f"no percept {steer.when!r}"
                                     f"{nearest(steer.when, sorted(percepts or []), 'its percepts')}")
                when.append((i, b, steer.when))
            if steer.behaviour in AIMED and target in (None, "visitor") and not section.visitors:
                raise StageError(i, ("vehicle", "steer", b, "target"), f"{steer.behaviour} steers to the nearest "
                                 f"tracked visitor{' (its target when none is given)' if target is None else ''}, and "
                                 f"the room tracks none ([[room.visitors]]): {UNTRACKED}")
            behaviours.append(Behaviour(steer.behaviour, steer.weight, steer.probability, params))
        key = json.dumps([[b.name, b.weight, b.probability, sorted(b.params.items())] for b in behaviours]
                         + [s.combine, s.neighbours, s.reach], default=str)
        if key not in keys:
            keys[key] = len(out)
            out.append(Recipe(tuple(behaviours), s.combine, s.neighbours, s.reach))
        groups[i] = keys[key]
    return out, groups, when


class Stage:
    """The room, the crowd in it, and what crosses it."""

    def __init__(self, section: RoomSection, creatures: list["CreatureKind"], rng: np.random.Generator,
                 sensors: dict[str, "StateObject"]) -> None:
        self.section = section
        self.creatures = creatures
        self.index = {c.name: i for i, c in enumerate(creatures)}
        self.room = floor(section)
        self.sensors = sensors
        specs = [c.spec.vehicle for c in creatures]
        self.v = self._vehicles(specs, rng)
        self._markers: np.ndarray | None = None  # every creature's MARKER where it stands, once a tick
        plans, groups, self._when = recipes(section, [c.spec for c in creatures], self.index)
        self.notes = np.array([n.at for n in section.notes], dtype=float).reshape(-1, 2)
        self._note_radius = np.array([n.radius for n in section.notes]).reshape(-1, 1)
        self._on_note = self._standing()  # who stands on which: one put there strikes nothing
        self._was_at = self.v.pos.copy()  # where each stood at the last strike check
        around = Surroundings(paths={p.name: Path(np.array(p.points, float), p.radius) for p in section.paths},
                              fields={f.name: self._field(f) for f in section.flows}, notes=self.notes)
        lod = None if section.lod is None else LevelOfDetail(section.lod.near, section.lod.levels, section.lod.budget,
                                                             section.lod.unheard)
        self.crowd = Crowd(self.room, self.v, plans, groups, substep=section.substep,
                           seed=int(rng.integers(2**32)), lod=lod, around=around)
        self.zones = Zones(section.zones, creatures)
        self.gaits = Gaits([None if c.spec.vehicle.gait is None else walk(c.spec, i) for i, c in enumerate(creatures)],
                           self.v.pos, rng)
        self._walked_at = 0.0
        h = section.hearing
        self.law = DistanceLaw(h.law, h.reference, h.silent)
        self.masking = Masking(h.margin, h.band, h.threshold)
        self.listener = np.array(section.listener if section.listener is not None else (section.width / 2, 0.0))
        self.speakers = ring(section.channels, 0.0) if section.speakers == "ring" else None
        self.dome = Dome(section.dome or DOME) if section.speakers == "dome" else None
        corners = np.array([[0.0, 0.0], [section.width, 0.0], [0.0, section.depth], [section.width, section.depth]])
        self._reach = section.dome_reach or max(float(norms(corners - self.listener).max()), 1e-3)
        if self.dome is not None:
            self.channels = len(self.dome.speakers)
        else:
            self.channels = 2 if self.speakers is None else section.channels
        self._loud: list[tuple[float, np.ndarray]] = []  # (until, where) of each loud note
        self._player: tuple[float, np.ndarray] | None = None  # (until, where) of the last outside note
        self._ears = Ears(len(creatures), self.masking)
        # Every note's arrivals still on their way, one row per ear it is yet to reach: when
        # it starts there, where it ends, its level, its pitch, which ear, which note (its
        # number in ``_sounds``, (note, source), in the order they were emitted).
        self._flying = {key: np.zeros(0) for key in ("start", "end", "db", "pitch")}
        self._flying.update(ear=np.zeros(0, dtype=np.int64), note=np.zeros(0, dtype=np.int64))
        self._new_rows: list[dict[str, np.ndarray]] = []  # joined to _flying once a tick (a burst stays linear)
        self._sounds: dict[int, tuple[NoteEvent, str]] = {}
        self._emitted = itertools.count()
        self.masked = 0  # arrivals a louder sound hid
        self._tree: cKDTree | None = None
        self._points = np.zeros((0, 2))  # what the tree holds
        self._tree_at = -1
        self._next_report = 0.0
        self.share: RoomShare | None = None
        self._world: World | None = None
        self._remote: dict[str, int] = {}  # a shared room's remote creature -> its row in around.others
        self._next_beat = -np.inf  # the next shared beat the pulse hears (counted from the first one seen)
        self._half: dict[int, float | None] = {}  # a visitor with one coordinate: since when (None: said)
        # The tick each last decided on; staggered so a level's creatures spread over its ticks.
        self._decided = -1 - np.arange(len(creatures), dtype=np.int64) % 256
        # What each creature sounds now, for [room.lod] unheard (None: levels by distance alone).
        self.sounding: Sounding | None = None
        if lod is not None and lod.unheard and creatures:
            self.sounding = Sounding(len(creatures))
            self.crowd.audibility = Audibility(self.law, h.threshold)
            creatures[0].world.listeners.append(self._played)

    def attach(self, share: "RoomShare", world: "World") -> None:
        """Share this room with other processes (``[room.share]``, a live run): their creatures
        join the neighbours, the percepts and the ears; ours and our notes go to them."""
        self.share, self._world = share, world
        world.listeners.append(share.played)

    def _played(self, creature: str, note: NoteEvent) -> None:
        """One of the room's creatures plays ``note`` (a world listener): it sounds, this loud,
        until the note ends (level of detail's ``unheard``)."""
        assert self.sounding is not None
        self.sounding.play(self.index[creature], note.time, note.time + note.duration, velocity_db(note.velocity))

    # -- building ------------------------------------------------------------------------
    def _vehicles(self, specs: list[VehicleSpec], rng: np.random.Generator) -> Vehicles:
        """Each creature where its spec says, else at a seeded random free place."""
        size = self.room.size
        pos, heading = np.zeros((len(specs), 2)), np.zeros((len(specs), 2))
        for i, s in enumerate(specs):
            if s.at is not None:
                pos[i] = s.at
            else:
                for _ in range(100):  # a free place (off the obstacles), else a corner of the free floor
                    pos[i] = rng.uniform(s.radius, size - s.radius)
                    if not len(self.room.obstacles) or (
                            norms(self.room.centres - pos[i]) > self.room.radii + s.radius).all():
                        break
                else:  # some floor is free (creatures.room.stage.check_places), if too little to draw
                    free = self.room.standing_room(s.radius)
                    pos[i] = free[rng.integers(len(free))]
            angle = np.radians(s.heading) if s.heading is not None else rng.uniform(-np.pi, np.pi)
            heading[i] = (np.cos(angle), np.sin(angle))

        def col(key: str) -> np.ndarray:
            return np.array([getattr(s, key) for s in specs], dtype=float)

        v = Vehicles(pos, np.zeros_like(pos), heading, col("mass"), col("max_force"), col("max_speed"),
                     col("radius"), np.radians(col("max_turn")))
        return v

    def _field(self, f) -> FlowField:
        if f.shape == "uniform":
            return FlowField.uniform(self.room.size, f.cell, f.direction)
        if f.shape == "painted":
            return FlowField.painted(self.room.size, f.rows)
        return FlowField.vortex(self.room.size, f.cell, f.clockwise)

    # -- each tick --------------------------------------------------------------------------
    def tick(self, t: float, percept: Callable[[int, str], float], emit: Callable[..., None]) -> list[tuple[int, NoteEvent]]:
        """Visitors from the tracker, ``when`` weights from the creatures' percepts (``percept(i,
        name)``), the zones, then the sub-steps up to ``t``. Returns the note objects struck:
        (creature index, note) for the caller to play as that creature's."""
        self._visitors(t, emit)
        self._loud = [(end, where) for end, where in self._loud if end > t]
        self.crowd.around.loud = np.array([w for _, w in self._loud]).reshape(-1, 2)
        if self._player is not None and self._player[0] <= t:
            self._player = None
        self.crowd.around.player = np.zeros((0, 2)) if self._player is None else self._player[1][None, :]
        for i, b, name in self._when:
            self.crowd.gain[i, b] = min(max(percept(i, name), 0.0), 1.0)
        self.zones.update(t, self.v, emit)
        if self.share is not None:
            self._take_share(t, emit)
        self.crowd.listeners = np.vstack([self.crowd.around.visitors, self.listener[None, :]])  # who is heard, near
        if self.sounding is not None:
            self.crowd.loudness = self.sounding.loudness(t)
        if clock_gap(self.crowd.t, t):
            self.crowd.skip_to(t)  # a gap is not lived: the crowd stands through it
        self.crowd.advance_to(t)
        self._markers = None  # the crowd moved: placed again when next drawn
        self.gaits.advance(self.v.pos, self.v.max_speed * max(t - self._walked_at, 0.0) + 1e-9)
        self._walked_at = t
        struck = self._strikes(t, emit)
        if self.share is not None:
            self.share.publish(self.crowd.t, list(self.index), self._rows(self.v.vel))
        if t + 1e-9 >= self._next_report:  # where everyone is, for the report and for tests
            self._next_report = next_on_grid(self._next_report, self.section.report_every, t)
            shared = {} if self.share is None else self._shared_report()
            emit("room", pos=np.round(self.v.pos, 3 + bool(shared)).tolist(),
                 heading=np.round(self.v.heading, 3).tolist(),
                 visitors=np.round(self.crowd.around.visitors, 3).tolist(), masked=self.masked, **shared)
        return struck

    def _strikes(self, t: float, emit: Callable[..., None]) -> list[tuple[int, NoteEvent]]:
        """Creatures that stepped onto a note object since the last tick, with its note (a
        creature standing on one strikes it once; stepping off and on again strikes again).
        The way walked since the last tick counts, not only where it ends: one that crossed a
        small object within a tick (faster than its width per tick) struck it in passing."""
        if not len(self.notes):
            return []
        struck = []  # the way includes where it ends: standing on one now counts
        for k, i in zip(*np.nonzero(self._crossed(self._was_at, self.v.pos) & ~self._on_note)):
            spec = self.section.notes[k]
            emit("struck", note=int(k), creature=self.creatures[i].name, pitch=spec.pitch)
            struck.append((int(i), NoteEvent(round(t, 6), spec.pitch, spec.velocity, 0, spec.duration)))
        self._on_note = self._standing()
        self._was_at = self.v.pos.copy()
        return struck

    def _crossed(self, start: np.ndarray, end: np.ndarray) -> np.ndarray:
        """(notes, creatures) bool: whose straight way from ``start`` to ``end`` passes within a
        note object's radius."""
        way = end - start  # (N, 2)
        length = np.maximum((way ** 2).sum(axis=1), 1e-12)
        along = np.clip(((self.notes[:, None, :] - start[None]) * way[None]).sum(axis=2) / length, 0.0, 1.0)
        nearest = start[None] + along[..., None] * way[None]
        return norms(self.notes[:, None, :] - nearest) <= self._note_radius

    def _standing(self) -> np.ndarray:
        """(notes, creatures) bool: who stands on which note object now (a way of no length)."""
        return self._crossed(self.v.pos, self.v.pos)

    def note_marks(self) -> list[tuple[tuple[float, float, float], int]]:
        """The note objects as the frames draw them: on the floor, room (x, y) at world (x, 0, −y)."""
        return [((float(n.at[0]), 0.0, -float(n.at[1])), n.pitch) for n in self.section.notes]

    def _rows(self, velocity: np.ndarray) -> np.ndarray:
        """This process's creatures as a shared room's wire carries them (creatures/room/wire.py)."""
        v = self.v
        return np.column_stack([v.pos, velocity, v.heading, v.radius])

    def _shared_report(self) -> dict[str, object]:
        """What a ``room`` event adds in a shared room: where it sees the others' creatures, at
        which Unix time (and Link beat), so processes' views can be checked against each other."""
        share = self.share
        assert share is not None
        shared: dict[str, object] = {
            "others": dict(zip(self._remote, np.round(self.crowd.around.others[:, :2], 4).tolist())),
            "unix": round(share.epoch + self.crowd.t, 6)}
        if share.timeline is not None:
            shared["beat"] = round(share.beat(self.crowd.t), 6)
        return shared

    def deciding(self, tick: int, dt: float) -> np.ndarray | None:
        """Which creatures perceive and decide on tick number ``tick`` (``[room.lod] decide``),
        None for all: a creature at level L once it has waited 2**L ticks, and of more than
        ``decide_budget`` the most overdue (waited / period) first, the nearer on a tie, then in
        turn, so a far creature cut one tick is first in line the next and none starves. A level's
        period is capped so that a creature still decides at least every half second at a tick
        of ``dt``: a longer wait would look like a clock gap (:data:`creatures.clock.CLOCK_GAP`)
        to its action-groups."""
        lod = self.section.lod
        if lod is None or not lod.decide:
            return None
        cap = max(int(np.floor(np.log2(max(0.5 / dt, 1.0)))), 0)
        period = np.left_shift(1, np.minimum(self.crowd.level, cap))
        waited = tick - self._decided
        due = overdue_first(np.nonzero(waited >= period)[0], waited, period, self.crowd.level, tick,
                            lod.decide_budget)
        self._decided[due] = tick
        return due

    def begin(self, t: float) -> None:
        """A live run's first tick is at ``t``: the time spent setting up is not lived (under a
        second of it would be, as steps, and a restarted process's creatures would set off from
        their saved places before the first tick: 0.35 m in one CI run)."""
        self.crowd.skip_to(t)
        self._walked_at = t

    def keep_sharing(self, t: float) -> None:
        """A paused run (the console's pause, the schedule's night) stays in the shared room: its
        creatures stand where they are (sent with no velocity, so no one's dead reckoning walks
        them on), and what the others say is read and dropped (a paused colony forgets what it
        heard, as ``World.forget`` does), so they do not time it out."""
        if self.share is None:
            return
        self.share.poll(t)
        self.share.publish(t, list(self.index), self._rows(np.zeros_like(self.v.vel)))

    def _take_share(self, t: float, emit: Callable[..., None]) -> None:
        """What the room's other processes said: their notes into the note bus (heard from
        where their creatures stand), their creatures placed as they stand at the crowd's time
        (the sub-steps up to ``t`` move them on), who joined and left, and with Link each
        shared beat heard by the colony's pulse (one beat and tempo for the whole room)."""
        share, world = self.share, self._world
        assert share is not None and world is not None
        notes = share.poll(t)
        names, rows = share.others(self.crowd.t)
        self._remote = {name: i for i, name in enumerate(names)}
        self.crowd.around.others = np.clip(rows, [0, 0, -np.inf, -np.inf, -1, -1, 0],
                                           [*self.room.size, np.inf, np.inf, 1, 1, np.inf])
        for name, note in notes:
            world.inject(note, name)  # logged as heard from that creature, from where it stands
        for owner in share.joined:
            emit("room peer", owner=owner, creatures=sum(r.owner == owner for r in share.remote.values()))
        for owner, why in share.left:
            emit("room peer left", owner=owner, why=why)
        for name, owner, other in share.clashes:
            emit("room owner clash", creature=name, owner=owner, other=other)
        share.joined, share.left, share.clashes = [], [], []
        if share.timeline is not None:
            beat = share.timeline.beat_at(share.epoch + t)
            if not self._next_beat - 2 <= beat <= self._next_beat + 4:  # joining, a suspend, a jump: start again
                self._next_beat = np.ceil(beat)
            while self._next_beat <= beat:
                world.pulse.hear(t - (beat - self._next_beat) * 60.0 / share.timeline.tempo)
                self._next_beat += 1

    def _visitors(self, t: float, emit: Callable[..., None]) -> None:
        seen, moving = [], []
        for i, visitor in enumerate(self.section.visitors):
            x, y = self.sensors.get(visitor.x), self.sensors.get(visitor.y)
            fresh = [s is not None and len(s) > 0 and s.times_array[-1] >= t - visitor.timeout for s in (x, y)]
            if fresh[0] != fresh[1]:
                self._half_seen(i, visitor, fresh[0], t, emit)
            if not all(fresh):
                continue  # the tracker lost them (or never found them): gone
            self._half.pop(i, None)
            seen.append((float(x.latest()), float(y.latest())))
            moving.append(self._velocity(x, y))
        room = self.crowd.around
        room.visitors = np.clip(np.array(seen, float).reshape(-1, 2), 0.0, self.room.size)
        room.visitor_vel = np.array(moving, float).reshape(-1, 2)

    def _half_seen(self, i: int, visitor: VisitorSpec, has_x: bool, t: float, emit: Callable[..., None]) -> None:
        """Visitor ``i`` has one coordinate and not the other. Shown only whole, such a visitor
        was never there and nothing said why (a tracker sending ``/visitor/1 x`` alone, a map's
        ``value = { arg = 1 }`` for a message of one argument); once it has stayed so for its
        ``timeout`` it is said once, as a ``room visitor half`` event, until it is seen whole."""
        since = self._half.setdefault(i, t)
        if since is not None and t - since >= visitor.timeout:
            heard, missing = (visitor.x, visitor.y) if has_x else (visitor.y, visitor.x)
            emit("room visitor half", visitor=i, heard=heard, missing=missing)
            self._half[i] = None

    @staticmethod
    def _velocity(x: "StateObject", y: "StateObject") -> tuple[float, float]:
        """From the last two readings of each sensor (0 with fewer)."""
        def rate(s: "StateObject") -> float:
            times, data = s.times_array, s.data
            if len(times) < 2 or times[-1] <= times[-2]:
                return 0.0
            return (float(data[-1]) - float(data[-2])) / (times[-1] - times[-2])
        return rate(x), rate(y)

    # -- where each creature stood, across a restart ------------------------------------------
    def figure(self, creature: "CreatureKind", own: np.ndarray) -> np.ndarray:
        """``creature``'s joints where it stands in the room, facing its heading: its walk if it
        has a gait, else ``own`` (its figure's joints, root motion's travel taken off: in a room
        the vehicle carries the body)."""
        i = self.index[creature.name]
        local = own - _travel(creature)
        return self.gaits.figure(i, local, self.v.pos[i], self.v.heading[i], float(np.hypot(*self.v.vel[i])))

    def marker(self, creature: "CreatureKind") -> tuple[np.ndarray, np.ndarray]:
        """The :data:`MARKER` of ``creature`` (one without a body) where it stands, turned to its
        heading: joints and parents, as a figure. Every creature's are placed in one call after
        the crowd moves: the live view asks for each at 30 frames a second on the creature's
        thread, and a thousand placed one by one took ~30 ms a frame."""
        if self._markers is None:
            self._markers = in_room(MARKER, self.v.pos, self.v.heading)
        return self._markers[self.index[creature.name]].copy(), MARKER_PARENTS.copy()

    def carry(self, creature: "CreatureKind", points: np.ndarray) -> np.ndarray:
        """Points ``(K, 3)`` in ``creature``'s own space (its note objects) where it stands in the
        room, turned with it."""
        i = self.index[creature.name]
        return in_room(points - _travel(creature), self.v.pos[i], self.v.heading[i])

    def placement(self, name: str) -> dict[str, list[float]]:
        """Where creature ``name`` stands and how it moves, for its state file (a process of a
        shared room that is killed and started again puts its creatures back where they were)."""
        i = self.index[name]
        return {"at": self.v.pos[i].tolist(), "velocity": self.v.vel[i].tolist(), "heading": self.v.heading[i].tolist()}

    def put(self, name: str, place: dict[str, Any]) -> None:
        """Take back a :meth:`placement` (ValueError/TypeError/KeyError on a damaged one; a place
        off this room's floor is brought onto it, as a smaller room's config may have moved the walls)."""
        i = self.index[name]
        at, velocity, heading = (np.array([bounds.number(x, f"place.{key}") for x in bounds.items(
            place[key], f"place.{key}", shortest=2, longest=2)]) for key in ("at", "velocity", "heading"))
        if not np.hypot(*heading) > 0:
            raise ValueError("place.heading: a heading of length 0")
        self.v.pos[i] = np.clip(at, 0.0, self.room.size)
        self.v.vel[i] = velocity if np.hypot(*velocity) <= self.v.max_speed[i] else np.zeros(2)
        self.v.heading[i] = heading / np.hypot(*heading)
        self._markers = None
        self.gaits.moved(i, self.v.pos[i])
        self._on_note[:, i] = self._standing()[:, i]  # a place taken back strikes nothing
        self._was_at[i] = self.v.pos[i]  # nor does the jump to it

    # -- hearing -----------------------------------------------------------------------------
    def source_at(self, source: str) -> np.ndarray:
        """Where a sound of ``source`` comes from: its creature, else (input) the first tracked
        visitor, else ``input_at``, else the listener."""
        if source in self.index:
            return self.v.pos[self.index[source]].copy()
        if source in self._remote:
            return self.crowd.around.others[self._remote[source], :2].copy()
        if len(self.crowd.around.visitors):
            return self.crowd.around.visitors[0].copy()
        return np.array(self.section.input_at if self.section.input_at is not None else self.listener, float)

    def emit(self, note: NoteEvent, source: str) -> None:
        """A note has started at its source: it reaches each other creature's ear after
        distance/343 s, attenuated by the law."""
        where = self.source_at(source)
        if note.velocity >= self.section.hearing.loud:
            self._loud.append((note.time + LOUD_FOR, where))
        if source not in self.index and source not in self._remote:  # a shared room's creatures are not players
            self._player = (note.time + PLAYER_FOR, where)
        me = self.index.get(source, -1)
        starts, ends, dbs = arrivals(note.time, note.duration, velocity_db(note.velocity), norms(self.v.pos - where),
                                     self.law, delay=self.section.hearing.delay)
        ears = np.arange(len(starts))
        if me >= 0:  # not its own ear
            starts, ends, dbs, ears = (np.delete(x, me) for x in (starts, ends, dbs, ears))
        if len(ears) == 0:  # no other ear in the room: nothing to fly, and nothing to keep (due forgets
            return          # a note only when its last arrival lands, which it would never have)
        number = next(self._emitted)
        self._sounds[number] = (note, source)
        row = {"start": starts, "end": ends, "db": dbs, "pitch": np.full(len(ears), float(note.pitch)), "ear": ears,
               "note": np.full(len(ears), number)}
        self._new_rows.append(row)

    def due(self, t: float) -> list[tuple[int, NoteEvent, str]]:
        """What each ear hears by ``t``: (creature index, the note as it arrives, its source), in
        the order the sounds arrive (start, then the order the notes were emitted, then ear),
        leaving out what is masked by a louder sound already sounding at that ear."""
        if self._new_rows:
            self._flying = {key: np.concatenate([x, *(row[key] for row in self._new_rows)])
                            for key, x in self._flying.items()}
            self._new_rows = []
        flying = self._flying
        now = flying["start"] <= t
        if not now.any():
            return []
        taken = np.flatnonzero(now)
        taken = taken[np.lexsort((flying["ear"][taken], flying["note"][taken], flying["start"][taken]))]
        ear, start, db, number = (flying[key][taken] for key in ("ear", "start", "db", "note"))
        heard = self._ears.hear(ear, start, flying["end"][taken], db, flying["pitch"][taken])
        self.masked += len(taken) - int(np.count_nonzero(heard))
        self._flying = {key: x[~now] for key, x in flying.items()}
        out = []
        velocities = np.clip(np.round(db_velocity(db[heard])), 1, 127).astype(np.int64)  # round half to even, as round()
        for i, at, velocity, k in zip(ear[heard].tolist(), start[heard].tolist(), velocities.tolist(),
                                      number[heard].tolist()):
            note, source = self._sounds[k]
            out.append((i, NoteEvent(round(at, 6), note.pitch, velocity, note.channel, note.duration), source))
        for k in np.setdiff1d(number, self._flying["note"]).tolist():
            del self._sounds[k]  # every ear has it
        return out

    # -- where each voice sounds ---------------------------------------------------------------
    def speaker_gains(self) -> np.ndarray:
        """Every creature's amplitude gains on each output channel, (N, channels): its
        direction from the listener panned over the speakers (stereo or VBAP), times the
        distance law. A dome has the floor projected onto it: a creature at the listener sounds
        from overhead, one ``dome_reach`` away or further from ear height (the room's floor is
        flat, and the dome's height would otherwise only ever carry the ring's sound)."""
        pos = self.v.pos
        az = np.atleast_1d(azimuth(pos, self.listener))
        distance = norms(pos - self.listener)
        if self.dome is not None:  # the floor mapped onto the dome: nearer is higher
            pan = self.dome.gains(az, 90.0 * (1.0 - np.minimum(distance / self._reach, 1.0)))
        else:
            pan = stereo(az) if self.speakers is None else vbap(az, self.speakers)
        return pan.reshape(len(pos), -1) * self.law.gain(distance)[:, None]

    # -- what a creature perceives of the room (the percepts of creatures/authored/percepts.py) --
    def _everyone(self) -> np.ndarray:
        """Where every creature stands now: the crowd's, then a shared room's remote ones (the
        points of :meth:`_index`, built with it)."""
        self._index()
        return self._points

    def _index(self) -> cKDTree:
        """A kd-tree of every creature as it stands now (rebuilt once per sub-step it is asked in)."""
        if self._tree_at != self.crowd.steps:
            others = self.crowd.around.others
            self._points = np.vstack([self.v.pos, others[:, :2]]) if len(others) else self.v.pos.copy()
            self._tree, self._tree_at = cKDTree(self._points), self.crowd.steps
        return self._tree

    def nearest(self, name: str, of: str) -> np.ndarray | None:
        """Where the nearest visitor, other creature, player or loud sound to creature ``name``
        is (None when there is none)."""
        i = self.index[name]
        here = self.v.pos[i]
        if of == "creature":
            everyone = self._everyone()
            if len(everyone) < 2:
                return None
            _, j = self._index().query(here, k=2)
            return everyone[j[1] if j[0] == i else j[0]]
        around = self.crowd.around
        points = {"visitor": around.visitors, "player": around.player, "loud": around.loud}[of]
        if not len(points):
            return None
        return points[int(np.argmin(norms(points - here)))]

    def distance(self, name: str, of: str) -> float:
        """Metres to the nearest ``of`` (inf when there is none)."""
        where = self.nearest(name, of)
        return np.inf if where is None else float(norms(where - self.v.pos[self.index[name]]))

    def bearing(self, name: str, of: str) -> float | None:
        """Degrees from creature ``name``'s heading to the nearest ``of`` (0 ahead, ±180 behind,
        positive to its left; None when there is none)."""
        where = self.nearest(name, of)
        return None if where is None else self._bearing(name, where)

    def toward(self, name: str, source: str) -> float | None:
        """Degrees from creature ``name``'s heading to ``source`` as the world names who played
        a note: another creature of the room, or ``input`` (the player, where the last outside
        note came from); None when it is not placed."""
        if source in self.index or source in self._remote:
            return self._bearing(name, self.source_at(source))
        return self.bearing(name, "player")

    def _bearing(self, name: str, where: np.ndarray) -> float:
        i = self.index[name]
        rel = where - self.v.pos[i]
        h = self.v.heading[i]
        return float(np.degrees(np.arctan2(h[0] * rel[1] - h[1] * rel[0], h @ rel)))

    def crowding(self, name: str, radius: float) -> int:
        """How many other creatures are within ``radius`` m of creature ``name``."""
        return int(self._index().query_ball_point(self.v.pos[self.index[name]], radius, return_length=True)) - 1

    def sees(self, name: str, of: str) -> int:
        """How many visitors or other creatures creature ``name`` sees (its cone, its range,
        obstacles in the way: creatures/room/vision.py)."""
        i = self.index[name]
        spec = self.creatures[i].spec.vehicle
        if of == "visitor":
            things = self.crowd.around.visitors
        else:
            near = self._index().query_ball_point(self.v.pos[i], spec.sight)
            things = self._everyone()[[j for j in near if j != i]]
        if not len(things):
            return 0
        return int(visible(self.v.pos[i:i + 1], self.v.heading[i:i + 1], things, self.room, fov=spec.fov,
                           range_=spec.sight).sum())


def _travel(creature: "CreatureKind") -> np.ndarray:
    """The horizontal offset root motion has given ``creature``'s own pose (zero without a body)."""
    body = getattr(creature, "body", None)
    offset = np.zeros(3) if body is None else np.array(getattr(body, "offset", np.zeros(3)), dtype=float)
    offset[1] = 0.0
    return offset
