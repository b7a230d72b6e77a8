"""The config of a room: the installation's ``[room]`` table and each creature's
``[creature.vehicle]`` table (documented in docs/config.md from these field descriptions).

Every number is bounded and every list has a maximum length (a config is read in a gallery,
where a typo must be an error at its line, never a night of nonsense).
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import AfterValidator, BaseModel, Field, ValidationError, model_validator

from creatures.bounds import FINITE, Bounded
from creatures.config import nearest
from creatures.room.recipe import BEHAVIOURS

BODY_KEYS = ("max_speed", "max_force", "mass", "radius", "max_turn")
"""The ``[creature.vehicle]`` keys a zone's ``spec`` may override (the vehicle's columns; its
other keys are read when the room is built)."""

LIGHTEST = 0.001
"""Kilograms: the least mass of a vehicle. Any positive mass was taken, and under ~1e-308 kg
(a subnormal float) force / mass overflowed to infinity and every position became NaN."""

LARGEST_ROOM = 1000.0
"""Metres: the longest side a room may have (a field, not a continent)."""

Metres = Annotated[float, Field(ge=0, le=LARGEST_ROOM)]
"""A coordinate on the floor, m from the room's corner."""

Point = tuple[Metres, Metres]

Degrees = Annotated[float, Field(ge=-360, le=360)]
"""An azimuth, anticlockwise from +x as seen from the listening point."""

Elevation = Annotated[float, Field(ge=-90, le=90)]
"""An elevation above the horizontal through the listener's ears."""


class Strict(BaseModel):
    model_config = FINITE


class ObstacleSpec(Strict):
    """A round obstacle: ``at`` [x, y] and ``radius``, metres."""

    at: Point = Field(description="centre [x, y], m from the room's corner")
    radius: float = Field(gt=0, le=LARGEST_ROOM, description="radius, m")


class VisitorSpec(Strict):
    """A tracked visitor: two sensors of the input map (``[[input]]`` with ``to = "sensor"``,
    e.g. an OSC tracker's ``/visitor/1 x y``) giving their position. One heard without the
    other for ``timeout`` is said once in the events log (a ``room visitor half`` event)."""

    x: str = Field(description="sensor holding x, m (scale a tracker's 0..1 with the map's `range`)")
    y: str = Field(description="sensor holding y, m")
    timeout: float = Field(2.0, gt=0, le=3600, description="seconds without a reading before the visitor "
                                                           "counts as gone")


class ZoneSpec(Strict):
    """An ActionBox (REACT): a rectangle of floor that changes each creature inside it, and
    undoes the change when it leaves."""

    name: str = Field(pattern=r"^[A-Za-z0-9_\-]+$", description="the zone's name (in the events log)")
    low: Point = Field(description="one corner [x, y], m")
    high: Point = Field(description="the opposite corner [x, y], m")
    drives: dict[str, Bounded] = Field(default_factory=dict, max_length=64,
                                     description="drives set to these levels on entry (restored on leaving)")
    spec: dict[str, float | int | str | bool] = Field(
        default_factory=dict, max_length=64,
        description="keys overridden inside: the vehicle's max_speed, max_force, mass, radius, max_turn, or any "
                    "key of the creature's spec the remote console may set (gain, hears_input, voice.gain, …; "
                    "dotted for a nested table, a name that holds a dot quoted whole: notes.\"sit.low\")")
    enable: list[str] = Field(default_factory=list, max_length=256, description="tuples enabled inside (and "
                                                                            "off everywhere else)")
    disable: list[str] = Field(default_factory=list, max_length=256, description="tuples disabled inside")

    @model_validator(mode="after")
    def _body_keys(self) -> "ZoneSpec":
        """The vehicle's keys are numbers within ``[creature.vehicle]``'s own bounds here (one
        bound for all, (0, 36000], let a zone set 36000 m/s or a mass of 1e-310 kg, which made
        positions NaN); a creature's spec keys are checked against the creatures' specs when
        the room is (creatures.room.stage.check_places)."""
        for key, value in self.spec.items():
            if key not in BODY_KEYS:
                continue
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ValueError(f"zone {self.name!r}: spec[{key!r}] = {value!r} must be a number")
            try:
                VehicleSpec.model_validate({key: value})
            except ValidationError as error:
                raise ValueError(f"zone {self.name!r}: spec[{key!r}] = {value!r}: "
                                 f"{error.errors()[0]['msg']}") from None
        return self


