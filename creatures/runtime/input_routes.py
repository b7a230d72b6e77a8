"""The ``[[input]]`` tables, checked and compiled: OSC 1.0 address patterns, MIDI message
filters, and the targets' keys checked against the creatures before anything runs.

A table that cannot work raises :class:`MapError` naming its key, which the config loader
turns into an error with file and line (:func:`creatures.runtime.schema.load_installation`);
what passes is a :class:`Route` the input map (:mod:`creatures.runtime.input_map`) matches
messages against.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass

import mido

from creatures.config import nearest
from creatures.runtime.schema import Arg, InputMap, named_pitch

SOURCES = ("osc", "midi", "serial", "file")
TARGETS = ("note", "sensor", "reward", "drive")
TARGET_KEYS = {
    "note": ("pitch", "velocity", "duration"),
    "sensor": ("name", "value", "range", "input_range"),
    "reward": ("creatures", "amount", "window", "rate"),
    "drive": ("drive", "amount", "set", "creatures"),
}

# midi = ... : the mido message type and the message's arguments by index.
MIDI = {
    "note": ("note_on", ("note", "velocity", "channel")),
    "note_off": ("note_off", ("note", "velocity", "channel")),
    "cc": ("control_change", ("value", "control", "channel")),
    "program": ("program_change", ("program", "channel")),
    "pitchbend": ("pitchwheel", ("pitch", "channel")),
    "aftertouch": ("aftertouch", ("value", "channel")),
    "polytouch": ("polytouch", ("value", "note", "channel")),
}
MIDI_KIND = {mido_type: kind for kind, (mido_type, _) in MIDI.items()}
MIDI_SPAN = {"pitchbend": (-8192.0, 8191.0)}
"""The span of a MIDI message's first argument where it is not 0..127 (for ``range``)."""


class MapError(ValueError):
    """A ``[[input]]`` table that cannot work: ``key`` names the key at fault, ``index`` the
    table (its position among the ``[[input]]`` tables)."""

    def __init__(self, key: str, message: str) -> None:
        super().__init__(message)
        self.key = key
        self.index = 0


# -- OSC 1.0 address patterns ------------------------------------------------------------------
def address_pattern(pattern: str) -> re.Pattern[str]:
    """The regex of an OSC 1.0 address pattern: ``?`` one character, ``*`` any run of
    characters, ``[abc]``/``[a-z]``/``[!a-z]`` one character of (or not of) a set, ``{foo,bar}``
    one of the strings. No wildcard crosses a ``/`` (OSC matches part by part)."""
    if not pattern.startswith("/"):
        raise ValueError(f"an OSC address pattern starts with '/' (got {pattern!r})")
    out, i = [], 0
    while i < len(pattern):
        c = pattern[i]
        if c == "*":
            out.append("[^/]*")
        elif c == "?":
            out.append("[^/]")
        elif c == "[":
            end = pattern.find("]", i + 1)
            if end < 0:
                raise ValueError(f"unclosed '[' at {i} in {pattern!r}")
            body = pattern[i + 1:end]
            negate = body.startswith("!")
            body = body[1:] if negate else body
            if not body or "/" in body:
                raise ValueError(f"empty or '/' character set at {i} in {pattern!r}")
            chars = "".join("-" if ch == "-" and 0 < k < len(body) - 1 else re.escape(ch) for k, ch in enumerate(body))
            try:
                re.compile(f"[{chars}]")
            except re.error as exc:
                raise ValueError(f"bad character set [{body}] in {pattern!r} ({exc})") from None
            out.append(f"[{'^/' if negate else ''}{chars}]")
            i = end
        elif c == "{":
            end = pattern.find("}", i + 1)
            if end < 0:
                raise ValueError(f"unclosed '{{' at {i} in {pattern!r}")
            choices = pattern[i + 1:end].split(",")
            if any("/" in choice or any(ch in choice for ch in "*?[]{") for choice in choices):
                raise ValueError(f"a {{...}} alternative holds only plain strings (in {pattern!r})")
            out.append("(?:" + "|".join(re.escape(choice) for choice in choices) + ")")
            i = end
        elif c in "]}" or c in " #,":
            raise ValueError(f"character {c!r} at {i} is not allowed in an OSC address pattern {pattern!r}")
        else:
            out.append(re.escape(c))
        i += 1
    return re.compile("".join(out))


def arg_indices(spec: InputMap) -> list[tuple[str, int]]:
    """Every ``(key, argument index)`` a map reads, with the defaults it implies."""
    keys = TARGET_KEYS.get(spec.to or "", ())
    used = [(key, v.arg) for key in keys if isinstance(v := getattr(spec, key, None), Arg)]
    if spec.to in ("note", "sensor") and getattr(spec, "pitch" if spec.to == "note" else "value") is None:
        used.append(("pitch" if spec.to == "note" else "value", 0))
    return used


