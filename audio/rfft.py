"""Magnitude spectra for hearing's per-hop transforms, without scipy.fft's dispatch around them.

A live input's block is one hop, and each hop takes three to five real FFTs of 512–4096 samples
(audio/logspectrum.py, audio/onset_ear.py): 5–24 µs of pocketfft's work each, around which
``scipy.fft.rfft`` spent ~10 µs a call more (its backend dispatch and argument checks), about a
tenth of the live look's time on the machine of 2026-12-07. So pocketfft's own entry point, the
one ``scipy.fft.rfft`` ends in, is called directly where this scipy has it (every scipy since
1.4), and the public ``rfft`` otherwise: the same transform, bit for bit (tests/test_audio_rfft.py).
"""

from __future__ import annotations

import numpy as np
from scipy.fft import rfft

try:
    from scipy.fft._pocketfft.pypocketfft import r2c
except ImportError:  # a scipy that moved it: the public path, slower by its dispatch
    r2c = None


def magnitudes(frames: np.ndarray, n: int | None = None) -> np.ndarray:
    """``|rfft(frames, n, axis=-1)|``: each row's magnitude spectrum, zero-padded to ``n`` samples."""
    if r2c is None:
        return np.abs(rfft(frames, n=n, axis=-1))
    if n is not None and n != frames.shape[-1]:
        padded = np.zeros((*frames.shape[:-1], n), dtype=frames.dtype)
        padded[..., :min(n, frames.shape[-1])] = frames[..., :n]
        frames = padded
    return np.abs(r2c(frames, (frames.ndim - 1,), True, 0, None, 1))
