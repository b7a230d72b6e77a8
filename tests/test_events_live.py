"""The events log in a live run (creatures/events.py, ``flushed_elsewhere``): the creature's
thread never writes the file, and an emit never waits for a write under way."""

from __future__ import annotations

import threading

from creatures.events import BACKLOG_BYTES, BUFFER_BYTES, EventLog, read_events


class _GatedFile:
    """The log's file, whose writes wait until ``release`` is set (a slow disk)."""

    def __init__(self, real) -> None:
        self.real = real
        self.entered = threading.Event()
        self.release = threading.Event()

    def write(self, data: bytes) -> int:
        self.entered.set()
        assert self.release.wait(30), "the test never released the write"
        return self.real.write(data)

    def fileno(self) -> int:
        return self.real.fileno()

    def close(self) -> None:
        self.real.close()


def test_emitting_never_writes_when_another_thread_flushes(tmp_path) -> None:
    path = tmp_path / "events.jsonl"
    log = EventLog(path, flushed_elsewhere=True)
    n = 0
    while path.stat().st_size == 0 and n * 60 < 2 * BUFFER_BYTES:
        log.emit(n * 0.04, "note", time=0.0, pitch=60, duration=0.5, padding="x" * 20)
        n += 1
    assert path.stat().st_size == 0  # well past one buffer: nothing written by the emitting thread
    log.flush()
    assert len(read_events(path)) == n
    flushed = path.stat().st_size
    while path.stat().st_size == flushed and log.count - n < BACKLOG_BYTES // 40:
        log.emit(1.0, "note", time=0.0, pitch=60, duration=0.5)
    assert len(read_events(path)) > n  # a stalled flusher: past the backlog the emitter writes after all
    log.close()
    assert len(read_events(path)) == log.count and log.lost == 0


def test_an_emit_does_not_wait_for_a_write_under_way(tmp_path) -> None:
    path = tmp_path / "events.jsonl"
    log = EventLog(path, flushed_elsewhere=True)
    log.emit(0.0, "note", time=0.0, pitch=60, duration=0.5)
    gate = log._handle = _GatedFile(log._handle)
    flusher = threading.Thread(target=log.flush)
    flusher.start()
    assert gate.entered.wait(30)  # the supervisor's write is under way, blocked on the disk
    emitted = threading.Event()
    emitter = threading.Thread(target=lambda: (log.emit(0.04, "note", time=0.04, pitch=62, duration=0.5),
                                               emitted.set()))
    emitter.start()
    assert emitted.wait(30)  # returned while the write still waits
    assert not gate.release.is_set()
    gate.release.set()
    flusher.join(30)
    emitter.join(30)
    log.close()
    assert [e["pitch"] for e in read_events(path)] == [60, 62]
