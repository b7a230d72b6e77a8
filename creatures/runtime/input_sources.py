"""Message sources of the input map besides the network and MIDI ports: serial devices and
rehearsal files (``[[input]]`` tables with ``serial = ...`` or ``file = ...``).

Both speak the input map's one language, OSC messages: a serial line ``light 0.5`` (or
``light,0.5``) is heard as ``/light 0.5``; a rehearsal row ``12.5,/reward,1.0`` is
``/reward 1.0`` heard 12.5 s after the run starts (a row whose address is ``midi`` carries
MIDI bytes). A rehearsal file lets an installation be rehearsed offline, on the simulated
clock, with what the sensors and the visitors will send in the gallery: the same rows fed
live give the same events (tests/test_input_map.py).

A serial device that is absent or unplugged is reported once and looked for again every
:data:`RETRY` seconds; reads never block (pyserial with ``timeout=0``), so the creature's
thread is never held by a sensor.
"""

from __future__ import annotations

import csv
import io
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable

import mido

from creatures.clock import Clock
from creatures.runtime.input_map import InputRouter
from midi.notes import NoteEvent

if TYPE_CHECKING:
    from creatures.runtime.schema import LoadedInstallation

RETRY = 2.0
"""Seconds between attempts to open a serial device that is absent."""

MAX_LINE = 256
"""Longest serial line read (bytes); a longer run without a newline is dropped as malformed, up
to and with its newline (its tail is no line of its own)."""

MAX_ROWS = 1_000_000
"""Most rows of a rehearsal file (a night of a 30 Hz sensor)."""


class RehearsalError(ValueError):
    """A rehearsal file that cannot be read; ``line`` is where (1-based) when known."""

    def __init__(self, path: Path, message: str, line: int | None = None) -> None:
        super().__init__(f"{path}{f':{line}' if line else ''}: {message}")
        self.line = line


def value_of(text: str) -> int | float | bool | str:
    """A token of a serial line or CSV row as the OSC argument it stands for."""
    lowered = text.strip().lower()
    if lowered in ("true", "false"):
        return lowered == "true"
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text.strip()


def line_message(line: str) -> tuple[str, list[Any]] | None:
    """``name v1 v2 ...`` (spaces, tabs or commas) as ``("/name", [v1, v2, ...])``; None if empty."""
    tokens = [t for t in line.replace(",", " ").split() if t]
    if not tokens:
        return None
    name = tokens[0]
    return (name if name.startswith("/") else f"/{name}"), [value_of(t) for t in tokens[1:]]


@dataclass(frozen=True, slots=True)
class Row:
    time: float
    address: str
    args: tuple
    line: int = 0  # of its rehearsal file (0: not read from one)


def load_rehearsal(path: Path) -> list[Row]:
    """The rows of a CSV (``time,address,args...``; a first row ``time,...`` is a header) or
    JSON-lines (``{"time": s, "address": "/x", "args": [...]}``) file, in time order."""
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise RehearsalError(path, f"cannot read rehearsal file ({exc})") from None
    try:
        text = data.decode("utf-8-sig")  # the byte-order mark a spreadsheet's "CSV UTF-8" begins with
    except UnicodeDecodeError as exc:  # said at its line: a file of a million rows is not searched by eye
        raise RehearsalError(path, f"not UTF-8 text (byte {exc.start}: {data[exc.start:exc.start + 1]!r}); save "
                                   "it as UTF-8 (a spreadsheet's \"CSV UTF-8\")",
                             data[:exc.start].count(b"\n") + 1) from None
    rows: list[Row] = []
    jsonl = path.suffix.lower() in (".jsonl", ".ndjson", ".json")
    lines = text.splitlines() if jsonl else list(csv.reader(io.StringIO(text)))
    for number, line in enumerate(lines, 1):
        if len(rows) >= MAX_ROWS:
            raise RehearsalError(path, f"more than {MAX_ROWS} rows", number)
        if not "".join(line).strip() or (not jsonl and line[0].strip().startswith("#")):
            continue
        try:
            if jsonl:
                record = json.loads(line)
                time, address, args = record["time"], record["address"], record.get("args", [])
            else:
                if number == 1 and line[0].strip().lower() == "time":
                    continue
                time, address, args = line[0], line[1].strip(), [value_of(x) for x in line[2:]]
            time = float(time)
            if not isinstance(address, str) or not isinstance(args, list):
                raise TypeError("address must be a string and args a list")
        except (ValueError, KeyError, IndexError, TypeError) as exc:
            if not jsonl and len(line) == 1 and ";" in line[0]:  # a spreadsheet saving in a European locale
                raise RehearsalError(path, "fields are separated by ';': a rehearsal CSV separates them by ','",
                                     number) from None
            raise RehearsalError(path, f"row is not time,address,args... ({type(exc).__name__}: {exc})",
                                 number) from None
        if not (math.isfinite(time) and time >= 0) or not (address.startswith("/") or address == "midi"):
            raise RehearsalError(path, "time must be seconds >= 0 and address an OSC address or 'midi'", number)
        rows.append(Row(time, address, tuple(args), number))
    return sorted(rows, key=lambda r: r.time)


def unplayed(file: str, rows: list[Row], duration: float) -> str | None:
    """What an offline run of ``duration`` s leaves of a rehearsal file, said (None: every row
    plays). A ten-minute rehearsal in the config's default 60 s run played its first minute,
    and the rest went unsaid, as if the colony had heard it and done nothing."""
    late = [row for row in rows if row.time > duration]
    if not late:
        return None
    return (f"{file}: {len(late)} of its {len(rows)} rows fall past the run's {duration:g} s (the last at "
            f"{late[-1].time:,.1f} s) and are not played; give --duration to play them")


