"""The block-by-block low-pass (audio/lowpass.py): scipy's Butterworth, in closed form, with
its state carried across blocks."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import butter, lfilter

from audio.lowpass import LowPass, butterworth


@pytest.mark.parametrize("cutoff", [10.0, 100.0, 1000.0, 5000.0, 10_900.0])
def test_the_closed_form_is_scipys_butterworth(cutoff):
    b, a = butter(2, cutoff, fs=22050)
    ours = butterworth(cutoff, 22050)
    assert np.allclose(ours[0], b, atol=1e-12, rtol=0) and np.allclose(ours[1], a, atol=1e-12, rtol=0)


def test_blocks_filter_as_one_signal_and_the_cutoff_is_held_in_range():
    x = np.random.default_rng(0).normal(size=4096)
    whole = lfilter(*butter(2, 800.0, fs=22050), x)
    lowpass = LowPass(22050)
    blocks = np.concatenate([lowpass.run(x[i:i + 441], 800.0) for i in range(0, len(x), 441)])
    assert np.allclose(blocks, whole, atol=1e-12)
    lowpass.set(1e6)
    assert lowpass.cutoff == pytest.approx(0.99 * 11025)
    lowpass.set(-5.0)
    assert lowpass.cutoff == 10.0


def test_a_silent_block_passes_once_the_ringing_has_died():
    lowpass = LowPass(22050)
    tail = lowpass.run(np.r_[1.0, np.zeros(440)], 500.0)
    assert np.abs(tail[1:]).max() > 0  # it rings on after the impulse
    silence = np.zeros(441)
    for _ in range(100):
        out = lowpass.run(silence, 500.0)
    assert out is silence and not out.any()  # died away: passed through, untouched


def test_a_nan_cutoff_keeps_the_last_and_the_filter_sings_on():
    """A NaN cutoff made NaN coefficients and left the state NaN: every block after it NaN (a
    voice's limiter turned that into silence for the rest of the run)."""
    x = np.random.default_rng(1).normal(size=441)
    lowpass = LowPass(22050)
    lowpass.run(x, 800.0)
    assert np.isfinite(lowpass.run(x, float("nan"))).all() and lowpass.cutoff == 800.0
    assert np.isfinite(lowpass.run(x, 800.0)).all()
    fresh = LowPass(22050)
    assert np.isfinite(fresh.run(x, float("nan"))).all() and fresh.cutoff == pytest.approx(0.99 * 11025)
