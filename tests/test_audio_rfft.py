"""audio/rfft.py: hearing's magnitude spectra, taken through pocketfft's own entry point, are
scipy.fft.rfft's bit for bit (so every note heard is the one heard before), with and without
zero-padding, and the public path it falls back on gives the same."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.fft import rfft

from audio import rfft as fast


@pytest.mark.parametrize("shape, n", [((512,), None), ((3, 512), None), ((1, 2048), None), ((2, 1024), 2048),
                                      ((1, 2048), 4096), ((2, 600), 512)])
def test_magnitudes_are_scipys_rfft_bit_for_bit(shape, n, monkeypatch):
    frames = np.random.default_rng(5).standard_normal(shape).astype(np.float32)
    expected = np.abs(rfft(frames, n=n, axis=-1))
    got = fast.magnitudes(frames, n)
    assert fast.r2c is not None  # this scipy has pocketfft's entry point: the fast path was taken
    assert got.dtype == expected.dtype == np.float32 and got.shape == expected.shape
    assert np.array_equal(got, expected)
    monkeypatch.setattr(fast, "r2c", None)  # a scipy that moved it
    assert np.array_equal(fast.magnitudes(frames, n), expected)
