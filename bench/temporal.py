"""Temporal models: how fast the low-integer-ratio duration model hears and generates
durations (targets ≥ 100,000/s each). The scalar paths (``update``, ``sample``) are measured
beside the batch paths (``update_many``, ``sample_many``), which compute the same thing."""

from __future__ import annotations

import numpy as np

from bench import Row, best_of
from creatures.temporal.durations import LowIntegerRatioModel

NOTES = np.array([1.0, 0.5, 2.0, 1.5])


def _rhythm(n: int, rng: np.random.Generator) -> np.ndarray:
    """Quarters, eighths, halves and dotted quarters at 100 BPM, ±5 % jitter, a tempo change
    to 130 BPM half way (so the re-anchoring path is in the measurement too)."""
    beats = NOTES[rng.choice(NOTES.size, size=n, p=[0.4, 0.3, 0.15, 0.15])]
    tempo = np.where(np.arange(n) < n // 2, 0.6, 60.0 / 130.0)
    return beats * tempo * rng.uniform(0.95, 1.05, n)


def run(quick: bool) -> list[Row]:
    rng = np.random.default_rng(0)
    n_batch, n_scalar = (20_000, 2_000) if quick else (200_000, 20_000)
    stream = _rhythm(n_batch, rng)
    trained = LowIntegerRatioModel()
    trained.update_many(stream[:2000])

    batch = best_of(lambda: LowIntegerRatioModel().update_many(stream))

    def scalar_updates() -> None:
        model = LowIntegerRatioModel()
        for d in stream[:n_scalar]:
            model.update(d)

    scalar = best_of(scalar_updates)
    sample_batch = best_of(lambda: trained.sample_many(rng, n_batch))

    def scalar_samples() -> None:
        for _ in range(n_scalar):
            trained.sample(rng)

    sample_scalar = best_of(scalar_samples)
    return [
        Row("durations added/s (update_many)", n_batch / batch, "1/s", target=100_000),
        Row("durations added/s (update, scalar)", n_scalar / scalar, "1/s"),
        Row("samples drawn/s (sample_many)", n_batch / sample_batch, "1/s", target=100_000),
        Row("samples drawn/s (sample, scalar)", n_scalar / sample_scalar, "1/s", target=100_000),
    ]
