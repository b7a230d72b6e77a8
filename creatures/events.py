"""The events log (DESIGN.md, "Seeing inside").

Every run can write one JSON object per line for each perception, selection, reward and motor
event, stamped with clock time. Plots, reports and the inspector read only this log and saved
state, so what they show is what happened. Files rotate at a size bound so a gallery run of
weeks cannot fill the disk.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import IO, Any

import orjson


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


def _line(record: dict[str, Any]) -> bytes:
    """One JSON line for ``record``, UTF-8. orjson writes numpy values and NaN (as ``null``)
    itself, about 9× faster than the standard library; a record it refuses (a key JSON cannot
    take, e.g. a numpy integer, or an integer beyond 64 bits) goes through :func:`_plain` and
    the standard library instead. A gallery day writes millions of events, so this is on
    every tick's path."""
    try:
        return orjson.dumps(record, option=_ORJSON) + b"\n"
    except TypeError:  # orjson.JSONEncodeError
        return json.dumps(_plain(record), separators=(",", ":"), ensure_ascii=False).encode() + b"\n"


class EventLog:
    """Append-only JSONL log, rotated to ``NAME.1``, ``NAME.2``… past ``max_bytes``.

    With ``path=None`` events are only kept in memory (``records``), which tests use.
    ``keep_in_memory`` bounds the in-memory list too.
    """

    def __init__(
        self,
        path: str | os.PathLike | None = None,
        *,
        max_bytes: int = 64 * 1024 * 1024,
        backups: int = 5,
        keep_in_memory: int = 0,
    ) -> None:
        self.path = Path(path) if path is not None else None
        self.max_bytes = max_bytes
        self.backups = backups
        self.keep_in_memory = keep_in_memory if path is not None else max(keep_in_memory, 1 << 20)
        self.records: list[dict[str, Any]] = []
        self.count = 0
        self._handle: IO[bytes] | None = None
        self._size = 0  # bytes in the live file, counted here rather than asking tell() per event
        if self.path is not None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._handle = self.path.open("ab")
            self._size = self._handle.tell()

    def emit(self, t: float, kind: str, **fields: Any) -> None:
        self.count += 1
        if self.keep_in_memory:
            record = {"t": round(float(t), 6), "kind": kind, **_plain(fields)}
            self.records.append(record)
            if len(self.records) > self.keep_in_memory:
                del self.records[: len(self.records) - self.keep_in_memory]
        else:
            record = {"t": round(float(t), 6), "kind": kind, **fields}
        if self._handle is not None:
            try:
                line = _line(record)
                self._handle.write(line)
                self._size += len(line)
                if self._size >= self.max_bytes:
                    self._rotate()
            except OSError as exc:
                if exc.filename is not None:
                    raise
                # "No space left on device" alone does not say which file filled the disk.
                raise type(exc)(exc.errno, exc.strerror, str(self.path)) from None

    def _rotate(self) -> None:
        assert self._handle is not None and self.path is not None
        self._handle.close()
        for i in range(self.backups - 1, 0, -1):
            older = self.path.with_name(f"{self.path.name}.{i}")
            if older.exists():
                older.replace(self.path.with_name(f"{self.path.name}.{i + 1}"))
        self.path.replace(self.path.with_name(f"{self.path.name}.1"))
        self._handle = self.path.open("ab")
        self._size = 0

    def flush(self) -> None:
        if self._handle is not None:
            self._handle.flush()

    def close(self) -> None:
        handle, self._handle = self._handle, None  # closed even if the final flush fails
        if handle is not None:
            handle.close()

    def __enter__(self) -> "EventLog":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def read_events(path: str | os.PathLike) -> list[dict[str, Any]]:
    """Read a JSONL events log; a malformed line raises ValueError naming file and line."""
    events = []
    with Path(path).open(encoding="utf-8") as handle:
        for lineno, line in enumerate(handle, 1):
            if not line.strip():
                continue
            try:
                events.append(json.loads(line))
            except json.JSONDecodeError as exc:
                raise ValueError(f"{path}:{lineno}: malformed event ({exc.msg})") from None
    return events
