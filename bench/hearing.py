"""Hearing: offline analysis speed of a creature's ear (segmentation + cepstra + DTW against
50 templates) as a multiple of real time on a synthetic recording, with librosa's bare MFCC
over the same audio as the anchor; and the numba DTW kernel against librosa.sequence.dtw.

Everything is timed under :func:`bench.voice.one_core`: the target is "≥ 100× real time on
one core", and the anchor ratio compares like with like only if librosa's MFCC (whose mel
projection would otherwise use threaded BLAS) gets the same single core as the ear."""

from __future__ import annotations

import time

import librosa
import numpy as np

from audio.cepstrum import cepstra, distances_to, dtw_cost
from audio.formants import SAMPLE_RATE as SR
from audio.formants import WORDS, word
from audio.segment import segment
from bench import Row, best_of
from bench.voice import one_core


def recording(
    seconds: float, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Words at random gaps over a 20 dB SNR noise bed: the signal, onsets (s), word indices."""
    x = 0.005 * rng.standard_normal(int(seconds * SR))  # the noise bed
    t, onsets, labels = 0.5, [], []
    while True:
        k = int(rng.integers(len(WORDS)))
        w = word(WORDS[k], rng, stretch=rng.uniform(0.8, 1.25), f0=rng.uniform(100, 160), rms=0.05)
        i = int(t * SR)
        if i + len(w) >= len(x):
            return x.astype(np.float32), np.array(onsets), np.array(labels)
        x[i : i + len(w)] += w
        onsets.append(t)
        labels.append(k)
        t += len(w) / SR + rng.uniform(0.25, 0.7)


def _hearing_rows(quick: bool) -> list[Row]:
    seconds = 60.0 if quick else 600.0
    rng = np.random.default_rng(7)
    x, onsets, labels = recording(seconds, rng)
    templates = [cepstra(word(WORDS[k % 5], rng), SR) for k in range(50)]
    heard: list[tuple[float, int]] = []  # (event start, word of the nearest template)

    def hear() -> None:
        heard.clear()
        for event in segment(x, SR):
            nearest = int(np.argmin(distances_to(cepstra(event.samples, SR), templates)))
            heard.append((event.start, nearest % 5))

    def bare_mfcc() -> None:
        librosa.feature.mfcc(y=x, sr=SR, n_mfcc=13)

    hear()  # warm numba and librosa
    bare_mfcc()
    t_hear = best_of(hear, repeat=1 if not quick else 2)
    t_mfcc = best_of(bare_mfcc)
    speed, anchor = seconds / t_hear, seconds / t_mfcc
    said = [labels[np.argmin(np.abs(onsets - start))] for start, _ in heard]
    recognised = np.mean([k == w for k, (_, w) in zip(said, heard)])
    return [
        Row(f"ear on {seconds / 60:g} min ({len(heard)} events/{len(onsets)} words, 50 templates)",
            speed, "× real time", target=100.0, baseline="bare librosa MFCC",
            ratio=speed / anchor),
        Row("bare librosa MFCC, same audio (anchor)", anchor, "× real time"),
        Row("words recognised by the ear (sanity check)", 100 * recognised, "%", target=95.0),
    ]


def _dtw_rows(quick: bool) -> list[Row]:
    rng = np.random.default_rng(8)
    a, b = rng.standard_normal((200, 13)), rng.standard_normal((200, 13))
    pairs = 20 if quick else 100
    dtw_cost(a, b)
    librosa.sequence.dtw(X=a.T, Y=b.T)

    def ours() -> None:
        for _ in range(pairs):
            dtw_cost(a, b)

    def theirs() -> None:
        for _ in range(pairs):
            librosa.sequence.dtw(X=a.T, Y=b.T)

    fast, slow = best_of(ours) / pairs, best_of(theirs) / pairs
    return [
        Row("DTW 200×13 vs 200×13 (numba kernel)", fast * 1e3, "ms", higher_is_better=False,
            baseline="librosa.sequence.dtw", ratio=slow / fast),
        Row("DTW 200×13 vs 200×13 (librosa.sequence.dtw)", slow * 1e3, "ms"),
    ]


def run(quick: bool) -> list[Row]:
    t0 = time.perf_counter()
    with one_core():
        rows = _dtw_rows(quick) + _hearing_rows(quick)
    rows.append(Row("benchmark wall time", time.perf_counter() - t0, "s"))
    return rows
