"""A benchmark whose peer or parts are missing says "skipped" and why, with no number (NaN),
never a 0 that a later ``--compare`` or a reader would take for a measurement; and a peer is
timed as often as ours, so neither side's first, cold run is the one compared."""

from __future__ import annotations

import math

import numpy as np
import pytest

import audio.transcribe
import bench.hearing as hearing
import bench.live as live
import bench.live_hearing as live_hearing
from bench.live_hearing import Heard


def assert_skipped(row, why: str) -> None:
    assert "skipped" in row.name and why in row.name, row.name
    assert math.isnan(row.value) and row.target is None and row.passed is None


class FakeEar:
    """A transcriber that hears nothing, counting the whole streams it was given per look."""

    streamed: dict[tuple[int, str], int] = {}

    def __init__(self, rate: int, look: str, ears=None) -> None:
        self.rate, self.look, self.ended, self.latency = rate, look, [], 0.05

    def feed(self, block: np.ndarray) -> list:
        return []

    def flush(self) -> None:
        key = (self.rate, self.look)
        FakeEar.streamed[key] = FakeEar.streamed.get(key, 0) + 1


@pytest.fixture
def fake_transcription(monkeypatch):
    """The transcription rows over silence with :class:`FakeEar`; returns the peer's timed runs."""
    FakeEar.streamed = {}
    peer_runs: list[int] = []

    def peer(session, mono, rate):
        if rate == 44100:  # the timed run over the 44.1 kHz piano, not the F1 table's
            peer_runs.append(rate)
        return []

    monkeypatch.setattr(hearing, "have_sampler", lambda: True)
    monkeypatch.setattr(hearing, "render", lambda notes, instrument, rate: np.zeros((rate // 10, 2), np.float32))
    monkeypatch.setattr(hearing, "note_f1", lambda reference, estimated: 0.5)
    monkeypatch.setattr(hearing, "given_times", lambda ear, mono, rate: [])
    monkeypatch.setattr(audio.transcribe, "Transcriber", FakeEar)
    monkeypatch.setattr(hearing, "_basic_pitch_session", lambda: (object(), ""))
    monkeypatch.setattr(hearing, "basic_pitch_notes", peer)
    return peer_runs


def test_transcription_without_a_sampler_is_skipped_not_zero(monkeypatch) -> None:
    monkeypatch.setattr(hearing, "have_sampler", lambda: False)
    [row] = hearing._transcription_rows(quick=True)
    assert_skipped(row, "fluidsynth")


def test_a_missing_basic_pitch_is_a_skipped_row_saying_how_to_install_it(fake_transcription, monkeypatch) -> None:
    monkeypatch.setattr(hearing, "_basic_pitch_session", lambda: (None, "not installed: pip install basic-pitch"))
    rows = hearing._transcription_rows(quick=True)
    assert_skipped(rows[-1], "pip install basic-pitch")
    assert all(math.isfinite(r.value) for r in rows[:-1])
    offline = next(r for r in rows if "offline look" in r.name and r.unit == "× real time")
    assert offline.ratio is None  # nothing to compare with


def test_basic_pitch_is_timed_as_often_as_our_offline_look(fake_transcription) -> None:
    rows = hearing._transcription_rows(quick=False)
    ours = FakeEar.streamed[(44100, audio.transcribe.OFFLINE)]
    assert ours == 2 and len(fake_transcription) == ours
    offline = next(r for r in rows if "offline look" in r.name and r.unit == "× real time")
    assert offline.baseline == "basic-pitch ONNX" and offline.ratio is not None


def test_live_without_jack_says_why_in_the_table(monkeypatch) -> None:
    monkeypatch.setattr(live, "missing_parts", lambda: "no JACK server running")
    [row] = live.run(quick=True)
    assert_skipped(row, "no JACK server running")


def test_live_hearing_without_jack_is_skipped_not_zero(monkeypatch) -> None:
    monkeypatch.setattr(live_hearing, "jack_available", lambda: "no JACK server")
    [row] = live_hearing.run(quick=True)
    assert_skipped(row, "no JACK server")


def test_live_hearing_answering_nothing_fails_instead_of_reading_0_ms(monkeypatch) -> None:
    monkeypatch.setattr(live_hearing, "jack_available", lambda: None)
    monkeypatch.setattr(live_hearing, "measure", lambda onsets, look: Heard([], list(range(onsets)), ""))
    rows = live_hearing.run(quick=True)
    assert [r.passed for r in rows] == [False, False]
    assert all(r.unit != "ms" for r in rows)
