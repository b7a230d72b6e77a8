"""Audio across the room: what each listening creature's ear hears of the input and the voices.

Notes cross a room attenuated by the distance law and late by distance/343 s
(:mod:`creatures.room.hearing`); sound does the same. Without a room every ear hears the
input, and with ``[audio] air`` every voice, at full level and at once. In a room each ear
that listens to audio (a creature whose kind hears sound: :attr:`CreatureKind.hears_audio`)
gets instead

    ear_i(t) = law(d_i,in) · input(t − d_i,in / c) + Σ_j gain_j · law(d_ij) · voice_j(t − d_ij / c)

with the input sounding where input notes sound (:meth:`Stage.source_at`: the first tracked
visitor, else ``input_at``, else the listener) and each voice at its creature, its own voice
too (its mouth is nearest: half-duplex hearing keeps it from answering itself). Delays are
whole samples (1/22050 s is 1.6 cm of travel). Voices are known only once the tick has
rendered them, so an ear hears them a tick late, as the room without positions does.

Each source keeps a ring of its recent samples, long enough for the room's diagonal; an ear's
block is gathered from the rings in one compiled pass (listeners × sources × frames), skipping
pairs more than :data:`INAUDIBLE` down.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from creatures.room.hearing import SPEED_OF_SOUND, DistanceLaw

INAUDIBLE = 1e-5
"""Amplitude gain (−100 dB) under which a source is left out of an ear's sum."""


class RoomAir:
    """Rings of the input and the voices, and each listening ear's block gathered from them."""

    def __init__(self, law: DistanceLaw, *, delay: bool, sample_rate: int, voices: int, diagonal: float,
                 longest_block: int) -> None:
        self.law, self.delay, self.sample_rate = law, delay, sample_rate
        self.longest = int(math.ceil(diagonal / SPEED_OF_SOUND * sample_rate)) if delay else 0
        self.capacity = self.longest + 2 * longest_block + 1
        self._input = np.zeros((1, self.capacity), dtype=np.float32)
        self._voices = np.zeros((voices, self.capacity), dtype=np.float32)
        # Samples written so far, begun at one ring's length so no read index is negative.
        self._input_head = self._voices_head = self.capacity

    def hear_input(self, block: np.ndarray | None, frames: int) -> None:
        """This tick's ``frames`` of input (None: silence; a short block is padded with it)."""
        x = np.zeros(frames, dtype=np.float32)
        if block is not None:
            x[: min(len(block), frames)] = block[:frames]
        self._input_head = _write(self._input, self._input_head, x[None, :])

    def hear_voices(self, voices: np.ndarray) -> None:
        """Every creature's voice this tick ``(creatures, frames)``, each at its own gain."""
        self._voices_head = _write(self._voices, self._voices_head, voices.astype(np.float32, copy=False))

    def ears(self, listeners: np.ndarray, positions: np.ndarray, gains: np.ndarray, input_at: np.ndarray,
             hears_input: np.ndarray, frames: int, *, voices: bool) -> np.ndarray:
        """The block ``(len(listeners), frames)`` each listener (creature index) hears now:
        the input from ``input_at`` (where ``hears_input``), and with ``voices`` every voice
        (``gains``: each creature's own level) from where its creature stands."""
        out = np.zeros((len(listeners), frames), dtype=np.float32)
        if not len(listeners):
            return out
        here = positions[listeners]
        d_in = np.hypot(*(here - input_at).T)
        _gather(self._input, self._input_head, (self.law.gain(d_in) * hears_input)[:, None],
                self._samples(d_in)[:, None], out)
        if voices:
            d = np.hypot(here[:, None, 0] - positions[None, :, 0], here[:, None, 1] - positions[None, :, 1])
            _gather(self._voices, self._voices_head, self.law.gain(d) * gains[None, :], self._samples(d), out)
        return out

    def _samples(self, distance: np.ndarray) -> np.ndarray:
        """Whole samples of travel over ``distance`` m (0 with the room's delay off), at most the
        room's diagonal (``input_at`` may stand outside the room)."""
        if not self.delay:
            return np.zeros(distance.shape, dtype=np.int64)
        return np.minimum(np.rint(distance / SPEED_OF_SOUND * self.sample_rate), self.longest).astype(np.int64)


@numba.njit(cache=True, nogil=True)
def _write(ring, head, block):  # pragma: no cover
    """Append ``block`` ``(sources, frames)`` to each source's ring; the new head."""
    capacity = ring.shape[1]
    for s in range(ring.shape[0]):
        for k in range(block.shape[1]):
            ring[s, (head + k) % capacity] = block[s, k]
    return head + block.shape[1]


@numba.njit(cache=True, nogil=True)
def _gather(ring, head, gains, delays, out):  # pragma: no cover
    """``out[l] += Σ_s gains[l, s] · ring[s]`` over the ``frames`` samples ending ``delays[l, s]``
    before ``head``: one pass over every audible listener-source pair."""
    capacity, frames = ring.shape[1], out.shape[1]
    for listener in range(out.shape[0]):
        for s in range(ring.shape[0]):
            g = gains[listener, s]
            if g < INAUDIBLE:
                continue
            start = (head - delays[listener, s] - frames) % capacity
            for k in range(frames):
                out[listener, k] += g * ring[s, (start + k) % capacity]
