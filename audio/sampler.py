"""Sampler: soundcreatures sing back what they heard (thesis *soundcreatures*).

"Without phase information we couldn't reconstruct model samples perfectly. So here we cheat
and also keep the raw samples around": the percept trees classify heard sounds, and the raw
audio is kept here to be played back. It is the creature's *body* that produces the sound —
"labelled positions on the animated body control parameters such as amplitude modulation
(e.g. rib cage) and a simple low-pass filter (e.g. here, back angle)" — so :meth:`render`
takes an ``amplitude`` and a ``cutoff_hz`` each block, typically from
:class:`audio.coupling.BodyControl`.

The low-pass is :class:`audio.lowpass.LowPass` (a 2nd-order Butterworth with its state carried
from block to block, so block boundaries are inaudible); the amplitude ramps linearly across a
block from the previous value, so body movement does not zipper.
"""

from __future__ import annotations

import numpy as np

from audio.lowpass import LowPass

MAX_PLAYING = 32
"""Most sounds a sampler plays at once, as a voice pool's polyphony is (:mod:`audio.voices`):
past it the oldest fades out over the next block. Each overlapping :meth:`Sampler.play` added
one more for good, so a creature asked to sing back faster than its sounds end mixed more of
them each block, its cost per block growing with the asking."""


class Sampler:
    """Stored sounds, played (overlapping) through one body-driven gain and low-pass.

    Parameters
    ----------
    sample_rate : float
        Rate of stored sounds and output.
    block_size : int
        Largest block :meth:`render` will be asked for.
    """

    def __init__(self, sample_rate: float = 48000.0, *, block_size: int = 1024) -> None:
        self.sample_rate = float(sample_rate)
        self.sounds: list[np.ndarray] = []
        self.playing: list[list] = []  # [sound index, next frame, gain, stolen (fades out this block)]
        self._free: list[int] = []  # slots of sounds let go, taken by the next ones added
        self._mix = np.zeros(block_size)
        self._amplitude = 0.0
        self._lowpass = LowPass(self.sample_rate)

    def add(self, sound: np.ndarray) -> int:
        """Keep a heard sound (mono, at ``sample_rate``); returns its index for :meth:`play`."""
        sound = np.asarray(sound, dtype=float)
        if sound.ndim != 1 or not len(sound) or not np.isfinite(sound).all():
            raise ValueError(f"a sound must be a non-empty finite mono array, got shape {sound.shape}")
        if self._free:
            index = self._free.pop()
            self.sounds[index] = sound
            return index
        self.sounds.append(sound)
        return len(self.sounds) - 1

    def forget(self, index: int) -> None:
        """Let stored sound ``index`` go (a long run hears without end; what it keeps must not
        grow with it); its slot is taken by the next :meth:`add`. Not while it plays."""
        if any(voice[0] == index for voice in self.playing):
            raise ValueError(f"stored sound {index} is playing")
        if 0 <= index < len(self.sounds) and len(self.sounds[index]):
            self.sounds[index] = np.zeros(0)
            self._free.append(index)

    def play(self, index: int, *, gain: float = 1.0) -> None:
        """Start sound ``index`` from its beginning (several may overlap, :data:`MAX_PLAYING`
        at most: the oldest sounding fades out to make room)."""
        if not 0 <= index < len(self.sounds) or not len(self.sounds[index]):
            raise IndexError(f"no stored sound {index} (have {len(self.sounds) - len(self._free)})")
        sounding = [v for v in self.playing if not v[3]]
        if len(sounding) >= MAX_PLAYING:
            sounding[0][3] = True
        self.playing.append([index, 0, float(gain), False])

    def render(self, out: np.ndarray, *, amplitude: float = 1.0, cutoff_hz: float = 20000.0) -> np.ndarray:
        """Mix the playing sounds into ``out`` through the body's gain and low-pass."""
        frames = len(out)
        if frames > len(self._mix):
            raise ValueError(f"block of {frames} frames exceeds block_size {len(self._mix)}")
        mix = self._mix[:frames]
        mix[:] = 0.0
        fade = None
        for voice in self.playing:
            sound = self.sounds[voice[0]]
            part = sound[voice[1] : voice[1] + frames]
            if voice[3]:  # stolen: faded to nothing across this block, no click
                fade = np.linspace(1.0, 0.0, frames) if fade is None else fade
                part = part * fade[: len(part)]
            mix[: len(part)] += voice[2] * part
            voice[1] += frames
        self.playing = [v for v in self.playing if v[1] < len(self.sounds[v[0]]) and not v[3]]
        filtered = self._lowpass.run(mix, cutoff_hz)
        ramp = np.arange(1, frames + 1) / frames
        out[:] = filtered * (self._amplitude + (amplitude - self._amplitude) * ramp)
        self._amplitude = amplitude
        return out
