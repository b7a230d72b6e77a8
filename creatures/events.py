"""The events log (DESIGN.md, "Seeing inside").

Every run can write one JSON object per line for each perception, selection, reward and motor
event, stamped with clock time. Plots, reports and the inspector read only this log and saved
state, so what they show is what happened. Files rotate at a size bound so a gallery run of
weeks cannot fill the disk.
"""

from __future__ import annotations

import bisect
import contextlib
import errno
import io
import json
import logging
import math
import os
import stat
import threading
from collections import Counter
from typing import IO, Any, Callable, Collection, Iterator

import orjson

from creatures.paths import UnsafePathError, kind_of, open_regular, regular_file

_log = logging.getLogger(__name__)


def _plain(value: Any) -> Any:
    """JSON-safe copy: numpy scalars/arrays become Python numbers/lists, NaN becomes None."""
    if hasattr(value, "tolist"):
        value = value.tolist()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


_ORJSON = orjson.OPT_SERIALIZE_NUMPY | orjson.OPT_NON_STR_KEYS


def json_line(record: dict[str, Any]) -> bytes:
    """One JSON line for ``record``, UTF-8. orjson writes numpy values and NaN (as ``null``)
    itself, about 9× faster than the standard library; a record it refuses (a key JSON cannot
    take, e.g. a numpy integer, or an integer beyond 64 bits) goes through :func:`_plain` and
    the standard library instead. A gallery day writes millions of events, so this is on
    every tick's path."""
    try:
        return orjson.dumps(record, option=_ORJSON) + b"\n"
    except TypeError:  # orjson.JSONEncodeError
        return json.dumps(_plain(record), separators=(",", ":"), ensure_ascii=False).encode() + b"\n"


BUFFER_BYTES = 64 * 1024
"""Events are gathered up to this many bytes and written at once (and at every flush)."""

BACKLOG_BYTES = 64 * BUFFER_BYTES
"""Pending bytes past which even a log flushed by another thread writes from the emitting one
(that thread has stalled: the log must not grow without bound)."""

IN_MEMORY = 1 << 20
"""Events a log without a file keeps when not told (tests read them from ``records``)."""

RETRY_EVERY = 1.0
"""Clock seconds between attempts to write again once the log's file failed (a full disk)."""