class PathSpec(Strict):
    """A path (REACTPath) the crowd may follow: points and how far it may stray."""

    name: str = Field(pattern=r"^[A-Za-z0-9_\-]+$", description="named by `path = ` in a steer table")
    points: list[Point] = Field(min_length=2, max_length=1024, description="[x, y] points, m")
    radius: float = Field(0.5, gt=0, le=LARGEST_ROOM, description="how far from the line it may stray, m")


class NoteObjectSpec(Strict):
    """A note object on the floor (thesis: exchange's and sand:stone's note objects, here in the
    room): a creature that steps onto it plays its note, once per stepping on."""

    at: Point = Field(description="where it lies [x, y], m")
    pitch: int = Field(ge=0, le=127, description="MIDI pitch it sounds")
    velocity: int = Field(90, ge=1, le=127, description="MIDI velocity")
    duration: float = Field(0.5, gt=0, le=60, description="seconds it sounds")
    radius: float = Field(0.3, gt=0, le=LARGEST_ROOM, description="how near counts as on it, m")


class FlowSpec(Strict):
    """A flow field (REACTFlowfield) over the room."""

    name: str = Field(pattern=r"^[A-Za-z0-9_\-]+$", description="named by `field = ` in a steer table")
    shape: Literal["uniform", "vortex", "painted"] = Field(
        "vortex", description="'uniform' (one direction), 'vortex' (round the room's centre) or 'painted' (`rows`)")
    direction: tuple[Annotated[float, Field(ge=-1, le=1)], Annotated[float, Field(ge=-1, le=1)]] = Field(
        (1.0, 0.0), description="shape = 'uniform': the direction [dx, dy]")
    clockwise: bool = Field(False, description="shape = 'vortex': which way round")
    cell: float = Field(0.5, gt=0.01, le=LARGEST_ROOM, description="grid cell, m (uniform, vortex)")
    rows: list[Annotated[str, Field(min_length=1, max_length=1000, pattern=r"^[<>^v.]+$")]] | None = Field(
        None, min_length=1, max_length=1000,
        description="shape = 'painted': the room as a plan, one string per row of cells, the first along the back "
                    "wall (y = depth), the last along the front (y = 0): '>' east (+x), '<' west, '^' toward the "
                    "back (+y), 'v' toward the front, '.' no flow; the rows are stretched over the room")

    @model_validator(mode="after")
    def _painted(self) -> "FlowSpec":
        if self.shape == "painted":
            if not self.rows:
                raise ValueError("shape = 'painted' needs rows (strings of > < ^ v and .)")
            if len({len(r) for r in self.rows}) > 1:
                raise ValueError(f"every row of a painted field must be as long as the first "
                                 f"({len(self.rows[0])} cells); got lengths {[len(r) for r in self.rows]}")
        elif self.rows is not None:
            raise ValueError(f"rows paint a field: shape = 'painted', not {self.shape!r}")
        return self


class HearingSpec(Strict):
    """How sound crosses the room: a distance law, the speed of sound, and masking."""

    law: Literal["inverse", "inverse_square", "linear"] = Field(
        "inverse", description="level against distance: 'inverse' (−6 dB per doubling), 'inverse_square' "
                               "(−12 dB), 'linear' (amplitude to silence at `silent`)")
    reference: float = Field(1.0, gt=0, le=LARGEST_ROOM, description="distance of full level, m")
    silent: float = Field(20.0, gt=0, le=LARGEST_ROOM, description="law = 'linear': distance of silence, m")
    delay: bool = Field(True, description="sound arrives distance/343 s late")
    margin: float = Field(20.0, ge=0, le=120, description="a sound this many dB louder masks a quieter one "
                                                         "overlapping it in time")
    band: float = Field(12.0, ge=0, le=128, description="semitones within which a louder note masks")
    threshold: float = Field(-60.0, ge=-200, le=0, description="dB (re velocity 127 at the reference "
                                                               "distance) below which nothing is heard")
    loud: float = Field(100.0, ge=1, le=127, description="velocity from which a note is a loud sound "
                                                         "(steer target 'loud') for one second")


