"""Notes in the microphone heard between behaviour ticks, as MIDI notes are.

The live loop looks at its inputs about every millisecond between ticks
(:mod:`creatures.runtime.ticking`), so a key that goes down is answered at once rather than at
the next tick. Audio was read only at ticks, so a note played into the microphone waited for
the next tick (up to ``tick`` seconds: 10 ms in bench/live_hearing.py's run) before the
transcriber saw its attack, on top of the transcriber's own look. Here the microphone is read
at every look too: what arrived is transcribed at once, its notes join the note bus, and the
audio is kept for the next tick, where the creatures' ears and the room's air hear it whole
(transcribed once, not again: ``Session.step(..., transcribed=True)``).

The thesis builds its motor system under "the constraints imposed by the need for real-time
interaction with our characters"; a performer notices a late answer long before a late tick.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from creatures.runtime.session import Session


class Microphone(Protocol):
    def read(self) -> np.ndarray | None:
        """Everything that arrived since the last read, at the session's rate (possibly empty)."""
        ...


class MicrophoneNotes:
    """Reads ``microphone`` at every look, hears its notes at once, and hands the tick the audio."""

    def __init__(self, microphone: Microphone, session: Session) -> None:
        self.microphone = microphone
        self.session = session
        self._pending: list[np.ndarray] = []

    def poll(self, t: float) -> int:
        """Read what arrived by ``t`` and hear its notes (they join the note bus); how many."""
        block = self.microphone.read()
        if block is None or not len(block):
            return 0
        self._pending.append(block)
        return self.session.hear_notes(t, block)

    def take(self, t: float) -> np.ndarray:
        """All the audio since the last tick (its notes already heard), for the tick at ``t``."""
        self.poll(t)
        if not self._pending:
            return np.zeros(0, dtype=np.float32)
        block = self._pending[0] if len(self._pending) == 1 else np.concatenate(self._pending)
        self._pending.clear()
        return block
