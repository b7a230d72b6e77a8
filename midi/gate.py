"""The live MIDI input's bound: at most ``max_rate`` messages a second reach the colony.

An OSC listener reads at most ``[osc] max_rate`` packets a second (:mod:`midi.osc`); a MIDI
port had no such bound, and a broken or hostile controller's burst of 10,000 notes was placed
note by note on the creature's thread (exchange: one tick of 0.3–0.5 s here, 2.4 s on a loaded
machine; 30–60 ms with this bound). So the same token bucket (:class:`~midi.peer_table.Bucket`) meters the MIDI
input: ``max_rate`` tokens a second, :data:`BURST` seconds' worth held after a quiet spell, one
spent by each message; a message that finds the bucket empty is dropped (the caller counts it).

Unlike OSC's, the excess is not left in the port's queue: there RtMidi would drop whatever came
next when it filled, note-offs with the rest, and what stayed would arrive late. One kind of
message is never dropped: the note-off of a note that was let in (a note-on of velocity 0
included), which passes without a token; dropped, it would leave the note held for ever. A
note-off of a note not let in (dropped, or pressed before the port opened) spends a token as
any message does. A channel-mode message that ends every note of its channel (All Sound Off,
All Notes Off and the mode changes that imply it: CC 120 and 123–127, a controller's panic
button) passes the same way when that channel holds notes let in, and they are all ended: a
flood must not leave a panicking player's notes held. On a channel holding none it spends a
token, so a flood of them is bounded like any other.
"""

from __future__ import annotations

from collections import Counter

import mido

from midi.notes import is_note_off
from midi.peer_table import Bucket

ENDS_EVERY_NOTE = frozenset({120, 123, 124, 125, 126, 127})
"""Channel-mode controllers that end every note of their channel (MIDI 1.0: All Sound Off,
All Notes Off, Omni Off/On, Mono On, Poly On)."""

BURST = 0.5
"""Seconds of ``max_rate`` taken at once after a quiet spell: at the default 500 a second, 250
messages (ten-note chords with both pedals, a fader swept end to end) pass whole, and a burst
beyond costs the creature's thread at most that many notes (a tick of about 30 ms of exchange's)."""


class MidiGate:
    """Lets a MIDI message through if ``max_rate`` allows it at time ``t`` (seconds of the run's clock)."""

    def __init__(self, max_rate: float) -> None:
        self.max_rate = max_rate
        self._budget = Bucket(max_rate, max(1.0, max_rate * BURST))
        self._held: Counter[tuple[int, int]] = Counter()  # (channel, note) -> note-ons let in, not yet ended

    def admit(self, msg: mido.Message, t: float) -> bool:
        """Whether ``msg`` passes: a note-off of a note let in always does, without a token, and
        so does a message ending every note of a channel holding notes let in; any other message
        if the bucket holds one, which it spends."""
        if is_note_off(msg) and self._held[(msg.channel, msg.note)]:
            self._held[(msg.channel, msg.note)] -= 1
            return True
        if msg.type == "control_change" and msg.control in ENDS_EVERY_NOTE:
            held = [key for key, count in self._held.items() if key[0] == msg.channel and count]
            for key in held:
                del self._held[key]
            if held:
                return True
        if not self._budget.take(t):
            return False
        if msg.type == "note_on":  # not a note-off (above): a key went down
            self._held[(msg.channel, msg.note)] += 1
        return True
