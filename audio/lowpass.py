"""A low-pass run block by block: a 2nd-order Butterworth whose state carries across blocks,
so block boundaries and cutoff changes are inaudible (the filter is redesigned only when the
cutoff moves, and keeps its state through the change). The design is the closed form of the
bilinear transform with the cutoff prewarped (Q = 1/√2: the RBJ cookbook's low-pass), the same
coefficients :func:`scipy.signal.butter` gives to 1e-12 at ~1/200 of its cost, since a cutoff
a drive moves is redesigned every block.

Used where a voice's brightness is a body's or a skill's to set: the soundcreatures' mouth
(thesis "soundcreatures": "a simple low-pass filter (e.g. here, back angle)",
:mod:`audio.sampler`) and the scanned strings of a creature whose timbre follows its drives
(thesis "sand:stone": "timbre is modulated directly by the boredom model",
:class:`creatures.kinds.parts.Voice`).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.signal import lfilter

LOWEST_HZ = 10.0
"""The lowest cutoff taken (a cutoff asked lower is held here)."""

AT_REST = 1e-9
"""The filter's state below which its ringing has died (−180 dB)."""


def butterworth(cutoff_hz: float, sample_rate: float) -> tuple[np.ndarray, np.ndarray]:
    """``(b, a)`` of the 2nd-order Butterworth low-pass at ``cutoff_hz`` (a0 = 1)."""
    w = 2.0 * math.pi * cutoff_hz / sample_rate
    cos, alpha = math.cos(w), math.sin(w) / math.sqrt(2.0)  # sin(w) / (2Q), Q = 1/√2
    a0 = 1.0 + alpha
    b0 = (1.0 - cos) / 2.0 / a0
    return np.array([b0, 2.0 * b0, b0]), np.array([1.0, -2.0 * cos / a0, (1.0 - alpha) / a0])


class LowPass:
    """A 2nd-order Butterworth low-pass of one channel at ``sample_rate``."""

    def __init__(self, sample_rate: float) -> None:
        self.sample_rate = float(sample_rate)
        self.cutoff: float | None = None
        self._ba: tuple[np.ndarray, np.ndarray] | None = None
        self._zi: np.ndarray | None = None

    def set(self, cutoff_hz: float) -> None:
        """Move the cutoff (held to [:data:`LOWEST_HZ`, 0.99 × Nyquist]; a NaN keeps the cutoff
        it had: its coefficients would be NaN, and the state they left NaN for good, so one NaN
        from a drive silenced the voice for the rest of the run)."""
        if math.isnan(cutoff_hz):
            if self.cutoff is not None:
                return
            cutoff_hz = 0.5 * self.sample_rate  # nothing to keep yet: open
        cutoff = min(max(float(cutoff_hz), LOWEST_HZ), 0.99 * 0.5 * self.sample_rate)
        if cutoff == self.cutoff:
            return
        self._ba, self.cutoff = butterworth(cutoff, self.sample_rate), cutoff
        if self._zi is None:  # the filter starts at rest
            self._zi = np.zeros(2)

    @property
    def resting(self) -> bool:
        """Whether the filter's ringing has died (below :data:`AT_REST`): silence in is silence out."""
        return self._zi is None or float(np.abs(self._zi).max()) < AT_REST

    def run(self, block: np.ndarray, cutoff_hz: float) -> np.ndarray:
        """``block`` (frames) through the filter at ``cutoff_hz``. A silent block after the
        filter's ringing has died (below :data:`AT_REST`) is passed through as it is: a
        voice that sings now and then filters only while it sounds."""
        if self._zi is not None and not block.any() and self.resting:
            return block
        self.set(cutoff_hz)
        filtered, self._zi = lfilter(*self._ba, block, zi=self._zi)
        return filtered
