"""The shared room's wire: what one process tells the others about its creatures, as OSC over
UDP (IViHumans: minds and renderers that talk over a protocol; REACT's crowd in one room).

Two messages, each one datagram, spoken by every process of a room to every other:

``/room/bodies room:s owner:s seq:i at:d beat:d names:s rows:b``
    Where the ``owner`` process's creatures stand at Unix time ``at`` (and Ableton Link beat
    ``beat``, or −1 without Link): ``names`` comma-separated, ``rows`` little-endian float32,
    :data:`COLUMNS` per creature (x, y, vx, vy, hx, hy, radius). At most :data:`MOST_BODIES`
    creatures a datagram: a larger crowd is several, each taken on its own.
``/room/note room:s owner:s creature:s pitch:i velocity:i duration:d at:d beat:d``
    A note ``creature`` plays, time-tagged with when it starts (``at``, and ``beat`` on Link's
    timeline), so a hearer far away hears it from where the creature stands, as late as the
    distance makes it, not as late as the network did.
``/room/bye room:s owner:s``
    The process is leaving; its creatures leave the room now instead of after the timeout.

Any OSC client can speak it (the test speaks it with python-osc's client). A float argument
may be float32 (``f``, most tools' number) or float64 (``d``, what this project sends); an
``at`` of 0 or less means "now" (the hearer stamps it with its own clock, as the creature
protocol does: a float32 cannot hold a Unix time), a ``beat`` below 0 means "no Link".
Everything is checked before python-osc parses the datagram (:func:`check`: the type tags,
sizes) and bounded after (:func:`decode`); what does not fit is refused with a cause the share
counts.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np
from pythonosc.osc_message import OscMessage
from pythonosc.osc_message_builder import OscMessageBuilder

from midi.notes import NoteEvent
from midi.osc import MAX_DURATION, NAME

COLUMNS = 7
"""Floats per creature in ``rows``: x, y, vx, vy, hx, hy, radius."""

MOST_BODIES = 128
"""Creatures per ``bodies`` datagram (≈ 12 KB with 64-character names: one datagram, never
fragmented past what loopback and a LAN carry whole)."""

MAX_PACKET = 16384
"""Bytes: the largest datagram of this protocol."""

MAX_SPEED = 100.0
"""m/s: a faster velocity is refused (a vehicle's ``max_speed`` is at most this)."""

_TAGS = {b"/room/bodies": re.compile(rb",ssi[fd][fd]sb"), b"/room/note": re.compile(rb",sssii[fd][fd][fd]"),
         b"/room/bye": re.compile(rb",ss")}
_OWNER = re.compile(r"[A-Za-z0-9_.:\-]{1,96}")


class Refused(ValueError):
    """A datagram that is not this protocol; ``cause`` is the counter it goes to."""

    def __init__(self, cause: str, message: str) -> None:
        super().__init__(message)
        self.cause = cause


@dataclass(frozen=True)
class Bodies:
    """One ``bodies`` datagram, decoded and bounded."""

    room: str
    owner: str
    seq: int
    at: float
    beat: float
    names: tuple[str, ...]
    rows: np.ndarray  # (n, COLUMNS) float64


@dataclass(frozen=True)
class Note:
    """One ``note`` datagram: ``note.time`` is 0; ``at``/``beat`` say when it starts."""

    room: str
    owner: str
    creature: str
    note: NoteEvent
    at: float
    beat: float


@dataclass(frozen=True)
class Bye:
    room: str
    owner: str


def _build(address: str, args: list) -> bytes:
    builder = OscMessageBuilder(address)
    for kind, value in args:
        builder.add_arg(value, kind)
    return builder.build().dgram


def bodies(room: str, owner: str, seq: int, at: float, beat: float, names: list[str], rows: np.ndarray) -> list[bytes]:
    """The datagrams telling where ``names`` stand (``rows`` (n, COLUMNS)), :data:`MOST_BODIES` each."""
    out = []
    data = np.ascontiguousarray(rows, dtype="<f4")
    for start in range(0, max(len(names), 1), MOST_BODIES):
        part = names[start:start + MOST_BODIES]
        out.append(_build("/room/bodies", [("s", room), ("s", owner), ("i", seq & 0x7FFFFFFF), ("d", at),
                                           ("d", beat), ("s", ",".join(part)),
                                           ("b", data[start:start + MOST_BODIES].tobytes())]))
    return out


def note(room: str, owner: str, creature: str, played: NoteEvent, at: float, beat: float) -> bytes:
    return _build("/room/note", [("s", room), ("s", owner), ("s", creature), ("i", played.pitch),
                                 ("i", played.velocity), ("d", played.duration), ("d", at), ("d", beat)])


def bye(room: str, owner: str) -> bytes:
    return _build("/room/bye", [("s", room), ("s", owner)])


def check(data: bytes) -> bytes:
    """The address of a datagram of this protocol, refused before python-osc sees it when its
    size or type tags are not exactly one of the three messages'."""
    if len(data) > MAX_PACKET:
        raise Refused("oversize", f"datagram of {len(data)} bytes (at most {MAX_PACKET})")
    end = data.find(b"\x00")
    address = data[:end] if end > 0 else b""
    tags_at = (end + 4) & ~3
    expected = _TAGS.get(address)
    if expected is None:
        raise Refused("address" if data[:1] == b"/" else "not osc", "not a /room/ message")
    stop = data.find(b"\x00", tags_at)
    if stop < 0 or expected.fullmatch(data[tags_at:stop]) is None:
        raise Refused("type tags", f"{address.decode()} expects type tags {expected.pattern.decode()}")
    return address


def decode(data: bytes) -> Bodies | Note | Bye:
    """One datagram, checked and bounded (:class:`Refused` with its cause otherwise)."""
    address = check(data)
    try:
        args = OscMessage(data).params
    except Exception:  # python-osc raises ParseError, and struct/index errors on a truncated one
        raise Refused("not osc", "a datagram python-osc cannot read") from None
    room, owner = args[0], args[1]
    if NAME.fullmatch(room) is None or _OWNER.fullmatch(owner) is None:
        raise Refused("arguments", "room or owner name out of bounds")
    if address == b"/room/bye":
        return Bye(room, owner)
    if address == b"/room/note":
        creature, pitch, velocity, duration, at, beat = args[2:]
        if NAME.fullmatch(creature) is None or not (math.isfinite(at) and math.isfinite(beat)):
            raise Refused("arguments", "note: creature name or time out of bounds")
        if not 0 <= duration < math.inf:
            raise Refused("arguments", f"note: duration {duration!r}")
        try:
            played = NoteEvent(0.0, pitch, min(velocity, 127), 0, min(duration, MAX_DURATION))
        except ValueError as exc:
            raise Refused("arguments", f"note: {exc}") from None
        return Note(room, owner, creature, played, at, beat)
    seq, at, beat, names, blob = args[2:]
    names_ = tuple(names.split(",")) if names else ()
    if len(blob) != 4 * COLUMNS * len(names_) or len(names_) > MOST_BODIES:
        raise Refused("arguments", f"bodies: {len(names_)} names but {len(blob)} bytes of rows")
    if not all(NAME.fullmatch(n) for n in names_) or len(set(names_)) != len(names_):
        raise Refused("arguments", "bodies: a creature name out of bounds or twice")
    rows = np.frombuffer(blob, dtype="<f4").reshape(-1, COLUMNS).astype(np.float64)
    if not (math.isfinite(at) and math.isfinite(beat) and np.isfinite(rows).all()):
        raise Refused("arguments", "bodies: a number that is not finite")
    if (np.abs(rows[:, 2:4]) > MAX_SPEED).any() or (rows[:, 6] <= 0).any() or (rows[:, 6] > 100).any():
        raise Refused("arguments", "bodies: a speed or radius out of bounds")
    return Bodies(room, owner, seq, at, beat, names_, rows)