def note_on(note: NoteEvent) -> mido.Message:
    """A recorded note as the note-on a live port would have sent."""
    return mido.Message("note_on", channel=note.channel, note=note.pitch, velocity=max(note.velocity, 1))


class Rehearsal:
    """A rehearsal file played from ``start`` seconds on the run's clock (None: from the
    first poll, the start of a live run); ``file`` names it (rows of no file: empty)."""

    def __init__(self, rows: list[Row], start: float | None, router: InputRouter, file: str = "") -> None:
        self.rows = rows
        self.start = start
        self.router = router
        self.file = file
        self.next = 0

    def unreached(self, t: float) -> str | None:
        """The rows a live run that stopped at ``t`` never reached, said (None: it played them
        all). Its end is known only when it stops (Ctrl-C, SIGTERM, the schedule, a wedged
        device or ``--duration``), so it is said then, in the summary: rows past the end were
        never played and went unsaid, as if the colony had heard them and done nothing."""
        left = len(self.rows) - self.next
        if not left:
            return None
        ran = t - self.start if self.start is not None else 0.0
        return (f"{self.file}: {left} of its {len(self.rows)} rows were not played: the run stopped {ran:,.1f} s "
                f"into them, before the row at {self.rows[self.next].time:,.1f} s (the last at "
                f"{self.rows[-1].time:,.1f} s)")

    def poll(self, t: float) -> int:
        if self.start is None:
            self.start = t
        notes = 0
        while self.next < len(self.rows) and self.start + self.rows[self.next].time <= t:
            row = self.rows[self.next]
            self.next += 1
            at = f"{self.file}:{row.line}" if row.line else ""
            if row.address == "midi":
                notes += self.router.midi_bytes(row.args, t, "file", at)
            else:
                notes += self.router.osc(row.address, row.args, t, "file", at)
        return notes


class SerialSource:
    """Lines from a serial device, read without blocking; absent devices are retried."""

    def __init__(self, device: str, baud: int, clock: Clock, router: InputRouter, say: Callable[[str], None], *,
                 opener: Callable[..., Any] | None = None) -> None:
        self.device = device
        self.baud = baud
        self.clock = clock
        self.router = router
        self.say = say
        self.opener = opener
        self.port: Any = None
        self.buffer = b""
        self.skipping = False  # inside an over-long line, dropped up to its newline
        self.next_try = -math.inf
        self.reported = False

    def _open(self) -> None:
        import serial

        opener = self.opener or serial.Serial  # a device's path: no URL handler (input_routes.check_device)
        try:
            self.port = opener(self.device, baudrate=self.baud, timeout=0)
        except (serial.SerialException, OSError, ValueError) as exc:
            self.next_try = self.clock.now() + RETRY
            if not self.reported:
                self.reported = True
                self.say(f"serial input {self.device} unavailable ({exc}); looking for it every {RETRY:.0f} s")
            return
        if self.reported:
            self.say(f"serial input {self.device} connected")
        self.reported = False

    def poll(self, t: float) -> int:
        if self.port is None:
            if self.clock.now() < self.next_try:
                return 0
            self._open()
            if self.port is None:
                return 0
        try:
            chunk = self.port.read(4096)
        except Exception as exc:  # pyserial raises SerialException, OSError, TypeError on unplug
            self.close()
            self.next_try = self.clock.now() + RETRY
            self.reported = True
            self.say(f"serial input {self.device} lost ({exc}); looking for it every {RETRY:.0f} s")
            return 0
        *lines, rest = (self.buffer + chunk).split(b"\n")
        if self.skipping:
            # The tail of an over-long line was heard as a line of its own ("calibrating ....
            # lux 0.9" gave the sensor 0.9), and each 4 KiB of one counted once more.
            if not lines:
                return 0
            lines, self.skipping = lines[1:], False
        self.buffer = rest
        if len(self.buffer) > MAX_LINE:
            self.router.miss("malformed", "serial", self.device, t, f"a line longer than {MAX_LINE} bytes")
            self.buffer, self.skipping = b"", True
        notes = 0
        for raw in lines:
            try:
                message = line_message(raw.decode("utf-8").strip()) if len(raw) <= MAX_LINE else None
            except UnicodeDecodeError:
                message = None
            if message is None:
                if raw.strip():
                    self.router.miss("malformed", "serial", self.device, t, "not a line `name value ...`")
                continue
            notes += self.router.osc(*message, t, "serial")
        return notes

    def close(self) -> None:
        # a line cut off by an unplug is no reading: joined to the first after the device came
        # back, it made a reading of what the device sent before it went
        self.buffer, self.skipping = b"", False
        if self.port is not None:
            try:
                self.port.close()
            except Exception:  # closing an unplugged device may fail; it is gone either way
                pass
            self.port = None


def open_sources(inst: "LoadedInstallation", router: InputRouter, clock: Clock, say: Callable[[str], None], *,
                 live: bool) -> list[Rehearsal | SerialSource]:
    """The config's rehearsal files (offline from time 0, live from the run's start) and, in
    live runs, its serial devices."""
    sources: list[Rehearsal | SerialSource] = []
    for i, spec in enumerate(inst.settings.input.map):
        if spec.file is not None:
            sources.append(Rehearsal(inst.rehearsals[i], None if live else 0.0, router, spec.file))
        elif spec.serial is not None and live:
            sources.append(SerialSource(spec.serial, spec.baud, clock, router, say))
        elif spec.serial is not None:
            say(f"serial input {spec.serial} is read in live runs only (rehearse it offline with a file)")
    return sources
