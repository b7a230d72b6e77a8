"""MIDI in and out: note events, live ports (mido + python-rtmidi), files, raw bytes, a
note scheduler, note objects placed in space, and OSC exchange between creatures."""