class EventLog:
    """Append-only JSONL log, rotated to ``NAME.1``, ``NAME.2``… past ``max_bytes``.

    With ``path=None`` events are only kept in memory (``records``), which tests use:
    :data:`IN_MEMORY` of them unless ``keep_in_memory`` says how many (0: none, only the taps
    see them; a live run without ``--log`` keeps its last thousand). The list is cut back to
    ``keep_in_memory`` in batches, an eighth over: cut one record at a time, a full list moved
    every pointer it held on each emit (107 µs an event at a million, against ~2 µs), and a live
    run without ``--log`` that kept a million (the bound was once a floor) slowed so after
    twenty minutes.

    The log is what a run can most afford to lose: a full disk or an I/O error on its file
    never stops the colony. Events that cannot be written are counted (``lost``, with the
    reason in ``error``), ``report`` is told once per outage, writing is tried again every
    :data:`RETRY_EVERY` clock seconds, and the first line written after an outage is an
    ``events lost`` record, so the log itself shows the gap. A line torn by the failure is cut
    off the file, which keeps only whole lines. Only a regular file is written and rotated:
    ``path`` naming a device, a FIFO or a directory is refused at once, and rotation renames
    only the very file the log has open and regular files beside it.

    ``flushed_elsewhere``: another thread calls :meth:`flush` regularly (a live run's
    supervisor), so :meth:`emit` never writes to disk itself (up to :data:`BACKLOG_BYTES`
    pending): the creature's thread neither waits on the disk nor on a write under way,
    since a write happens outside the lock that emitting takes (the pending lines are
    swapped out under it).
    """

    def __init__(
        self,
        path: str | os.PathLike | None = None,
        *,
        max_bytes: int = 64 * 1024 * 1024,
        backups: int = 5,
        keep_in_memory: int | None = None,
        report: Callable[[str], None] | None = None,
        flushed_elsewhere: bool = False,
    ) -> None:
        self.path = regular_file(path, "events log") if path is not None else None
        self.max_bytes = max_bytes
        self.backups = backups
        self.keep_in_memory = keep_in_memory if keep_in_memory is not None else 0 if path is not None else IN_MEMORY
        self.records: list[dict[str, Any]] = []
        self.count = 0
        self.lost = 0
        self.error: str | None = None
        self.report = report
        self.flushed_elsewhere = flushed_elsewhere
        self._handle: IO[bytes] | None = None
        self._size = 0  # bytes in the live file, counted here rather than asking tell() per event
        self._pending = bytearray()  # whole lines not yet written
        self._ends: list[int] = []  # where each pending line ends in ``_pending``
        self._t = 0.0
        self._retry_at = -math.inf
        self._down = False  # an outage is under way (reported once, and again when it ends)
        self._gap_pending = False  # the first pending line is the ``events lost`` record, not an event
        self._closed = False
        self.taps: list[Callable[[dict[str, Any]], None]] = []
        """Called with every record as emitted, on the emitting thread (the live view's feed,
        :mod:`creatures.view.feed`): each must be quick and must not keep the record's fields
        to change them."""
        # A live run flushes from its supervisor thread (creatures/supervisor.py) while the
        # creature's thread emits: the pending buffer and its line ends change under this lock.
        # Reentrant, since ``report`` may itself log. Writes hold ``_writing`` instead (one at
        # a time, taken before ``_lock``, never while holding it).
        self._lock = threading.RLock()
        self._writing = threading.RLock()
        if self.path is not None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._open()

    def _open(self) -> None:
        """Open the log's file for appending; refuse anything but a regular file (O_NONBLOCK:
        a FIFO put there since the check must not block the run)."""
        assert self.path is not None
        handle = io.open(self.path, "ab", buffering=0,
                         opener=lambda p, flags: os.open(p, flags | os.O_NONBLOCK, 0o666))
        mode = os.fstat(handle.fileno()).st_mode
        if not stat.S_ISREG(mode):
            handle.close()
            raise UnsafePathError(f"events log {self.path}: is {kind_of(mode)}, not a regular file")
        self._handle = handle
        self._size = os.fstat(handle.fileno()).st_size

    def emit(self, t: float, kind: str, **fields: Any) -> None:
        self.count += 1
        if self.keep_in_memory:
            record = {"t": round(float(t), 6), "kind": kind, **_plain(fields)}
            self.records.append(record)
            if len(self.records) > self.keep_in_memory + max(self.keep_in_memory // 8, 16):  # in batches
                del self.records[: len(self.records) - self.keep_in_memory]
        else:
            record = {"t": round(float(t), 6), "kind": kind, **fields}
        for tap in self.taps:
            tap(record)
        if self.path is None or self._closed:
            return
        line = json_line(record)
        with self._lock:
            self._t = t
            if self._handle is None and not self._reopen():
                self.lost += 1
                return
            due = self._append(line)
        if due:
            self._drain()

    def _append(self, line: bytes) -> bool:
        """Add a line; whether the pending lines are now due to be written (by the caller,
        once it has let go of the lock)."""
        self._pending += line
        self._ends.append(len(self._pending))
        if self.flushed_elsewhere:
            return len(self._pending) >= BACKLOG_BYTES
        return len(self._pending) >= BUFFER_BYTES or self._size + len(self._pending) >= self.max_bytes

    def _drain(self) -> None:
        """Write the pending lines; rotate past the bound. A failure counts what was lost.
        The lines are taken under the lock and written outside it, so an emit meanwhile only
        appends to a fresh buffer."""
        with self._writing:
            with self._lock:
                if self._handle is None or not self._pending:
                    return
                if self._size >= self.max_bytes:  # reopened after an outage: rotate before writing more
                    try:
                        self._rotate()
                    except OSError as exc:
                        self._fail(exc)
                        return
                data, ends, handle = self._pending, self._ends, self._handle
                self._pending, self._ends = bytearray(), []
            failed = self._write(handle, bytes(data))
            with self._lock:
                if failed is not None:  # as if never taken: the failure counts these lines and the newer
                    self._pending = data + self._pending
                    self._ends = ends + [len(data) + end for end in self._ends]
                    self._fail(failed)
                    return
                self._settle(len(data))

    def _write(self, handle: IO[bytes], data: bytes) -> OSError | None:
        """Write all of ``data``; the failure, if any."""
        try:
            written = 0
            while written < len(data):  # an unbuffered write may take part of it
                taken = handle.write(data[written:])
                if not taken:
                    raise OSError(errno.EIO, "the file took none of the write", str(self.path))
                written += taken
        except OSError as exc:
            return exc
        return None

    def _settle(self, written: int) -> None:
        """After ``written`` bytes reached the file: end an outage, rotate past the bound."""
        self._size += written
        self._gap_pending = False  # the gap record (only ever first) has been written
        if self._down:
            self._down = False
            if self.report is not None:
                self.report(f"events log: writing {self.path} again ({self.lost} events lost)")
        if self._size >= self.max_bytes:
            try:
                self._rotate()
            except OSError as exc:
                self._fail(exc)

    def _fail(self, exc: OSError) -> None:
        """The file failed (disk full, I/O error, cannot rotate): keep the whole lines that
        reached it, cut a torn one off, count the rest lost, let go of the file."""
        handle, self._handle = self._handle, None
        whole = kept = 0  # without the file (it failed to reopen) or its size, every pending line is lost
        if handle is not None:
            with contextlib.suppress(OSError):
                reached = os.fstat(handle.fileno()).st_size - self._size
                whole = bisect.bisect_right(self._ends, reached)
                kept = self._ends[whole - 1] if whole else 0
                if reached > kept:
                    os.ftruncate(handle.fileno(), self._size + kept)
            with contextlib.suppress(OSError):
                handle.close()
        self.lost += len(self._ends) - whole - (self._gap_pending and whole == 0)
        self._size += kept
        self._pending.clear()
        self._ends.clear()
        self._gap_pending = False
        self.error = f"{exc.strerror or exc} ({exc.filename or self.path})"
        self._retry_at = self._t + RETRY_EVERY
        first, self._down = not self._down, True
        if first and self.report is not None:
            self.report(f"events log: cannot write {self.path}: {self.error}; the colony goes on, events "
                        f"are counted and dropped until it can be written again")

    def _reopen(self) -> bool:
        """After a failure, open the file again once :data:`RETRY_EVERY` has passed; the first
        line then says how many events were lost (the outage ends when a write succeeds)."""
        if self._t < self._retry_at:
            return False
        self._retry_at = self._t + RETRY_EVERY
        try:
            self._open()
        except OSError:
            return False
        self._gap_pending = True
        self._append(json_line({"t": round(float(self._t), 6), "kind": "events lost", "lost": self.lost,
                            "error": self.error}))
        return True

    def _rotate(self) -> None:
        """``NAME`` → ``NAME.1`` → ``NAME.2``…, renaming only regular files: ``NAME`` must still
        be the file this log has open (the same inode), never whatever the path names now."""
        assert self._handle is not None and self.path is not None
        ours = os.fstat(self._handle.fileno())
        now = os.lstat(self.path)
        if not stat.S_ISREG(now.st_mode) or (now.st_dev, now.st_ino) != (ours.st_dev, ours.st_ino):
            raise UnsafePathError(errno.EEXIST, "not rotated: the path is no longer this log's regular file",
                                  str(self.path))
        parts = [self.path.with_name(f"{self.path.name}.{i}") for i in range(1, self.backups + 1)]
        for part in parts:
            with contextlib.suppress(FileNotFoundError):
                mode = os.lstat(part).st_mode
                if not stat.S_ISREG(mode):
                    raise UnsafePathError(errno.EEXIST, f"not rotated: is {kind_of(mode)}", str(part))
        self._handle.close()
        self._handle = None
        for older, newer in zip(reversed(parts[:-1]), reversed(parts[1:])):
            if older.exists():
                older.replace(newer)
        self.path.replace(parts[0])
        self._open()

    def flush(self) -> None:
        self._drain()

    @property
    def loss(self) -> str | None:
        """One line on what the log lost, or None when it kept everything."""
        if not self.lost:
            return None
        return f"events log {self.path}: {self.lost} events not written (last failure: {self.error})"

    def close(self) -> None:
        self._drain()
        with self._lock:
            self._closed = True
        handle, self._handle = self._handle, None
        if handle is not None:
            with contextlib.suppress(OSError):  # unbuffered: nothing is left to fail but the descriptor
                handle.close()

    def __enter__(self) -> "EventLog":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _edges(value: Any) -> bool:
    return isinstance(value, list) and all(
        isinstance(e, list) and len(e) == 2 and all(isinstance(n, int) and n >= 0 for n in e) for e in value)


def _hands(value: Any) -> bool:
    flat = value
    while flat and isinstance(flat, list) and all(isinstance(v, list) for v in flat):
        flat = [x for v in flat for x in v]
    return isinstance(flat, list) and len(flat) % 3 == 0 and all(_number(x) for x in flat)


def _points(value: Any) -> bool:
    return isinstance(value, list) and all(isinstance(p, list) and len(p) == 3 and all(_number(x) for x in p)
                                           for p in value)


def _parents(value: Any) -> bool:
    return isinstance(value, list) and all(isinstance(p, int) and -1 <= p < len(value) for p in value)


_NOTE = {"time": _number, "pitch": _number, "duration": _number}
FIELDS: dict[str, dict[str, Callable[[Any], bool]]] = {
    "": {"t": _number, "kind": lambda v: isinstance(v, str)},
    "note": _NOTE,
    "heard": _NOTE,
    "selection": {"tuple": lambda v: isinstance(v, str)},
    "motor graph": {"hands": _hands, "edges": _edges},
    "skeleton": {"creature": lambda v: isinstance(v, str), "parents": _parents,
                 "place": lambda v: _points([v])},
    "pose": {"creature": lambda v: isinstance(v, str), "joints": _points,
             "marks": lambda v: isinstance(v, list) and all(isinstance(m, list) and len(m) == 4
                                                            and all(_number(x) for x in m) for m in v)},
}
"""The fields every event has (``""``) and those the readers (report, inspector) take from
some kinds, with what each must be; ``creature`` and ``source`` are strings where present."""


def _malformed(event: Any) -> str | None:
    """What is wrong with one decoded event, or None."""
    if not isinstance(event, dict):
        return f"an event is a JSON object, found {type(event).__name__}"
    for kind in ("", event.get("kind")):
        for name, fits in FIELDS.get(kind, {}).items() if isinstance(kind, str) else ():
            if not fits(event.get(name)):
                what = f"{kind!r} event" if kind else "event"
                return f"{what} with a missing or malformed {name!r} ({event.get(name)!r:.40})"
    for name in ("creature", "source"):
        if name in event and not isinstance(event[name], str):
            return f"{name!r} must be a string"
    return None


def iter_events(path: str | os.PathLike, say: Callable[[str], None] | None = None) -> Iterator[dict[str, Any]]:
    """Each event of a JSONL events log in turn; a malformed line — not JSON, not UTF-8, nested
    too deep, or an event lacking what the readers take from it (:data:`FIELDS`) — raises
    ValueError naming file and line (issue 13: ``creatures inspect`` gave tracebacks on such logs).

    One event at a time, because a long run's log is mostly ``pose`` events that a report
    never draws: a 26 MB log held whole as dicts took 218 MB (a night's, gigabytes).

    A last line cut short (no newline: a live run's ``--log`` when the power went) is the
    write the cut interrupted, not a damaged log: it is left out and said to ``say`` (the
    module's logger when none). ``creatures view``, ``inspect`` and the report refused the
    whole run for it."""
    with open_regular(path, "events log") as handle:  # a FIFO would block inspect forever
        for lineno, raw in enumerate(handle, 1):
            if not raw.strip():
                continue
            try:
                event = json.loads(raw.decode("utf-8"))
            except (UnicodeDecodeError, json.JSONDecodeError) as exc:
                if not raw.endswith(b"\n"):  # only the last line can lack one
                    (say or _log.warning)(f"{path}:{lineno}: the last line was cut short (its write interrupted); "
                                          "read without it")
                    return
                why = "not UTF-8 text" if isinstance(exc, UnicodeDecodeError) else exc.msg
                raise ValueError(f"{path}:{lineno}: malformed event ({why})") from None
            except RecursionError:
                raise ValueError(f"{path}:{lineno}: malformed event (nested too deeply)") from None
            problem = _malformed(event)
            if problem is not None:
                raise ValueError(f"{path}:{lineno}: malformed event ({problem})")
            yield event


def read_events(path: str | os.PathLike, say: Callable[[str], None] | None = None, *,
                kinds: Collection[str] | None = None, counts: Counter[str] | None = None) -> list[dict[str, Any]]:
    """The events of a JSONL events log (:func:`iter_events`, which checks every line), only
    those of ``kinds`` kept when given; ``counts`` gets every event read counted by kind, so a
    reader that keeps a few kinds can still say how many of each the run logged."""
    events = []
    for event in iter_events(path, say):
        if counts is not None:
            counts[event["kind"]] += 1
        if kinds is None or event["kind"] in kinds:
            events.append(event)
    return events