# -- one compiled [[input]] table -------------------------------------------------------------
@dataclass
class Colony:
    """What the config knows of a creature before it exists: its drives, and whether it has
    an action-group a reward can reach (``CreatureKind.drive_names`` / ``rewardable``)."""

    drives: tuple[str, ...]
    rewardable: bool


CLICKS_PER_SECOND = 10.0
"""Rewards a second a ``to = "reward"`` map takes unless its ``limit`` says otherwise: more than
a visitor's clicker gives. A reward adds to the credited values (``V += rate·trigger·amount``),
so a flood is a retraining: 10,000 ``/reward`` messages in 10 s (a bouncing switch, a stuck
sender) took an audited colony's values from about 2 to 370, saved, and it then played nothing."""


class Route:
    """One ``[[input]]`` table, checked against the colony and compiled for matching."""

    def __init__(self, spec: InputMap, colony: dict[str, Colony]) -> None:
        self.spec = spec
        self.limit = spec.limit if spec.limit is not None else CLICKS_PER_SECOND if spec.to == "reward" else None
        self.pattern: re.Pattern[str] | None = None
        self.midi: str | None = None
        if spec.osc is not None:
            try:
                self.pattern = address_pattern(spec.osc)
            except ValueError as exc:
                raise MapError("osc", f"bad OSC address pattern: {exc}") from None
        if spec.midi is not None:
            if spec.midi not in MIDI:
                raise MapError("midi", f"unknown MIDI message {spec.midi!r}{nearest(spec.midi, sorted(MIDI), 'MIDI messages')}")
            self.midi = spec.midi
        self._check_filters()
        if spec.to is None:
            raise MapError("to", f"a map needs to = {' / '.join(repr(t) for t in TARGETS)}")
        if spec.to not in TARGETS:
            raise MapError("to", f"unknown target {spec.to!r}{nearest(spec.to, sorted(TARGETS), 'targets')}")
        for key in sorted({k for keys in TARGET_KEYS.values() for k in keys} - set(TARGET_KEYS[spec.to])):
            if key in spec.model_fields_set:
                raise MapError(key, f"not a key of to = {spec.to!r} (its keys: {', '.join(TARGET_KEYS[spec.to])})")
        arity = len(MIDI[self.midi][1]) if self.midi else spec.args
        for key, index in arg_indices(spec):
            if arity is not None and index >= arity:
                what = f"midi = {self.midi!r}" if self.midi else f"args = {arity}"
                raise MapError(key, f"argument {index} is beyond the {arity} argument(s) of {what}")
            self._check_default(key)
        if spec.to == "sensor":
            self._check_sensor()
        self.creatures = self._creatures(colony)

    def _check_default(self, key: str) -> None:
        """A ``default`` the key can take: text only for a pitch (a note name, ``"C4"``) or the
        creatures a reward reaches. ``value = { arg = 1, default = "low" }`` loaded, and every
        message short of that argument was then dropped as malformed."""
        default = getattr(getattr(self.spec, key, None), "default", None)
        if not isinstance(default, str) or key == "creatures":
            return
        if key == "pitch":
            if named_pitch(default) is None:
                raise MapError(key, f"default {default!r} is no pitch: a MIDI number or a note name such as 'C4'")
            return
        raise MapError(key, f"default {default!r} is text: {key} is a number")

    def _check_filters(self) -> None:
        spec = self.spec
        for key, kinds in (("channel", MIDI), ("control", ("cc",)), ("note", ("note", "note_off", "polytouch"))):
            if getattr(spec, key) is not None and self.midi not in kinds:
                raise MapError(key, f"only for midi = {' / '.join(repr(k) for k in kinds)}")
        if spec.args is not None and self.pattern is None:
            raise MapError("args", "the arity of an OSC message: only with osc = ...")

    def _check_sensor(self) -> None:
        """A sensor map's name and scaling. Each slip here once loaded and failed quietly: a
        nameless sensor was fed as ``world.sensors[None]``, which nothing reads; an
        ``input_range`` without ``range`` was ignored (a 0..1023 reading went in unscaled); an
        empty one made every reading malformed, the run's first message the first sign."""
        spec = self.spec
        if spec.name is None:
            raise MapError("name", "to = 'sensor' needs name = NAME (what percepts and [[room.visitors]] read it by)")
        if spec.input_range is None:
            return
        if spec.range is None:
            raise MapError("input_range", "input_range is what range = [lo, hi] scales from: without range the "
                                          "reading goes in as it is; add range, or remove input_range")
        if spec.input_range[0] == spec.input_range[1]:
            raise MapError("input_range", f"input_range {list(spec.input_range)} is empty: no reading can be "
                                          "scaled from it (give the reading's lowest and highest values)")

    def _creatures(self, colony: dict[str, Colony]) -> list[str] | None:
        """The creatures a reward or drive reaches (None: named by an argument)."""
        spec = self.spec
        if spec.to not in ("reward", "drive"):
            return []
        if spec.to == "drive":
            if spec.drive is None:
                raise MapError("drive", "to = 'drive' needs drive = NAME")
            if (spec.amount is None) == (spec.set is None):
                raise MapError("amount", "to = 'drive' takes amount (added) or set (the new level), one of them")
        can = [name for name, c in colony.items() if (c.rewardable if spec.to == "reward" else spec.drive in c.drives)]
        if isinstance(spec.creatures, Arg):
            return None
        for name in spec.creatures or ():
            if name not in colony:
                raise MapError("creatures", f"no creature named {name!r}{nearest(name, sorted(colony), 'creatures')}")
            if name not in can:
                why = ("has no action-group to reward" if spec.to == "reward" else
                       f"has no drive {spec.drive!r} (its drives: {', '.join(colony[name].drives) or 'none'})")
                raise MapError("creatures", f"creature {name!r} {why}")
        if spec.creatures is None and not can:
            drives = sorted({d for c in colony.values() for d in c.drives})
            raise MapError("creatures" if spec.to == "reward" else "drive",
                           "no creature has an action-group to reward" if spec.to == "reward"
                           else f"no creature has a drive {spec.drive!r}{nearest(spec.drive, sorted(drives), 'drives')}")
        return list(spec.creatures) if spec.creatures is not None else can

    def matches_osc(self, address: str, args: tuple) -> bool:
        return (self.pattern is not None and self.pattern.fullmatch(address) is not None
                and (self.spec.args is None or len(args) == self.spec.args))

    def matches_midi(self, kind: str, msg: mido.Message) -> bool:
        spec = self.spec
        return (kind == self.midi and (spec.channel is None or msg.channel == spec.channel)
                and (spec.control is None or msg.control == spec.control)
                and (spec.note is None or msg.note == spec.note))


