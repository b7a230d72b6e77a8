"""The polled RtMidi input counts what it must drop: malformed bytes and full queues; the live
run's port keeps the count."""

from __future__ import annotations

import mido

from creatures.clock import SimulatedClock
from midi.polled import QUEUE_SIZE, PolledInput
from midi.ports import ResilientPort


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



class UnpluggedMidiIn(FakeMidiIn):
    """A device whose cable is pulled once its queued events are read: reading raises."""

    def get_message(self) -> tuple[list[int], float] | None:
        if not self.events:
            raise OSError("device disconnected")
        return super().get_message()


def test_a_resilient_port_keeps_what_its_polled_inputs_lost_across_a_reopen():
    """The live run reads its input through :class:`ResilientPort`; what each polled port it
    opened counted as lost is summed there, a port lost and opened again included."""
    full = [[0x90, i % 128, 1 + i % 127] for i in range(QUEUE_SIZE - 1)]
    first = FakeMidiIn(full + [[0xF4]])  # a full queue, and an undefined status byte
    ports = iter([PolledInput("keys", midi_in=first),
                  PolledInput("keys", midi_in=FakeMidiIn([[0x90, 60], [0xF5]]))])  # a cut note-on, an undefined status

    class Keyboard:
        def names(self) -> list[str]:
            return ["keys"]

        def open(self, name: str, *, virtual: bool = False) -> PolledInput:
            return next(ports)

    clock = SimulatedClock()
    keys = ResilientPort("keys", Keyboard(), clock, report=lambda message: None)
    assert len(keys.pending()) == QUEUE_SIZE - 1
    first.__class__ = UnpluggedMidiIn  # the cable is pulled
    assert keys.pending() == [] and not keys.connected
    clock.advance(keys.retry_interval)
    assert keys.pending() == [] and keys.connected  # opened again: the second port
    assert (keys.full_queues, keys.malformed_bytes) == (1, 1 + 3)
