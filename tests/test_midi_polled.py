"""The polled RtMidi input counts what it must drop: malformed bytes and full queues."""

from __future__ import annotations

import mido

from midi.polled import QUEUE_SIZE, PolledInput


class FakeMidiIn:
    """Stands in for an open ``rtmidi.MidiIn``: hands out queued ``(bytes, delta)`` events."""

    def __init__(self, events: list[list[int]]) -> None:
        self.events = list(events)
        self.closed = False

    def get_message(self) -> tuple[list[int], float] | None:
        return (self.events.pop(0), 0.0) if self.events else None

    def close_port(self) -> None:
        self.closed = True

    def delete(self) -> None:
        pass


def test_malformed_bytes_are_dropped_and_counted():
    fake = FakeMidiIn([[0x90, 60, 100], [0x3C], [0x90, 61], [0xF4], [0x80, 60, 0]])
    port = PolledInput("fake", midi_in=fake)
    got = list(port.iter_pending())
    port.close()
    assert got == [mido.Message("note_on", note=60, velocity=100), mido.Message("note_off", note=60, velocity=0)]
    # A stray data byte, a note-on cut short (its status and one data byte), an undefined status.
    assert port.malformed_bytes == 4
    assert port.full_queues == 0 and fake.closed


def test_a_poll_that_finds_rtmidis_queue_full_is_counted():
    port = PolledInput("fake", midi_in=FakeMidiIn([[0x90, i % 128, 1 + i % 127] for i in range(QUEUE_SIZE - 1)]))
    assert len(list(port.iter_pending())) == QUEUE_SIZE - 1
    port._rt.events.append([0x90, 1, 1])
    assert len(list(port.iter_pending())) == 1
    assert port.full_queues == 1 and port.malformed_bytes == 0
