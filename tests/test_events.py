"""The events log writes one JSON object per line, rotates at its bound, and reads back."""

from __future__ import annotations

import errno
import os
import time
from collections import Counter

import numpy as np
import pytest

from creatures.events import EventLog, read_events


def test_events_round_trip_with_numpy_values(tmp_path):
    path = tmp_path / "events.jsonl"
    with EventLog(path) as log:
        log.emit(0.5, "selection", tuple="sit", values=np.array([1.0, 2.5]), v=np.float32(3.0))
        log.emit(1.0, "reward", value=float("nan"))
    events = read_events(path)
    assert events[0] == {"t": 0.5, "kind": "selection", "tuple": "sit", "values": [1.0, 2.5], "v": 3.0}
    assert events[1]["value"] is None


def test_rotation_bounds_disk_use(tmp_path):
    path = tmp_path / "events.jsonl"
    with EventLog(path, max_bytes=2000, backups=2) as log:
        for i in range(1000):
            log.emit(i, "tick", i=i)
    files = sorted(p.name for p in tmp_path.iterdir())
    assert files == ["events.jsonl", "events.jsonl.1", "events.jsonl.2"]
    assert all(p.stat().st_size < 2100 for p in tmp_path.iterdir())
    assert read_events(path)[-1]["i"] == 999


def test_a_reopened_log_counts_what_is_already_on_disk(tmp_path):
    """Rotation is decided on bytes counted in memory; a log appended to by a restarted run
    starts from the file's size, so the bound holds across restarts too."""
    path = tmp_path / "events.jsonl"
    with EventLog(path, max_bytes=2000, backups=1) as log:
        for i in range(40):
            log.emit(i, "tick", i=i)
    before = path.stat().st_size
    with EventLog(path, max_bytes=2000, backups=1) as log:
        for i in range(40, 80):
            log.emit(i, "tick", i=i, where="café")  # two bytes for é: bytes are counted, not characters
    assert before > 500 and (tmp_path / "events.jsonl.1").exists()
    assert all(p.stat().st_size < 2100 for p in tmp_path.iterdir())
    assert [e["i"] for e in read_events(tmp_path / "events.jsonl.1") + read_events(path)] == list(range(80))


def test_nan_anywhere_and_numpy_keys_are_written_as_plain_json(tmp_path):
    path = tmp_path / "events.jsonl"
    with EventLog(path) as log:
        log.emit(0.0, "values", values={np.int64(3): np.array([1.0, np.nan]), "b": (np.inf, 2)})
        log.emit(1.0, "count", n=2**70, who="café")  # beyond what orjson takes
    assert read_events(path) == [{"t": 0.0, "kind": "values", "values": {"3": [1.0, None], "b": [None, 2]}},
                                 {"t": 1.0, "kind": "count", "n": 2**70, "who": "café"}]


def test_in_memory_log_is_bounded():
    log = EventLog(keep_in_memory=10)
    for i in range(100):
        log.emit(i, "tick")
    assert log.count == 100 and len(log.records) >= 10


def test_malformed_line_names_file_and_line(tmp_path):
    path = tmp_path / "events.jsonl"
    path.write_text('{"t": 0, "kind": "a"}\n{broken\n')
    with pytest.raises(ValueError, match=r"events.jsonl:2"):
        read_events(path)


def test_a_reader_keeps_the_kinds_it_asks_for_and_counts_every_kind(tmp_path):
    """The report draws no poses, most of a log: it keeps what it draws and counts the rest."""
    path = tmp_path / "events.jsonl"
    path.write_text('{"t": 0, "kind": "stop"}\n{"t": 0, "kind": "note", "time": 0, "pitch": 60, "duration": 1}\n'
                    '{"t": 1, "kind": "stop"}\n{"t": 1, "kind": "run"}\n')
    counts: Counter[str] = Counter()
    kept = read_events(path, kinds=("note", "run"), counts=counts)
    assert [e["kind"] for e in kept] == ["note", "run"] and counts == {"stop": 2, "note": 1, "run": 1}
    path.write_text('{"t": 0, "kind": "stop"}\n{"t": 1, "kind": "note"}\n')  # a kind not kept is still checked
    with pytest.raises(ValueError, match=r"events.jsonl:2: malformed event \('note' event with a missing"):
        read_events(path, kinds=("run",))


def test_a_last_line_cut_short_is_left_out_and_said(tmp_path):
    """A live run's --log when the power went ends mid-line; ``creatures view``, ``inspect``
    and the report refused the whole run for it. A damaged line before the last still is."""
    path = tmp_path / "events.jsonl"
    path.write_text('{"t": 0, "kind": "a"}\n{"t": 0.5, "kind": "b"}\n{"t": 1.0, "ki')
    said: list[str] = []
    assert [e["kind"] for e in read_events(path, said.append)] == ["a", "b"]
    assert said == [f"{path}:3: the last line was cut short (its write interrupted); read without it"]
    path.write_bytes(b'{"t": 0, "kind": "a"}\n{"t": 0.5, "kind": "\xc3')  # cut inside a character
    assert [e["kind"] for e in read_events(path, said.append)] == ["a"]
    path.write_text('{"t": 0, "kind": "a"}\n{"t": 0.5, "ki\n{"t": 1.0, "kind": "c"}')
    with pytest.raises(ValueError, match=r"events.jsonl:2: malformed event"):
        read_events(path)


def test_a_full_disk_is_counted_loss_naming_the_log_and_close_still_lets_go(tmp_path):
    """A full disk never raises out of the log (issue 13: it crashed a live run): the events
    are counted lost, the reason names the file, and close lets go of it."""
    path = tmp_path / "events.jsonl"
    said = []
    log = EventLog(path, report=said.append)
    real = log._handle

    class FullDisk:
        """The log's file once the disk is full: every write fails."""

        def write(self, data):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

        def fileno(self):
            return real.fileno()

        def close(self):
            real.close()

    log._handle = FullDisk()
    for i in range(3):
        log.emit(0.1 * i, "tick")
    log.close()
    assert log.lost == 3 and real.closed
    assert log.loss == f"events log {path}: 3 events not written (last failure: No space left on device ({path}))"
    assert len(said) == 1 and str(path) in said[0]
    log.close()  # nothing left to fail


def test_a_log_keeps_what_it_is_told_and_trims_in_batches():
    """A live run without --log asks for its last thousand events: it keeps about that many
    (it used to keep a million, the bound being a floor), and emitting into a full list costs
    what emitting into an empty one does (trimmed one record at a time, each emit moved the
    whole list: 107 µs at a million)."""
    log = EventLog(keep_in_memory=1000)
    for i in range(20_000):
        log.emit(i, "tick", n=i)
    assert 1000 <= len(log.records) <= 1000 + 1000 // 8 and log.records[-1]["n"] == 19_999
    assert EventLog(keep_in_memory=0).keep_in_memory == 0 and EventLog().keep_in_memory == 1 << 20
    full = EventLog()
    full.records = [{"t": 0.0, "kind": "old"}] * (1 << 20)
    start = time.process_time()
    for i in range(5_000):
        full.emit(i, "tick")
    assert (time.process_time() - start) / 5_000 < 20e-6  # the cut is paid once per 131,072 emits
