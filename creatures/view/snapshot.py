"""The snapshot format: what anything that shows a colony is sent (docs/view.md).

One ``hello`` names the creatures, their skeletons (parent indices) and where each stands in
the picture; then ``frame`` messages carry, at one clock time, every body's joint positions as
:meth:`~creatures.kinds.base.CreatureKind.shown` gives them (the creature's own coordinates,
or in a room the room's; unrounded), its note objects in space, and the events-log records the page shows that were
emitted since the previous frame (notes played and heard, selections, drives, values, percept
sizes, xruns). A live run builds these from its creatures and its log's tap
(:mod:`creatures.view.feed`); a replay builds the very same messages from an offline run's
events log (:func:`replay`), whose ``skeleton`` and ``pose`` events :func:`skeleton_events`
and :func:`pose_event` write. Keeping the format here, in one module, is what lets another
stream (an OSC body stream) and this one stay one format.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import TYPE_CHECKING, Any, Iterable

import numpy as np

from creatures.events import json_line
from creatures.kinds.base import CreatureKind

if TYPE_CHECKING:
    from creatures.runtime.inspect import Knowledge

SPACING = 1.5
"""Metres between neighbouring creatures in the picture (the offscreen frames' layout too)."""

SHOWN = frozenset({"note", "heard", "selection", "interruption", "values", "motivation", "percepts", "xruns",
                   "timing", "reward", "drive", "network", "events lost"})
"""Events-log kinds the page shows (its plots, lists and status line read these)."""

DIGITS = 6
"""Decimals a pose keeps in the events log: micrometres, the log's own time resolution."""

Message = dict[str, Any]


def place(index: int, count: int, creature: CreatureKind | None = None) -> tuple[float, float, float]:
    """Where creature ``index`` of ``count`` stands: side by side along x, centred on 0; at the
    origin for a ``creature`` in a room, whose drawn joints are already where it stands."""
    if creature is not None and creature.stage is not None:
        return (0.0, 0.0, 0.0)
    return ((index - (count - 1) / 2) * SPACING, 0.0, 0.0)


@dataclass
class Body:
    """One creature as the view knows it: name, kind, parents (None: no body), place."""

    name: str
    kind: str
    parents: list[int] | None
    place: tuple[float, float, float]


def bodies(creatures: list[CreatureKind]) -> list[Body]:
    """Every creature's skeleton (from its first figure as drawn: in a room, one without a body
    is a marker) and place."""
    found = []
    for i, creature in enumerate(creatures):
        figure = creature.shown()
        parents = None if figure is None else [int(p) for p in figure[1]]
        found.append(Body(creature.name, creature.spec.kind, parents, place(i, len(creatures), creature)))
    return found


def hello(title: str, mode: str, found: list[Body], **status: Any) -> Message:
    """The first message: the creatures, their skeletons and places; ``mode`` live or replay."""
    return {"type": "hello", "title": title, "mode": mode,
            "creatures": [{"name": b.name, "kind": b.kind, "parents": b.parents, "place": list(b.place)}
                          for b in found], "status": status}


def marks_of(creature: CreatureKind) -> list[list[float]]:
    """A creature's note objects as ``[x, y, z, pitch]`` rows, as drawn (its own coordinates, or
    the room's)."""
    return [[float(x) for x in position] + [float(pitch)] for position, pitch in creature.shown_marks()]


def frame(t: float, creatures: Iterable[CreatureKind], events: list[Message] | None = None) -> Message:
    """One frame at clock time ``t``: every body's joints (copied: a figure may be a view of
    state the next tick changes), every creature's note objects, and ``events``."""
    joints, marks = {}, {}
    for creature in creatures:
        figure = creature.shown()
        if figure is not None:
            joints[creature.name] = np.array(figure[0], dtype=float)
        shown = marks_of(creature)
        if shown:
            marks[creature.name] = shown
    return {"type": "frame", "t": float(t), "bodies": joints, "marks": marks, "events": events or []}


def skeleton_events(found: list[Body]) -> list[Message]:
    """``skeleton`` events' fields (one per creature with a body) for the events log."""
    return [{"creature": b.name, "kind_of": b.kind, "parents": b.parents, "place": list(b.place)}
            for b in found if b.parents is not None]


def pose_event(creature: CreatureKind) -> Message | None:
    """A ``pose`` event's fields: the creature's joints and note objects now, to :data:`DIGITS`."""
    figure = creature.shown()
    if figure is None:
        return None
    marks = [[round(x, DIGITS) for x in mark] for mark in marks_of(creature)]
    return {"creature": creature.name, "joints": np.round(np.asarray(figure[0], float), DIGITS).tolist(),
            "marks": marks}


@dataclass
class Replay:
    """An offline run's log as view messages: the hello, then ``(t, frame)`` in time order."""

    hello: Message
    frames: list[Message] = field(default_factory=list)


STILL_EVERY = 0.1
"""Seconds of clock time per frame when a run has no bodies to pace its replay."""


def replay(events: Iterable[Message]) -> Replay:
    """The view messages an offline run's events log holds: one frame per distinct ``pose``
    time, carrying the poses of that time (a creature without a pose there keeps its last) and
    the shown events since the previous frame; a run whose creatures have no bodies (or was
    run with ``[view] log_fps = 0``) has a frame every :data:`STILL_EVERY` seconds, carrying
    its events. Raises ValueError for a log with nothing to show, or a pose that does not fit
    its skeleton (naming creature and time).

    One pass over ``events``, which may be :func:`~creatures.events.iter_events`: a pose is
    kept as an array, not as the event that carried it (poses are 85 % of a log's bytes, and a
    10-minute run's events held as dicts took 218 MB)."""
    run: Message = {}
    skeletons: dict[str, Message] = {}
    frames: list[Message] = []
    joints: dict[str, np.ndarray] = {}
    marks: dict[str, np.ndarray] = {}  # (N, 4): x, y, z, pitch
    shown: list[Message] = []
    still: list[Message] | None = []  # the shown events, until a pose says the run has bodies
    current: float | None = None

    def close_frame(t: float) -> None:
        frames.append({"type": "frame", "t": t, "bodies": dict(joints), "marks": dict(marks), "events": shown[:]})
        shown.clear()

    for event in events:
        kind, t = event["kind"], event["t"]
        if kind == "run":
            run = run or event
        elif kind == "skeleton":
            skeletons[event["creature"]] = event
        elif kind == "pose":
            still = None
            if current is not None and t != current:
                close_frame(current)
            current = t
            joints[event["creature"]] = np.asarray(event["joints"], float)
            marks[event["creature"]] = np.asarray(event.get("marks", []), float).reshape(-1, 4)
        elif kind in SHOWN:
            shown.append(event)
            if still is not None:
                still.append(event)
    if still is not None:  # no poses: frames paced by the clock
        frames = _still_frames(still)
    elif current is not None:
        close_frame(current)
    if not frames:
        raise ValueError("the events log holds nothing to show: no body poses and no notes, selections or drives")
    for frame in frames:
        for who, posed in frame["bodies"].items():
            if who not in skeletons or len(skeletons[who]["parents"]) != len(posed):
                raise ValueError(f"the pose of {who!r} at {frame['t']} s does not fit its skeleton (a damaged log)")
    names = [n for n in run.get("creatures", []) if isinstance(n, str)] or list(skeletons)
    found = [Body(n, skeletons[n].get("kind_of", ""), list(skeletons[n]["parents"]), tuple(skeletons[n]["place"]))
             if n in skeletons else Body(n, "", None, place(i, len(names))) for i, n in enumerate(names)]
    return Replay(hello(run.get("title", ""), "replay", found, creatures=len(names)), frames)


def _still_frames(shown: list[Message]) -> list[Message]:
    """Frames every :data:`STILL_EVERY` seconds of clock time, each carrying the shown events
    of its interval: the replay of a run without bodies."""
    frames: list[Message] = []
    for event in shown:
        t = round(STILL_EVERY * math.floor(event["t"] / STILL_EVERY + 1e-9), DIGITS)
        if not frames or t > frames[-1]["t"]:
            frames.append({"type": "frame", "t": t, "bodies": {}, "marks": {}, "events": []})
        frames[-1]["events"].append(event)
    return frames


def scene(message: Message, hello_message: Message) -> tuple[np.ndarray, np.ndarray, list[tuple[tuple, float]]]:
    """A frame's bodies placed side by side, as one skeleton: joint positions ``(J, 3)``,
    parents ``(J,)`` and note marks ``((x, y, z), pitch)`` — what the offscreen renderer and the
    page both draw."""
    positions, parents, marks = [], [], []
    offset = 0
    for body in hello_message["creatures"]:
        shift = np.asarray(body["place"], float)
        joints = message["bodies"].get(body["name"])
        if joints is not None and body["parents"] is not None:
            positions.append(np.asarray(joints, float) + shift)
            parents.append(np.where(np.asarray(body["parents"]) >= 0, np.asarray(body["parents"]) + offset, -1))
            offset += len(joints)
        marks += [(tuple(float(v) for v in np.asarray(m[:3]) + shift), float(m[3]))
                  for m in message["marks"].get(body["name"], [])]
    if not positions:
        return np.zeros((0, 3)), np.zeros(0, int), marks
    return np.concatenate(positions), np.concatenate(parents), marks


def trees(t: float | None, known: list["Knowledge"]) -> Message:
    """A ``trees`` message: each creature's percept trees (name, size, children) as the
    inspector finds them in its learned state (:func:`creatures.runtime.inspect.knowledge`);
    ``t`` None for a finished run's saved state."""
    return {"type": "trees", "t": t, "trees": {k.creature: [asdict(tree) for tree in k.trees] for k in known}}


def encode(message: Message) -> str:
    """A message as JSON text (numpy arrays as nested lists, NaN as null), as the events log
    writes its line: a record orjson refuses (a numpy integer key, an integer beyond 64 bits,
    which a log with a file hands its taps as emitted) goes through the standard library (it
    raised here, and the live view's feeding task died: no frame after it, for any browser)."""
    return json_line(message)[:-1].decode()
