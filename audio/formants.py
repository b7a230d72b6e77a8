"""Speech-like sound made in code: vowel formants, "words" and spoken lines of text.

The hearing tests, the hearing benchmark and the speech-fed installations (*ozymandias*'
"spoken text of the poem", *soundcreatures* hearing voices) need voices without recordings
or downloads. A vowel is a jittered glottal pulse train through three parallel formant
resonators (Peterson & Barney averages); a "word" is its vowels in sequence, cross-faded, so
words with different vowel sequences are different sound classes to the cepstral ear
(:mod:`audio.cepstrum`) while repeats of one word stay within its cluster radius.
:func:`speak` reads a text aloud that way: each written word becomes the word of its vowels,
with pauses between words and longer ones between lines.
"""

from __future__ import annotations

import re

import numpy as np
from scipy import signal

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

SAMPLE_RATE = 22050
"""Default rate, the installations' default analysis and synthesis rate."""


def envelope(n: int, sr: int = SAMPLE_RATE, *, attack: float = 0.005, release: float = 0.02) -> np.ndarray:
    """Raised-cosine attack and release, flat between."""
    env = np.ones(n)
    a, r = min(n // 2, int(attack * sr)), min(n // 2, int(release * sr))
    env[:a] = 0.5 - 0.5 * np.cos(np.pi * np.arange(a) / max(a, 1))
    env[n - r :] = env[:r][::-1] if a == r else 0.5 + 0.5 * np.cos(np.pi * np.arange(r) / max(r, 1))
    return env


def normalise(x: np.ndarray, rms: float) -> np.ndarray:
    """``x`` scaled to root-mean-square level ``rms``."""
    return x * (rms / max(np.sqrt(np.mean(x**2)), 1e-12))


def formant_burst(
    formants: tuple[float, ...],
    duration: float,
    rng: np.random.Generator,
    sr: int = SAMPLE_RATE,
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
    sr: int = SAMPLE_RATE,
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


def vowels_of(written: str) -> str:
    """The vowel sequence a written word is "spoken" as: its vowels (y as i), repeats
    collapsed, at most three; a word without vowels is a schwa-like "e"."""
    letters = re.sub(r"[^aeiou]", "", written.lower().replace("y", "i"))
    collapsed = re.sub(r"(.)\1+", r"\1", letters)
    return collapsed[:3] or "e"


def speak(
    text: str,
    rng: np.random.Generator,
    sr: int = SAMPLE_RATE,
    *,
    rms: float = 0.08,
    word_gap: tuple[float, float] = (0.12, 0.22),
    line_gap: float = 0.6,
    f0: float = 120.0,
) -> tuple[np.ndarray, list[tuple[float, float, str]]]:
    """``text`` read aloud by formant words: mono float32 and each word's ``(start, end, word)``
    in seconds. Lines (newlines) end with a longer pause and a falling pitch (declination),
    so the same written word said twice is a near repeat, as in speech."""
    pieces: list[np.ndarray] = []
    spans: list[tuple[float, float, str]] = []
    t = 0.0
    for line in (ln.split() for ln in text.strip().splitlines()):
        for k, written in enumerate(line):
            pitch = f0 * (1.1 - 0.2 * k / max(len(line) - 1, 1))
            w = word(vowels_of(written), rng, sr, stretch=float(rng.uniform(0.85, 1.15)), f0=pitch, rms=rms)
            gap = np.zeros(int(rng.uniform(*word_gap) * sr))
            spans.append((t, t + len(w) / sr, written))
            pieces += [w, gap]
            t += (len(w) + len(gap)) / sr
        pause = np.zeros(int(line_gap * sr))
        pieces.append(pause)
        t += len(pause) / sr
    return np.concatenate(pieces).astype(np.float32), spans
