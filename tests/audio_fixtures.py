"""Synthetic sounds for the hearing tests: tones, chirps, vowel-like formant bursts, "words",
noise and silence, plus event tracks with known onsets. Everything is generated in code from
seeded RNGs, so no test depends on a recording or a download."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
import soundfile
from scipy import signal

SR = 22050

VOWELS: dict[str, tuple[float, float, float]] = {
    # First three formants (Hz), Peterson & Barney style averages.
    "a": (730.0, 1090.0, 2440.0),
    "e": (530.0, 1840.0, 2480.0),
    "i": (270.0, 2290.0, 3010.0),
    "o": (570.0, 840.0, 2410.0),
    "u": (300.0, 870.0, 2240.0),
}

WORDS: tuple[str, ...] = ("ai", "ua", "ieu", "oe", "eao")
"""Five "word" classes: different vowel (formant) sequences."""


@pytest.fixture(scope="session")
def warm_librosa() -> None:
    """librosa and the DTW kernel JIT-compile on first use (~15 s cold, a few seconds from
    numba's cache): pay it once, before the first test that times or loops over them."""
    from audio.cepstrum import cepstra, dtw_distance
    from audio.pitch import note_events
    from audio.segment import SoundEvent

    x = tone(220.0, 0.3).astype(np.float32)
    c = cepstra(x, SR)
    dtw_distance(c, c)
    note_events(SoundEvent(0.0, 0.3, x, SR, -20.0))


def midi_to_hz(midi: float) -> float:
    return 440.0 * 2.0 ** ((midi - 69.0) / 12.0)


def envelope(n: int, sr: int = SR, *, attack: float = 0.005, release: float = 0.02) -> np.ndarray:
    """Raised-cosine attack and release, flat between."""
    env = np.ones(n)
    a, r = min(n // 2, int(attack * sr)), min(n // 2, int(release * sr))
    env[:a] = 0.5 - 0.5 * np.cos(np.pi * np.arange(a) / max(a, 1))
    env[n - r :] = env[:r][::-1] if a == r else 0.5 + 0.5 * np.cos(np.pi * np.arange(r) / max(r, 1))
    return env


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


def formant_burst(
    formants: tuple[float, ...],
    duration: float,
    rng: np.random.Generator,
    sr: int = SR,
    *,
    f0: float = 120.0,
    rms: float = 0.1,
) -> np.ndarray:
    """A vowel-like sound: a jittered glottal pulse train through parallel formant resonators."""
    n = int(duration * sr)
    periods = sr / (f0 * (1.0 + 0.01 * rng.standard_normal(int(duration * f0) + 2)))
    pulses = np.cumsum(periods).astype(int)
    source = np.zeros(n)
    source[pulses[pulses < n]] = 1.0
    source = signal.lfilter([1.0], [1.0, -0.95], source)  # glottal spectral tilt
    x = np.zeros(n)
    for k, f in enumerate(formants):
        r = np.exp(-np.pi * (60.0 + 20.0 * k) / sr)
        a = [1.0, -2 * r * np.cos(2 * np.pi * f / sr), r * r]
        x += signal.lfilter([1.0 - r], a, source) / (k + 1)
    return normalise(x * envelope(n, sr, attack=0.01, release=0.03), rms)


def word(
    name: str,
    rng: np.random.Generator,
    sr: int = SR,
    *,
    stretch: float = 1.0,
    f0: float = 120.0,
    rms: float = 0.1,
    segment: float = 0.15,
) -> np.ndarray:
    """A "word": its vowels in sequence, cross-faded; ``stretch`` scales its duration."""
    fade = int(0.03 * sr)
    out = np.zeros(0)
    for v in name:
        seg = formant_burst(VOWELS[v], segment * stretch + 0.03, rng, sr, f0=f0)
        if len(out):
            ramp = np.linspace(0.0, 1.0, fade)
            out[-fade:] = out[-fade:] * (1 - ramp) + seg[:fade] * ramp
            seg = seg[fade:]
        out = np.concatenate([out, seg])
    return normalise(out * envelope(len(out), sr, attack=0.01, release=0.03), rms)


def normalise(x: np.ndarray, rms: float) -> np.ndarray:
    return x * (rms / max(np.sqrt(np.mean(x**2)), 1e-12))


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
