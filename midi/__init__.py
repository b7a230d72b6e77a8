"""MIDI in and out: note events, live ports (mido + python-rtmidi), files, raw bytes, a
note scheduler, note objects placed in space, and OSC exchange between creatures.

One module per concern (thesis sections "exchange", "musical worlds", "listen"):

- :mod:`midi.notes` — :class:`NoteEvent`, note-on/off pairing.
- :mod:`midi.parser` — raw byte streams with running status.
- :mod:`midi.files` — ``.mid`` in and out with tempo maps; :class:`MidiFileError`.
- :mod:`midi.ports` — in-memory ports, port lookup, ports that survive device faults.
- :mod:`midi.polled` — a live input read once a tick; :mod:`midi.sinks` — where notes go to.
- :mod:`midi.scheduler` — :class:`NoteScheduler`: due-time sending, no hanging notes.
- :mod:`midi.note_objects` — :class:`NoteObject` / :class:`NoteSpace`.
- :mod:`midi.osc` — the network colony over OSC/UDP.
"""

from __future__ import annotations

from midi.files import MidiFileError, TempoMap, read_notes, write_notes
from midi.note_objects import NoteObject, NoteSpace
from midi.notes import NoteEvent
from midi.scheduler import NoteScheduler

__all__ = [
    "MidiFileError", "NoteEvent", "NoteObject", "NoteScheduler", "NoteSpace", "TempoMap",
    "read_notes", "write_notes",
]
