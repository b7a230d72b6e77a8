"""Sampler: stored sounds come back, shaped by the body's amplitude and low-pass."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import butter, lfilter

from audio.sampler import Sampler

SR = 48000
BLOCK = 480


def tone(hz: float, seconds: float = 0.5) -> np.ndarray:
    return 0.5 * np.sin(2 * np.pi * hz * np.arange(int(seconds * SR)) / SR)


def play_all(sampler: Sampler, blocks: int, **controls) -> np.ndarray:
    return np.concatenate([sampler.render(np.empty(BLOCK), **controls).copy() for _ in range(blocks)])


def test_blockwise_filter_matches_one_pass_filtering(rng):
    heard = rng.standard_normal(BLOCK * 10)
    sampler = Sampler(SR, block_size=BLOCK)
    sampler.play(sampler.add(heard))
    sampler.render(np.empty(BLOCK), amplitude=1.0, cutoff_hz=2000.0)  # settle the gain ramp from 0
    rest = play_all(sampler, 9, amplitude=1.0, cutoff_hz=2000.0)
    expected = lfilter(*butter(2, 2000.0, fs=SR), heard)[BLOCK:]
    np.testing.assert_allclose(rest, expected, atol=1e-12)  # state carried across blocks


def test_back_angle_low_pass_darkens_a_bright_sound():
    def level(cutoff):
        sampler = Sampler(SR, block_size=BLOCK)
        sampler.play(sampler.add(tone(5000.0)))
        out = play_all(sampler, 40, amplitude=1.0, cutoff_hz=cutoff)[BLOCK * 10 :]
        return np.sqrt(np.mean(out**2))

    assert 20 * np.log10(level(500.0) / level(15000.0)) < -30.0  # 12 dB/octave, ~3.3 octaves


def test_rib_cage_amplitude_scales_and_ramps_without_steps():
    sampler = Sampler(SR, block_size=BLOCK)
    index = sampler.add(np.full(BLOCK * 4, 0.5))
    sampler.play(index)
    loud = play_all(sampler, 2, amplitude=1.0, cutoff_hz=20000.0)
    assert np.all(np.diff(loud[:BLOCK]) > -1e-9)  # fades in from 0, no jump
    quiet = play_all(sampler, 2, amplitude=0.25, cutoff_hz=20000.0)
    assert quiet[-1] == pytest.approx(0.25 * loud[-1], rel=1e-3)
    assert np.abs(np.diff(np.r_[loud, quiet])).max() < 0.01  # the change is spread over a block


def test_sounds_overlap_then_finish():
    sampler = Sampler(SR, block_size=BLOCK)
    a, b = sampler.add(tone(440.0, 0.02)), sampler.add(tone(660.0, 0.05))
    sampler.play(a)
    sampler.play(b, gain=0.5)
    assert len(sampler.playing) == 2
    play_all(sampler, 3, amplitude=1.0)
    assert len(sampler.playing) == 1  # the 20 ms sound ended
    play_all(sampler, 3, amplitude=1.0)
    assert not sampler.playing


def test_bad_sounds_and_indices_are_refused():
    sampler = Sampler(SR)
    with pytest.raises(ValueError, match="non-empty finite mono"):
        sampler.add(np.array([0.0, np.nan]))
    with pytest.raises(IndexError, match="no stored sound 0"):
        sampler.play(0)


def test_at_most_max_playing_sound_at_once_the_oldest_fading_out():
    """Every overlapping play stayed for good: a creature asked to sing back faster than its
    sounds end mixed more of them each block. Past MAX_PLAYING the oldest fades out over the
    next block (no click), and the rest play on."""
    from audio.sampler import MAX_PLAYING

    def sampler_playing(which: list[int]) -> Sampler:
        sampler = Sampler(SR, block_size=BLOCK)
        for k in range(MAX_PLAYING + 8):
            sampler.add(tone(110.0 * (1 + k % 7), 1.0))
        sampler.render(np.empty(BLOCK), amplitude=1.0)  # settle the gain ramp from 0
        for k in which:
            sampler.play(k, gain=1.0 / MAX_PLAYING)
        return sampler

    every = list(range(MAX_PLAYING + 8))
    crowded, kept = sampler_playing(every), sampler_playing(every[8:])
    crowded_block, kept_block = play_all(crowded, 1, amplitude=1.0), play_all(kept, 1, amplitude=1.0)
    assert len(crowded.playing) == MAX_PLAYING and [v[0] for v in crowded.playing] == every[8:]
    faded = crowded_block - kept_block  # the eight stolen, through the same (linear) filter
    assert np.abs(faded[:BLOCK // 4]).max() > 0.02  # they sounded as the block began...
    assert np.abs(faded[-8:]).max() < 0.002  # ...and are gone by its end: the next block joins on
    np.testing.assert_allclose(play_all(crowded, 2, amplitude=1.0), play_all(kept, 2, amplitude=1.0), atol=0.01)
