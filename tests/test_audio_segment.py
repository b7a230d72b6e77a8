"""Amplitude-threshold segmentation of heard sound into sound events (audio/segment.py)."""

from __future__ import annotations

import numpy as np
import pytest

from audio.segment import Segmenter, frame_levels_db, segment
from audio.sources import FileSource
from audio_fixtures import SR, Recorder, event_track, noise, recording, silence, tone  # noqa: F401


def test_finds_95_percent_of_100_events_at_20_db_snr(rng: np.random.Generator, record: Recorder) -> None:
    track = event_track(rng, 100, snr_db=20.0)
    seg = Segmenter(SR)
    events = [e for block in FileSource(record(track.samples)) for e in seg.feed(block)]
    events += seg.flush()
    found = np.array([e.start for e in events])
    onset_error = np.abs(found[None, :] - track.onsets[:, None])  # true × found
    hits = (onset_error.min(axis=1) <= 0.020).sum()
    false = (onset_error.min(axis=0) > 0.020).sum()
    assert hits >= 95, f"only {hits}/100 events found with onset within 20 ms"
    assert false <= 5, f"{false} false events among {len(events)}"


def test_streaming_in_odd_blocks_equals_batch(rng: np.random.Generator) -> None:
    track = event_track(rng, 12)
    batch = segment(track.samples, SR)
    seg = Segmenter(SR)
    streamed = []
    cuts = np.cumsum(rng.integers(1, 3000, size=len(track.samples) // 500))
    for block in np.split(track.samples, cuts[cuts < len(track.samples)]):
        streamed += seg.feed(block)
    streamed += seg.flush()
    assert len(streamed) == len(batch) >= 10
    for a, b in zip(streamed, batch):
        assert (a.start, a.end) == (b.start, b.end)
        np.testing.assert_array_equal(a.samples, b.samples)


def test_event_samples_are_the_heard_sound(rng: np.random.Generator) -> None:
    sound = tone(440.0, 0.3)
    x = np.concatenate([noise(1.0, rng, rms=0.001), sound, noise(0.5, rng, rms=0.001)])
    (event,) = segment(x, SR)
    i = round(event.start * SR)
    np.testing.assert_array_equal(event.samples, x[i : i + len(event.samples)].astype(np.float32))
    assert event.duration == pytest.approx(0.3, abs=0.03)
    assert event.level_db == pytest.approx(20 * np.log10(0.1), abs=1.5)


def test_hold_bridges_short_dips_but_not_long_gaps(rng: np.random.Generator) -> None:
    burst = tone(300.0, 0.2)
    bed = lambda d: noise(d, rng, rms=0.001)  # noqa: E731
    x = np.concatenate([bed(1.0), burst, bed(0.04), burst, bed(0.4), burst, bed(0.5)])
    assert len(segment(x, SR, hold=0.08)) == 2  # the 40 ms dip is bridged
    assert len(segment(x, SR, hold=0.01)) == 3


def test_clicks_shorter_than_min_length_are_rejected(rng: np.random.Generator) -> None:
    x = np.concatenate([noise(1.0, rng, rms=0.001), tone(1000.0, 0.02), noise(0.5, rng, rms=0.001)])
    seg = Segmenter(SR, min_length=0.06)
    assert seg.feed(x) + seg.flush() == []
    assert seg.rejected == 1
    assert len(segment(x, SR, min_length=0.01)) == 1


def test_absolute_thresholds_ignore_quiet_sounds(rng: np.random.Generator) -> None:
    quiet, loud = tone(500.0, 0.3, rms=0.003), tone(500.0, 0.3, rms=0.1)  # −50 / −20 dBFS
    x = np.concatenate([silence(0.5), quiet, silence(0.5), loud, silence(0.5)])
    events = segment(x, SR, adaptive=False, floor_db=-45.0, on_db=10.0, off_db=5.0)
    assert [round(e.start, 1) for e in events] == [1.3]


def test_adaptive_floor_lets_a_steady_drone_fade_into_background(rng: np.random.Generator) -> None:
    x = np.concatenate([noise(1.0, rng, rms=0.001), tone(220.0, 12.0, rms=0.05)])
    events = segment(x, SR, floor_window=2.0, max_length=20.0)
    assert len(events) == 1 and events[0].duration < 3.0


def test_max_length_cuts_long_sounds_into_several_events() -> None:
    x = np.concatenate([silence(0.2), tone(220.0, 6.0), silence(0.2)])
    events = segment(x, SR, adaptive=False, floor_db=-60.0, max_length=2.0)
    assert len(events) == 3
    assert all(e.duration <= 2.0 + 1e-9 for e in events)


def test_level_saliency_flows_through_the_hearing_state_object(rng: np.random.Generator) -> None:
    x = np.concatenate([noise(1.0, rng, rms=0.001), tone(440.0, 0.5), noise(1.0, rng, rms=0.001)])
    seg = Segmenter(SR, t0=10.0)
    seg.feed(x)
    assert seg.hearing.saliency_at(11.25) > 1.0  # during the tone: above the on threshold
    assert seg.hearing.saliency_at(12.2) < 0.5  # the quiet bed after it
    assert seg.hearing.times[-1] == pytest.approx(10.0 + len(x) // 256 * 256 / SR)


def test_frame_levels_are_rms_in_dbfs() -> None:
    x = np.concatenate([np.full(256, 0.5), np.zeros(256), np.full(100, 1.0)])
    np.testing.assert_allclose(frame_levels_db(x, 256), [20 * np.log10(0.5), -100.0])


def test_hysteresis_needs_on_above_off() -> None:
    with pytest.raises(ValueError, match="hysteresis"):
        Segmenter(SR, on_db=3.0, off_db=6.0)