class LodSpec(Strict):
    """Level of detail: far creatures steer less often, within a budget per sub-step."""

    near: float = Field(4.0, gt=0, le=LARGEST_ROOM, description="m from the nearest visitor (or the listener) "
                                                               "within which a creature steers every sub-step; each "
                                                               "further `near` halves its rate")
    levels: int = Field(3, ge=0, le=8, description="slowest rate is one sub-step in 2**levels")
    unheard: int = Field(0, ge=0, le=8, description="levels added for a creature the nearest visitor or listener "
                                                    "does not hear: not sounding, or its note under [room.hearing] "
                                                    "threshold there (0: levels by distance alone)")
    budget: int | None = Field(None, ge=1, le=1_000_000, description="most creatures steering in one sub-step")
    decide: bool = Field(True, description="far creatures also perceive and decide (their behaviour's tick) at "
                                           "the lower rate")
    decide_budget: int | None = Field(None, ge=1, le=1_000_000, description="decide = true: most creatures "
                                      "deciding in one tick (the most overdue first, the nearer on a tie, so none "
                                      "starves; none = no limit)")


def _peer(peer: str) -> str:
    """A ``[room.share]`` peer in the form ``host:port``, checked on its own so that an error
    names its place in the list (that the host resolves, and to IPv4, is checked at load:
    creatures.runtime.schema.peer_problem)."""
    host, _, port = peer.rpartition(":")
    if not host or not (port.isascii() and port.isdigit()) or not 0 < int(port) < 65536:
        raise ValueError(f"peer {peer!r} is not 'host:port' (a port in 1..65535)")
    return peer


Peer = Annotated[str, AfterValidator(_peer)]


class ShareSpec(Strict):
    """``[room.share]``: this process owns its creatures in a room that others share
    (creatures/room/share.py): it sees and hears their creatures and they see and hear its."""

    room: str = Field(pattern=r"^[A-Za-z0-9_.\-]{1,64}$", description="the shared room's name: processes "
                      "with the same name (and the same room size) share one floor")
    host: str = Field("127.0.0.1", description="address to listen on ('0.0.0.0' to be reached from other "
                                               "machines)")
    port: int = Field(0, ge=0, le=65535, description="UDP port to listen on (0: any free one; discovery tells "
                                                     "the others)")
    peers: list[Peer] = Field(default_factory=list, max_length=64, description="'host:port' of processes to reach "
                              "without discovery")
    discover: bool = Field(True, description="find the room's other processes by mDNS (zeroconf)")
    link: bool = Field(False, description="keep one beat and tempo with the others over Ableton Link (aalink); "
                                          "positions and notes are stamped on its timeline")
    tempo: float = Field(120.0, ge=20, le=999, description="link = true: the tempo to start a Link session at "
                                                           "(joining one takes its tempo)")
    rate: float = Field(25.0, gt=0, le=200, description="position updates sent a second")
    timeout: float = Field(2.0, gt=0, le=3600, description="seconds without a word before a process's creatures "
                                                           "leave the room")


