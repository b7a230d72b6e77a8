"""Note events: their fields are checked, and note-on/off messages pair into notes."""

from __future__ import annotations

import mido
import pytest

from midi.notes import NoteEvent, NotePairer, from_messages


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
