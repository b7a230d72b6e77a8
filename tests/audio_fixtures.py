"""Synthetic sounds for the hearing tests: tones, chirps, vowel-like formant bursts, "words",
noise and silence, plus event tracks with known onsets. Everything is generated in code from
seeded RNGs, so no test depends on a recording or a download. The ``record`` fixture
(:func:`recording`) writes a synthesised signal as a WAV file, so a test hears it the way an
installation hears a recording: through :mod:`audio.sources`."""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import numpy as np
import pytest
import soundfile
from scipy import signal

# The speech-like generators live in the library (installations use them too); re-exported.
from audio.formants import SAMPLE_RATE, VOWELS, WORDS, envelope, formant_burst, normalise, word  # noqa: F401

SR = SAMPLE_RATE


@pytest.fixture(scope="session")
def warm_librosa() -> None:
    """librosa and the DTW kernel JIT-compile on first use (~15 s cold, a few seconds from
    numba's cache): pay it once, before the first test that times or loops over them."""
    from audio.cepstrum import cepstra, utterance_distance

    x = tone(220.0, 0.3).astype(np.float32)
    c = cepstra(x, SR)
    utterance_distance(c, c)


def alternating_words(classes: tuple[str, ...], talking: float, *, seed: int = 1, length: float = 60.0,
                      ) -> tuple[np.ndarray, list[tuple[float, float]]]:
    """Words of ``classes`` in turn, 1.2–2 s apart, for ``talking`` seconds of a ``length``
    second signal (silence after); the words' spans, word ``k`` of class ``k % len(classes)``."""
    rng = np.random.default_rng(seed)
    x = np.zeros(int(length * SR), np.float32)
    spans, t, k = [], 1.0, 0
    while t < talking:
        w = word(classes[k % len(classes)], rng, SR, stretch=rng.uniform(0.9, 1.1), rms=0.05)
        i = int(t * SR)
        x[i : i + len(w)] += w
        spans.append((t, t + len(w) / SR))
        t += len(w) / SR + rng.uniform(1.2, 2.0)
        k += 1
    return x, spans


def midi_to_hz(midi: float) -> float:
    return 440.0 * 2.0 ** ((midi - 69.0) / 12.0)


def silence(duration: float, sr: int = SR) -> np.ndarray:
    return np.zeros(int(duration * sr))


def noise(
    duration: float, rng: np.random.Generator, sr: int = SR, *, rms: float = 0.1
) -> np.ndarray:
    return rms * rng.standard_normal(int(duration * sr))


def tone(
    freq: float, duration: float, sr: int = SR, *, harmonics: int = 6, rms: float = 0.1
) -> np.ndarray:
    """A harmonic tone (partials falling as 1/k) with a short attack and release."""
    t = np.arange(int(duration * sr)) / sr
    ks = np.arange(1, harmonics + 1)
    ks = ks[ks * freq < sr / 2]
    x = (np.sin(2 * np.pi * freq * np.outer(ks, t)) / ks[:, None]).sum(axis=0)
    return normalise(x * envelope(len(x), sr), rms)


def chirp(f0: float, f1: float, duration: float, sr: int = SR, *, rms: float = 0.1) -> np.ndarray:
    t = np.arange(int(duration * sr)) / sr
    x = signal.chirp(t, f0, duration, f1, method="logarithmic")
    return normalise(x * envelope(len(x), sr), rms)


@dataclass
class EventTrack:
    """A signal with sound events at known times (seconds)."""

    samples: np.ndarray
    onsets: np.ndarray
    offsets: np.ndarray
    sr: int = SR


def event_track(
    rng: np.random.Generator,
    n_events: int,
    *,
    snr_db: float = 20.0,
    sr: int = SR,
    rms: float = 0.05,
) -> EventTrack:
    """``n_events`` mixed tones/chirps/vowels/noise bursts in white noise ``snr_db`` below them."""
    gaps = rng.uniform(0.25, 0.7, n_events + 1)
    durations = rng.uniform(0.12, 0.5, n_events)
    onsets = np.cumsum(np.concatenate([[gaps[0] + 1.0], durations[:-1] + gaps[1:-1]]))
    total = onsets[-1] + durations[-1] + gaps[-1]
    x = np.zeros(int(total * sr))
    for t0, d in zip(onsets, durations):
        kind = rng.integers(4)
        if kind == 0:
            ev = tone(rng.uniform(100, 1000), d, sr)
        elif kind == 1:
            ev = chirp(rng.uniform(200, 600), rng.uniform(800, 3000), d, sr)
        elif kind == 2:
            ev = formant_burst(VOWELS["aeiou"[rng.integers(5)]], d, rng, sr)
        else:
            ev = noise(d, rng, sr) * envelope(int(d * sr), sr)
        ev = normalise(ev, rms * 10 ** (rng.uniform(-3, 3) / 20))
        i = int(t0 * sr)
        x[i : i + len(ev)] += ev
    x += noise(total, rng, sr, rms=rms * 10 ** (-snr_db / 20))[: len(x)]
    return EventTrack(x.astype(np.float32), onsets, onsets + durations, sr)


def write_wav(path: Path, x: np.ndarray, sr: int = SR, *, subtype: str = "PCM_16") -> Path:
    soundfile.write(path, x, sr, subtype=subtype)
    return path


class Recorder(Protocol):
    """What the ``record`` fixture gives a test: a signal in, a WAV file's path out."""

    def __call__(self, x: np.ndarray, *, subtype: str = "PCM_16") -> Path: ...


@pytest.fixture(name="record")
def recording(tmp_path: Path) -> Recorder:
    """``record(x)`` writes ``x`` as a new WAV file in ``tmp_path`` and returns its path, to be
    heard through :func:`audio.sources.load_audio` or :class:`audio.sources.FileSource`.

    16-bit PCM by default, as a microphone recording would be; a signal that would clip there
    is refused rather than silently distorted (pass ``subtype="FLOAT"`` for signals whose
    random gain goes above full scale, e.g. the ±12 dB words).
    """
    takes = itertools.count()

    def record(x: np.ndarray, *, subtype: str = "PCM_16") -> Path:
        peak = float(np.abs(x).max(initial=0.0))
        if subtype.startswith("PCM") and peak >= 1.0:
            raise ValueError(f"peak {peak:.2f} would clip in {subtype}: record it as FLOAT")
        return write_wav(tmp_path / f"take{next(takes)}.wav", x, subtype=subtype)

    return record