class RoomSection(Strict):
    """``[room]``: the floor the creatures stand on (issue 21; REACT, IViHumans, WavesWorld's
    raveWorld). With a room, each creature has a place (``[creature.vehicle]``), hears others
    by distance and sounds from where it stands."""

    width: float = Field(10.0, gt=0, le=LARGEST_ROOM, description="x extent, m")
    depth: float = Field(10.0, gt=0, le=LARGEST_ROOM, description="y extent, m")
    obstacles: list[ObstacleSpec] = Field(default_factory=list, max_length=256, description="round obstacles on the floor")
    substep: float = Field(0.01, ge=0.001, le=0.1, description="fixed integration step, s (the tick does "
                                                               "not change the paths)")
    listener: Point | None = Field(None, description="where out.wav's listener stands [x, y] "
                                                                   "(default: the middle of the near wall, y = 0)")
    speakers: Literal["stereo", "ring", "dome"] = Field(
        "stereo", description="out.wav and live output: a stereo pair, a ring of `channels` speakers (2-D VBAP) "
                              "or a dome (3-D VBAP over `dome`)")
    channels: int = Field(8, ge=2, le=64, description="speakers = 'ring': how many")
    dome: list[tuple[Degrees, Elevation]] | None = Field(
        None, min_length=3, max_length=64, description="speakers = 'dome': each speaker's [azimuth, elevation] "
                                                       "degrees, one channel each in this order (default: eight "
                                                       "at ear height from 0°, four at 45° from 45°, one overhead)")
    dome_reach: float | None = Field(None, gt=0, le=LARGEST_ROOM, description="speakers = 'dome': a creature at "
                                     "the listener sounds overhead, one this far or further at ear height, "
                                     "between them lower with distance, m (default: the farthest corner)")
    input_at: Point | None = Field(None, description="where input notes sound when no visitor "
                                                                   "is tracked (default: the listener)")
    visitors: list[VisitorSpec] = Field(default_factory=list, max_length=64, description="visitors tracked through the input map's sensors (a sensor of its own for each coordinate of each)")
    hearing: HearingSpec = HearingSpec()
    lod: LodSpec | None = Field(None, description="[room.lod]; none = every creature steers every sub-step")
    zones: list[ZoneSpec] = Field(default_factory=list, max_length=256, description="zones (REACT's ActionBoxes) that change the creatures inside")
    paths: list[PathSpec] = Field(default_factory=list, max_length=256, description="paths for path_following")
    notes: list[NoteObjectSpec] = Field(default_factory=list, max_length=1024,
                                        description="note objects on the floor, struck by stepping on them; "
                                                    "`target = \"note\"` steers to the nearest")
    flows: list[FlowSpec] = Field(default_factory=list, max_length=64, description="flow fields for flow_following")

    @model_validator(mode="after")
    def _layout(self) -> "RoomSection":
        """A dome's channels are its speakers: ``channels`` beside it would be a second count."""
        if self.speakers == "dome" and "channels" in self.model_fields_set:
            raise ValueError("channels: a dome has one channel per speaker of `dome`; leave channels out")
        if self.speakers != "dome" and ({"dome", "dome_reach"} & self.model_fields_set):
            raise ValueError("dome and dome_reach are for speakers = \"dome\"")
        if self.speakers == "dome" and self.dome is not None:
            from creatures.room.speakers import Dome

            Dome(self.dome)  # its ValueError is the config's: a layout that cannot pan is refused here
        return self
    report_every: float = Field(1.0, gt=0, le=3600, description="seconds between 'room' events in the log: "
                                                                "every creature's position and heading, the visitors', "
                                                                "and 'masked', the notes a louder sound has hidden at "
                                                                "some ear since the run began (cumulative)")
    share: ShareSpec | None = Field(None, description="[room.share]: one room across processes and machines "
                                                      "(live runs)")


AIMED = ("seek", "flee", "arrival", "pursuit", "evasion", "leader_following")
"""The behaviours that steer by a ``target``."""

TAKEN_BY: dict[str, tuple[str, ...]] = {
    "target": AIMED, "slowing": ("arrival", "leader_following"), "panic": ("flee", "evasion"),
    "behind": ("leader_following",), "path": ("path_following",), "field": ("flow_following",),
    "rate": ("wander",),
}
"""Each parameter of a steer table and the behaviours that take it: a parameter set on any other
loaded, and the behaviour's function refused it at the first sub-step (a traceback mid-run)."""


