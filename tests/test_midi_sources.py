"""Note sources share one interface: poll() returns what is due by the clock, never blocks."""

from __future__ import annotations

import os

import mido
import pytest

from creatures.clock import SimulatedClock
from midi.files import TempoMap, write_notes
from midi.notes import NoteEvent, NotePairer, from_messages, to_messages
from midi.sources import ByteSource, FileSource, ListSource


def test_note_event_validates_its_fields():
    with pytest.raises(ValueError, match="velocity must be an int in 1..127"):
        NoteEvent(0.0, 60, 0)
    with pytest.raises(ValueError, match="duration must be a finite number >= 0"):
        NoteEvent(0.0, 60, 100, 0, float("nan"))
    with pytest.raises(ValueError, match="channel"):
        NoteEvent(0.0, 60, 100, 16)
    with pytest.raises(ValueError, match="pitch"):
        NoteEvent(0.0, True)


def test_pairing_is_fifo_and_accepts_velocity_zero_note_ons():
    on = lambda n, v=100: mido.Message("note_on", note=n, velocity=v)  # noqa: E731
    timed = [(0.0, on(60, 10)), (1.0, on(60, 20)), (2.0, on(60, 0)),
             (3.0, mido.Message("note_off", note=60)), (4.0, mido.Message("note_off", note=61))]
    pairer = NotePairer()
    notes = [n for t, m in timed if (n := pairer.feed(t, m))]
    assert notes == [NoteEvent(0.0, 60, 10, 0, 2.0), NoteEvent(1.0, 60, 20, 0, 2.0)]
    assert pairer.unmatched_offs == 1 and pairer.sounding == 0
    # A note still sounding at the end is closed there.
    assert from_messages([(0.5, on(70))], end=2.0) == [NoteEvent(0.5, 70, 100, 0, 1.5)]


def test_list_source_replays_against_the_simulated_clock_as_fast_as_possible(rng):
    clock = SimulatedClock(start=100.0)
    notes = [NoteEvent(float(t), 60 + i % 12, 90, 0, 0.3) for i, t in enumerate(sorted(rng.uniform(0, 20, 300)))]
    source = ListSource(notes, clock)
    heard = []
    for _ in range(600):  # each step must deliver something: at most one poll per message
        if (due := source.next_due()) is None:
            break
        clock.advance_to(due)
        heard += source.poll()
    assert source.exhausted
    assert [t for t, _ in heard] == [100.0 + t for t, _ in to_messages(notes)]
    assert [m for _, m in heard] == [m for _, m in to_messages(notes)]


def test_file_source_honours_the_tempo_map(tmp_path):
    notes = [NoteEvent(float(i), 60 + i, 100, 0, 0.5) for i in range(8)]
    write_notes(tmp_path / "tempo.mid", notes, tempo=TempoMap.from_seconds(480, [(3.0, 200.0)]))
    clock = SimulatedClock()
    source = FileSource(tmp_path / "tempo.mid", clock)
    clock.advance_to(4.0)
    early = source.poll()
    assert [m.note for _, m in early if m.type == "note_on"] == [60, 61, 62, 63, 64]
    clock.advance_to(4.4)
    assert source.poll() == []  # the next event (64 off at 4.5 s) is not yet due
    clock.advance_to(100.0)
    assert len(source.poll()) == 16 - len(early) and source.exhausted


def test_byte_source_reads_a_nonblocking_pipe_with_running_status():
    read_fd, write_fd = os.pipe()
    os.set_blocking(read_fd, False)

    def read() -> bytes:
        try:
            return os.read(read_fd, 4096)
        except BlockingIOError:
            return b""

    clock = SimulatedClock()
    source = ByteSource(clock, read)
    try:
        assert source.poll() == []  # nothing written: returns at once
        os.write(write_fd, bytes.fromhex("90 3C 64 3E"))  # second message split across writes
        first = source.poll()
        os.write(write_fd, bytes.fromhex("64 40 00 45"))
        clock.advance(0.1)
        second = source.poll()
    finally:
        os.close(read_fd)
        os.close(write_fd)
    assert [(t, m.note, m.velocity) for t, m in first] == [(0.0, 60, 100)]
    assert [(t, m.note, m.velocity) for t, m in second] == [(0.1, 62, 100), (0.1, 64, 0)]
    assert source.malformed_bytes == 0
