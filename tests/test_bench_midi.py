"""The MIDI latency benchmark's bookkeeping (bench/midi.py), on made-up runs: compiling is not
measured however long it takes, and a run where every note met a tick still gives its table."""

from __future__ import annotations

import math

import numpy as np

import bench.midi as midi


def fake_runs(monkeypatch, warm_ms: float, ticks: np.ndarray) -> list[int]:
    """:func:`midi._play` made up: the warm-up run (WARM_UP notes) waits ``warm_ms`` for each
    answer, a measured run 1–2 ms; returns the note counts it was asked for."""
    asked: list[int] = []

    def play(rng, total):
        asked.append(total)
        due = 0.5 + 0.01 * np.arange(total)
        latency = np.full(total, warm_ms) if total == midi.WARM_UP else 1.0 + rng.random(total)
        return midi.Played(latency, due, ticks)

    monkeypatch.setattr(midi, "_play", play)
    return asked


def test_a_long_compile_in_the_warm_up_is_not_measured(monkeypatch) -> None:
    asked = fake_runs(monkeypatch, 42_000.0, np.array([[0.0, 0.01], [0.04, 0.05]]))
    rows = {r.name: r for r in midi._latency_rows(np.random.default_rng(0), 500)}
    assert asked == [midi.WARM_UP, 500]
    p99 = next(r for name, r in rows.items() if name.endswith("p99") and name.startswith("MIDI in"))
    assert 1.0 <= p99.value <= 2.0 and p99.passed
    assert next(r.value for name, r in rows.items() if "warm-up" in name) == 42_000.0


def test_every_note_arriving_during_a_tick_gives_no_between_ticks_figure_and_no_crash(monkeypatch) -> None:
    fake_runs(monkeypatch, 1.0, np.array([[0.0, 100.0]]))  # one tick that outlasts every note
    rows = {r.name.strip(): r for r in midi._latency_rows(np.random.default_rng(0), 100)}
    assert math.isnan(rows["p99 of notes arriving between ticks (≤1 ms poll + decision)"].value)
    assert rows["notes arriving while a tick runs (they wait for its end)"].value == 100.0