class SteerSpec(Strict):
    """One steering behaviour of a creature (``[[creature.vehicle.steer]]``), in priority order."""

    behaviour: str = Field(description="one of: " + ", ".join(sorted(BEHAVIOURS)))
    weight: float = Field(1.0, ge=0, le=100, description="its weight in the combination")
    probability: float = Field(1.0, ge=0, le=1, description="combine = 'dithering': chance it is considered")
    when: str | None = Field(None, description="a percept of the creature whose value (0..1) scales the weight "
                                               "each tick (gathering only while someone plays)")
    target: str | Point | None = Field(
        None, description=", ".join(AIMED) + ": 'visitor' (the nearest), "
                          "'player' (where the last note from outside came from, for 4 s), 'loud' (the nearest "
                          "loud sound), 'note' (the nearest [[room.notes]] object), 'centre', [x, y], or another "
                          "creature's name; none: 'visitor'")
    slowing: float | None = Field(None, gt=0, le=LARGEST_ROOM,
                                  description="arrival, leader_following: slowing distance, m")
    panic: float | None = Field(None, gt=0, le=LARGEST_ROOM, description="flee, evasion: only within this, m")
    behind: float | None = Field(None, gt=0, le=LARGEST_ROOM, description="leader_following: distance behind, m")
    path: str | None = Field(None, description="path_following: a [[room.paths]] name")
    field: str | None = Field(None, description="flow_following: a [[room.flows]] name")
    rate: float | None = Field(None, ge=0, le=100, description="wander: drift of the wander angle, rad/√s")

    @model_validator(mode="after")
    def _known(self) -> "SteerSpec":
        if self.behaviour not in BEHAVIOURS:
            raise ValueError(f"unknown steering behaviour {self.behaviour!r}"
                             f"{nearest(self.behaviour, sorted(BEHAVIOURS), 'behaviours')}")
        for key in self.params():
            owners = TAKEN_BY[key]
            if self.behaviour not in owners:
                takes = [k for k, by in TAKEN_BY.items() if self.behaviour in by] + ["weight", "probability", "when"]
                raise ValueError(f"{key} is a key of {', '.join(owners[:-1]) + ' and ' if owners[1:] else ''}"
                                 f"{owners[-1]}, not of {self.behaviour} ({self.behaviour} takes: {', '.join(takes)})")
        return self

    def params(self) -> dict[str, Any]:
        """The behaviour's keyword parameters (those set)."""
        return {k: getattr(self, k) for k in TAKEN_BY if getattr(self, k) is not None}


class VehicleSpec(Strict):
    """``[creature.vehicle]``: a creature's place and body in the room (REACT's vehicle)."""

    at: Point | None = Field(None, description="start [x, y], m (default: a seeded random place)")
    heading: float | None = Field(None, ge=-360, le=360, description="start heading, degrees (default: random)")
    mass: float = Field(1.0, ge=LIGHTEST, le=1000, description="kg (at least a gram)")
    max_force: float = Field(2.0, gt=0, le=1000, description="largest steering force, N")
    max_speed: float = Field(1.0, gt=0, le=100, description="m/s")
    radius: float = Field(0.25, gt=0, le=LARGEST_ROOM, description="body radius, m")
    max_turn: float = Field(360.0, gt=0, le=36000, description="fastest turn, degrees per second")
    steer: list[SteerSpec] = Field(default_factory=list, max_length=32,
                                   description="steering behaviours, most important first")
    combine: Literal["weighted", "budget", "dithering"] = Field(
        "weighted", description="'weighted' (truncated sum), 'budget' (prioritised), 'dithering' (prioritised)")
    neighbours: int = Field(7, ge=1, le=64, description="neighbours the flocking behaviours see")
    reach: float = Field(3.0, gt=0, le=LARGEST_ROOM, description="radius of the neighbourhood, m")
    fov: float = Field(200.0, gt=0, le=360, description="vision cone, degrees")
    sight: float = Field(10.0, gt=0, le=LARGEST_ROOM, description="how far it sees, m")
    gait: str | None = Field(None, max_length=200, description="the body's clip that walks with the vehicle, played "
                                                              "by distance so its feet do not slide (e.g. the dog's "
                                                              "'walk'; creatures/room/gait.py)")
