"""Temporal models: how fast the low-integer-ratio duration model hears and generates
durations (issue target: ≥ 100,000/s each, for both entry points of each).

One duration at a time (``update``, ``sample``) is how a Du uses the model — ``DoUntil``
samples it when a tuple starts and teaches it when the tuple ends — so those scalar paths
carry the target as much as the batch paths (``update_many``, ``sample_many``) that
listeners feed whole onset streams through. Models are heard from fresh, so the first
anchoring, the young model's level checks and a tempo change are all in the measurement.
A last row, without a target, times a whole Du activation (a sample, then an update), where
each call finds the other's change and recomputes what it caches.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from bench import Row, best_of
from creatures.temporal.durations import LowIntegerRatioModel

NOTES = np.array([1.0, 0.5, 2.0, 1.5])
TARGET = 100_000


def _rhythm(n: int, rng: np.random.Generator) -> np.ndarray:
    """Quarters, eighths, halves and dotted quarters at 100 BPM, ±5 % jitter, a tempo change
    to 130 BPM half way (so the re-anchoring path is in the measurement too)."""
    beats = NOTES[rng.choice(NOTES.size, size=n, p=[0.4, 0.3, 0.15, 0.15])]
    tempo = np.where(np.arange(n) < n // 2, 0.6, 60.0 / 130.0)
    return beats * tempo * rng.uniform(0.95, 1.05, n)


def _per_second(n: int, fn: Callable[[], object]) -> float:
    return n / best_of(fn)


def run(quick: bool) -> list[Row]:
    rng = np.random.default_rng(0)
    n = 20_000 if quick else 200_000
    stream = _rhythm(n, rng)
    scalar_stream = stream.tolist()  # Python floats, as DoUntil.end passes them
    trained = LowIntegerRatioModel()
    trained.update_many(stream[:2000])

    def updates() -> None:
        update = LowIntegerRatioModel().update
        for d in scalar_stream:
            update(d)

    def samples() -> None:
        sample = trained.sample
        for _ in range(n):
            sample(rng)

    def activations() -> None:
        model = LowIntegerRatioModel()
        for d in scalar_stream:
            model.sample(rng)
            model.update(d)

    return [
        Row("durations added/s (update, one at a time)", _per_second(n, updates), "1/s", target=TARGET),
        Row("durations added/s (update_many)", _per_second(n, lambda: LowIntegerRatioModel().update_many(stream)), "1/s", target=TARGET),
        Row("samples drawn/s (sample, one at a time)", _per_second(n, samples), "1/s", target=TARGET),
        Row("samples drawn/s (sample_many)", _per_second(n, lambda: trained.sample_many(rng, n)), "1/s", target=TARGET),
        Row("Du activations/s (sample, then update)", _per_second(n, activations), "1/s"),
    ]
