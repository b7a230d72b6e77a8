"""Mixer for a colony: each creature's mono voice, with gain and pan, summed to stereo.

Several creatures share one loudspeaker pair (thesis *exchange*, *soundcreatures* played
"together"). The mix is one matrix product ``(frames, sources) @ (sources, 2)`` written
into a buffer allocated once, so mixing a block allocates nothing. Pan is equal-power
(−3 dB in the centre) so a creature keeps its loudness as it moves across the stereo field.

Each voice is soft-limited (:func:`audio.scanned.soft_limit`), but their sum, times the
creatures' gains, is not: past full scale the file (libsndfile) and the sound card clip it
hard. The mixer counts those samples (:attr:`Mixer.clipped`) and keeps the loudest
(:attr:`Mixer.peak`), so a run says it clipped rather than distorting without a word.
"""

from __future__ import annotations

import numpy as np


class Mixer:
    """``n_sources`` mono inputs → stereo, with per-source ``gain`` and ``pan`` (−1 left … +1 right).

    Example
    -------
    >>> mixer = Mixer(2, block_size=256)
    >>> mixer.set(0, gain=0.5, pan=-1.0)
    >>> stereo = mixer.mix(np.zeros((2, 256)))  # (256, 2), a view of the mixer's buffer
    """

    def __init__(self, n_sources: int, *, block_size: int = 1024, channels: int = 2) -> None:
        if n_sources < 1 or block_size < 1 or channels < 2:
            raise ValueError(f"need n_sources ≥ 1, block_size ≥ 1 and channels ≥ 2, got "
                             f"{n_sources}, {block_size}, {channels}")
        self.gains = np.ones(n_sources)
        self.pans = np.zeros(n_sources)
        self._placed = np.zeros(n_sources, dtype=bool)  # rows set by place(), not by gain and pan
        self._weights = np.zeros((n_sources, channels))
        self._out = np.zeros((block_size, channels))
        self.clipped = 0
        """Samples (all channels) of the mix beyond full scale (±1), which the output clips."""
        self.peak = 0.0
        """The largest magnitude the mix reached."""
        self._update_weights()

    def set(self, source: int, *, gain: float | None = None, pan: float | None = None) -> None:
        """Change one source's gain (linear, ≥ 0) and/or pan (clamped to [−1, 1])."""
        if gain is not None:
            if not gain >= 0:
                raise ValueError(f"gain must be ≥ 0, got {gain!r}")
            self.gains[source] = gain
        if pan is not None:
            self.pans[source] = min(max(pan, -1.0), 1.0)
        self._update_weights()

    def place(self, source: int, weights: np.ndarray) -> None:
        """Set one source's gain on every output channel at once (a creature in a room,
        panned by its position over a stereo pair or a ring: creatures/room/speakers.py)."""
        self._weights[source] = self._gains_of(weights, (self._weights.shape[1],))
        self._placed[source] = True

    def place_all(self, weights: np.ndarray) -> None:
        """:meth:`place` every source at once, ``weights`` ``(n_sources, channels)``: a room
        places every creature every tick, and one array assignment costs what one of 200
        calls did."""
        self._weights[:] = self._gains_of(weights, self._weights.shape)
        self._placed[:] = True

    def _gains_of(self, weights: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
        weights = np.asarray(weights, dtype=float)
        if weights.shape != shape or not (weights >= 0).all():
            raise ValueError(f"weights must be {shape} gains ≥ 0, got {weights!r}")
        return weights

    def _update_weights(self) -> None:
        angle = (self.pans + 1.0) * (np.pi / 4.0)
        free = ~self._placed
        self._weights[free, 0] = self.gains[free] * np.cos(angle[free])
        self._weights[free, 1] = self.gains[free] * np.sin(angle[free])

    def mix(self, blocks: np.ndarray) -> np.ndarray:
        """Sum ``blocks`` ``(n_sources, frames)`` into the output buffer; returns ``(frames, channels)``."""
        sources, frames = blocks.shape
        if sources != len(self.gains) or frames > len(self._out):
            raise ValueError(
                f"blocks must be ({len(self.gains)}, ≤{len(self._out)}), got {blocks.shape}"
            )
        out = self._out[:frames]
        np.matmul(blocks.T, self._weights, out=out)
        if frames:
            loudest = max(out.max(), -out.min())  # no temporary array unless it is over
            if loudest > self.peak:
                self.peak = float(loudest)
            if loudest > 1.0:
                self.clipped += int(np.count_nonzero(np.abs(out) > 1.0))
        return out