def check_device(device: str, devices: dict[str, int], index: int) -> None:
    """A ``serial = ...`` that can work: a device's path, read by one table (``devices``: the
    paths read so far, by table). A URL pyserial would take (``rfc2217://``, ``socket://``)
    waited seconds on the network at every retry, on the creatures' thread; a device read by
    two tables gave each half its lines, and a ``""`` was looked for all night."""
    if not device.strip():
        raise MapError("serial", "serial = '' names no device (e.g. '/dev/ttyUSB0', '/dev/serial/by-id/...')")
    if "://" in device:
        raise MapError("serial", f"serial = {device!r} is a URL: a serial table reads a device's path "
                                 "(e.g. '/dev/ttyUSB0'); a sender on the network sends OSC to [osc] port")
    real = os.path.realpath(device)
    if real in devices:
        raise MapError("serial", f"{device!r} is read by [[input]] table {devices[real]} (from 0) already: two "
                                 "readers of one device each hear part of its lines; read it once and map "
                                 "its lines with osc = ... tables")
    devices[real] = index


def compile_maps(maps: list[InputMap], colony: dict[str, Colony]) -> list[Route]:
    """Every mapping table (``to`` set; source tables excluded) as a :class:`Route`;
    :class:`MapError` (with ``index``, the table's position) for the first that cannot work."""
    routes = []
    devices: dict[str, int] = {}  # serial devices by their real path: the table reading each
    for i, spec in enumerate(maps):
        try:
            given = [key for key in SOURCES if getattr(spec, key) is not None]
            if len(given) != 1:
                raise MapError(given[1] if given else "osc", f"an [[input]] table hears one of {', '.join(SOURCES)} "
                                                             f"(this one: {', '.join(given) or 'none'})")
            own = {"serial": ("serial", "baud"), "file": ("file",)}.get(given[0])
            if own is not None:
                others = [k for k in InputMap.model_fields if k in spec.model_fields_set and k not in own]
                if others:
                    raise MapError(others[0], f"a {given[0]} table is a source of OSC messages (its keys: "
                                              f"{', '.join(own)}); map them with osc = ... tables")
                if spec.serial is not None:
                    check_device(spec.serial, devices, i)
                continue
            if "baud" in spec.model_fields_set:
                raise MapError("baud", "the speed of a serial device: only with serial = ...")
            routes.append(Route(spec, colony))
        except MapError as exc:
            exc.index = i
            raise
    return routes
