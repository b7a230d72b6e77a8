"""What a synthesizer or DAW needs to hear before a creature's first note, and CC streams.

A General MIDI synth (fluidsynth, a DAW's instrument track) plays a channel with whatever
patch, level and position it last had; a creature's voice should be the same every time the
installation starts. So each creature's channel is set up at the start of a run: bank select
(CC 0 and 32), program change, channel volume (CC 7), pan (CC 10, from the creature's stereo
``pan``) and, where the creature's synth bends pitch, the pitch-bend range (RPN 0). The same
messages open the creature's track in ``out.mid``, so the file plays alike in a DAW.
"""

from __future__ import annotations

import mido

BANK_MSB, BANK_LSB, VOLUME, PAN = 0, 32, 7, 10
RPN_MSB, RPN_LSB, DATA_MSB, DATA_LSB = 101, 100, 6, 38
RPN_NULL = 127


def _cc(channel: int, control: int, value: int) -> mido.Message:
    return mido.Message("control_change", channel=channel, control=control, value=value)


def midi_pan(pan: float) -> int:
    """A stereo position in -1..1 as MIDI pan 0..127 (centre 64)."""
    return max(0, min(127, int(round(64 + pan * 63.5))))


def channel_setup(channel: int, *, pan: float, program: int | None = None, bank: int | None = None,
                  volume: int | None = None, bend_range: float | None = None) -> list[mido.Message]:
    """The messages that put ``channel`` in a creature's voice; ``None`` leaves a setting to
    the synth. Bank select comes before the program change it qualifies (the MIDI rule), and
    the RPN is closed (set to null) after the bend range so a stray data entry changes nothing."""
    def cc(control: int, value: int) -> mido.Message:
        return _cc(channel, control, value)

    messages = []
    if bank is not None:
        messages += [cc(BANK_MSB, bank >> 7), cc(BANK_LSB, bank & 0x7F)]
    if program is not None:
        messages.append(mido.Message("program_change", channel=channel, program=program))
    if volume is not None:
        messages.append(cc(VOLUME, volume))
    messages.append(cc(PAN, midi_pan(pan)))
    if bend_range is not None:
        semitones = int(bend_range)
        cents = int(round((bend_range - semitones) * 100))
        messages += [cc(RPN_MSB, 0), cc(RPN_LSB, 0), cc(DATA_MSB, semitones), cc(DATA_LSB, cents),
                     cc(RPN_MSB, RPN_NULL), cc(RPN_LSB, RPN_NULL)]
    return messages


class CcStream:
    """One ``[[output.cc]]`` stream: a number read from a creature (a drive's level, a body feature) scaled
    from ``range`` to 0..127 and sent as a control change at most ``rate`` times a second,
    and only when its value changed (a synth's filter follows boredom without flooding it)."""

    def __init__(self, channel: int, controller: int, low: float, high: float, rate: float) -> None:
        if high == low:
            raise ValueError("a CC stream's range must not be empty")
        self.channel, self.controller = channel, controller
        self.low, self.high = low, high
        self.every = 1.0 / rate
        self.next = -float("inf")
        self.last: int | None = None

    def value(self, x: float) -> int:
        scaled = (x - self.low) / (self.high - self.low)
        return max(0, min(127, int(round(127 * scaled))))

    def due(self, t: float, x: float) -> mido.Message | None:
        """The message to send at ``t`` for reading ``x``, or None (not due, or unchanged)."""
        if t < self.next:
            return None
        self.next = t + self.every
        value = self.value(x)
        if value == self.last:
            return None
        self.last = value
        return _cc(self.channel, self.controller, value)
