"""An rtmidi input port that the creature polls, so no Python runs on the MIDI driver's thread.

mido's rtmidi backend hands every incoming message to a Python callback, which RtMidi calls
from the driver's own thread: under JACK, that is the real-time process callback, and the
callback must take Python's GIL. Whenever the creature's thread holds the GIL for a while (a
garbage-collection pass, a numba compile, a long numpy call that keeps it), the whole JACK
graph stalls behind it; the server then times out, and downstream clients re-read the last
buffer they were given. Measured here: with the GIL held for 2.4 s during a 100-note burst,
mido's callback input received 100 messages of which only 50 were distinct (stale repeats);
this polled input received all 100, in order.

So this port leaves the messages in RtMidi's own C++ queue (``queue_size_limit``) and
drains it from the creature's thread when asked, like any mido input. Bytes go through the
project's :class:`~midi.parser.StreamParser` (not mido's ``Parser``, which drops malformed
bytes without a trace), so what a faulty device sends is dropped *and counted*
(:attr:`PolledInput.malformed_bytes`). RtMidi drops messages beyond a full queue and only
prints a line to stderr; a poll that finds the queue full is counted in
:attr:`PolledInput.full_queues`, the sign that messages may have been lost.
"""

from __future__ import annotations

from typing import Any

import rtmidi
from mido.ports import BaseInput

from midi.parser import StreamParser

QUEUE_SIZE = 4096  # messages RtMidi holds between two polls (a busy tick at 25 Hz needs ~100)


def api_id(api: str | None) -> int:
    """RtMidi's number for an API name as mido spells it (``"UNIX_JACK"``, ``"LINUX_ALSA"``)."""
    if api is None:
        return rtmidi.API_UNSPECIFIED
    try:
        return getattr(rtmidi, f"API_{api}")
    except AttributeError:
        raise ValueError(f"unknown RtMidi API {api!r}") from None


class PolledInput(BaseInput):
    """A MIDI input (by exact port name, or a new virtual port called ``name``) read by polling."""

    _locking = False  # only the creature's thread touches it

    def _open(self, api: str | None = None, virtual: bool = False, midi_in: Any = None, **kwargs) -> None:
        """``midi_in``: an rtmidi ``MidiIn`` already open (tests pass a stand-in); else one
        is made for ``api`` and opened on the port called ``name``."""
        self._stream = StreamParser()
        self.full_queues = 0  # polls that found RtMidi's queue full (messages may have been lost)
        if midi_in is not None:
            self._rt = midi_in
            return
        self._rt = rtmidi.MidiIn(rtapi=api_id(api), queue_size_limit=QUEUE_SIZE)
        try:
            if virtual:
                self._rt.open_virtual_port(self.name)
            else:
                names = self._rt.get_ports()
                if self.name not in names:
                    raise OSError(f"unknown MIDI input port {self.name!r}; ports are {names}")
                self._rt.open_port(names.index(self.name))
        except (rtmidi.RtMidiError, RuntimeError) as exc:
            self._rt.delete()
            raise OSError(str(exc)) from exc
        self._rt.ignore_types(sysex=False, timing=False, active_sense=True)

    @property
    def malformed_bytes(self) -> int:
        """Bytes received that belonged to no message (dropped)."""
        return self._stream.malformed_bytes

    def _receive(self, block: bool = True) -> None:
        """Move everything RtMidi has queued into the port's messages (never waits: the base
        class loops, with a short sleep, when a caller asks to block)."""
        drained = 0
        while (event := self._rt.get_message()) is not None:
            self._stream.feed(event[0])
            drained += 1
        # RtMidi's ring holds QUEUE_SIZE - 1 messages; a poll that drained that many found it full.
        if drained >= QUEUE_SIZE - 1:
            self.full_queues += 1
        self._messages.extend(self._stream.pending())

    def _close(self) -> None:
        self._rt.close_port()
        self._rt.delete()
