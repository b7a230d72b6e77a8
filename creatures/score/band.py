"""The score's parts as the creature's own sound hears them: one voice a part, its brightness
and level following the controllers the score sends (thesis, "(void *)": "a character's
stance towards the user's control is connected to the timbre of the characters' music";
"thematic balance is biased to take into account what characters are visible on screen").

Out through MIDI a part's stance is a General MIDI program and CC 74, its visibility CC 11, and
the synth the MIDI drives renders them. ``out.wav`` (and live audio) is the creature's scanned
strings, which have no General MIDI patches, so each part gets a voice of its own built from the
creature's ``[creature.voice]`` and hears the same controllers at the same times:

- CC 74 (brightness) moves the part's low-pass: ``bright_hz × 2^((value − 64) / 32)``, so the
  stance's 20…120 spans about three octaves of cutoff (a reluctant character sounds dark, an
  opened-up one bright). ``bright_hz`` is the voice's own, or :data:`BRIGHT_HZ` when it has none.
- CC 11 (expression) scales the part's level by ``(value / 127)²``, the General MIDI curve
  (40·log10(v/127) dB), so an unseen character's theme sits back as it does through a synth.

The program choice itself (the glad or reluctant instrument) stays MIDI only: the brightness is
what the strings can carry of it.
"""

from __future__ import annotations

import heapq
import itertools

import numpy as np

from creatures.kinds.parts import Voice, VoiceSpec
from creatures.score.spec import ScorePartSpec

BRIGHT_HZ = 2500.0
"""Hz: a part's low-pass at CC 74 = 64 when the creature's voice names no ``bright_hz``."""

BRIGHTNESS, EXPRESSION = 74, 11
"""The controllers a part's sound follows."""


class PartVoices:
    """A voice per part (by channel), following its CC 74 and CC 11 from the time they are due."""

    def __init__(self, spec: VoiceSpec, parts: dict[str, ScorePartSpec]) -> None:
        self.spec = spec.model_copy(update={"bright_hz": spec.bright_hz or BRIGHT_HZ})
        self.channels = sorted({part.channel for part in parts.values()})
        self.voices: dict[int, Voice] = {}
        self.levels = {channel: {BRIGHTNESS: 64, EXPRESSION: 127} for channel in self.channels}
        self._due: list[tuple[float, int, int, int, int]] = []  # (time, order, channel, control, value)
        self._order = itertools.count()
        self._gains = {channel: 1.0 for channel in self.channels}  # gain at the end of the last block
        self._scratch = np.zeros(0, np.float32)

    def control(self, at: float, channel: int, control: int, value: int) -> None:
        """A controller the score sends for time ``at``; the part's sound follows it from then."""
        if channel in self.levels and control in (BRIGHTNESS, EXPRESSION):
            heapq.heappush(self._due, (at, next(self._order), channel, control, value))

    def play(self, pitch: int, velocity: int, end: float, channel: int) -> bool:
        """Sound a note on its part's voice; False when ``channel`` is no part's. (Before the
        first block has made the voices, a note is not sounded, as the creature's own voice.)"""
        if channel not in self.levels:
            return False
        if self.voices:
            self.voices[channel].play(pitch, velocity, end)
        return True

    def render(self, out: np.ndarray, t: float, sample_rate: int) -> None:
        """Add every part's voice up to clock time ``t`` to ``out``."""
        if not self.voices:
            self.voices = {channel: Voice(self.spec, sample_rate) for channel in self.channels}
        while self._due and self._due[0][0] <= t:
            _, _, channel, control, value = heapq.heappop(self._due)
            self.levels[channel][control] = value
        if len(self._scratch) != len(out):
            self._scratch = np.zeros(len(out), out.dtype)
        for channel, voice in self.voices.items():
            block = self._scratch
            block[:] = 0.0
            levels = self.levels[channel]
            voice.render(block, t, cutoff=2.0 ** ((levels[BRIGHTNESS] - 64) / 32.0))
            gain, was = (levels[EXPRESSION] / 127.0) ** 2, self._gains[channel]
            out += block * (np.linspace(was, gain, len(block), dtype=block.dtype) if gain != was else gain)
            self._gains[channel] = gain
