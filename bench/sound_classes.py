"""Sound classes on real voices and sampled instruments: where the hearing constants come from.

``python -m bench sound_classes`` clusters each corpus with :func:`audio.utterance.
cluster_medoids` over the time-warped cepstral distances of :mod:`audio.cepstrum` and counts
the sounds that land in the class of their word (:func:`class_accuracy`) over a range of
radii. The radius is chosen on the *tuning* corpora only (:func:`chosen_radius`) and checked on
*held-out* ones: other words, other voices, other seeds, another phrase. The corpora:

* **espeak-ng words**: twelve two-syllable words per set, each voice saying each word at two
  speeds and pitches (:data:`RENDITIONS`) over room noise, each cut out by the amplitude
  segmenter as an ear does. Tuning: :data:`TUNING_WORDS` by the six :data:`TUNING_VOICES`.
  Held out: :data:`HELD_OUT_WORDS` by those voices; the tuning words by three other voices
  (:data:`OTHER_VOICES`); and :data:`FRESH_WORDS` by those other voices, measured once after
  every choice was made (tests/test_audio_voices_espeak.py asserts on it). Words in other
  accents and by the Klatt synthesiser (:data:`OTHER_ACCENTS`) are reported, not required.
* **synthetic words** (:mod:`audio.formants`): gain ±12 dB, stretch 0.8–1.25×, 20 dB SNR —
  what the constants were first measured on.
* **sampled instruments** (fluidsynth): piano, guitar, flute, organ and strings each playing
  a phrase at three velocities and tempi; a class is one instrument playing one phrase.
  Tuning: two phrases; held out: a third.

It also measures, per liftering choice, without the vocal-tract-length warps, and for the
analysis the constants were first measured with (13 MFCCs, lifter 22, no warps), over how wide
a range of radii every tuning corpus keeps ≥ 90 % in class; and three creatures' profile
correlation (:func:`creatures.kinds.three_creatures.profile`) between same-class and
other-class sounds, from which its ``SAME`` is read.
"""

from __future__ import annotations

import functools
import shutil
import subprocess
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import librosa
import numpy as np
import soundfile as sf

from audio.cepstrum import WARPS, cepstra, distance_matrix
from audio.formants import SAMPLE_RATE
from audio.formants import WORDS as SYNTHETIC
from audio.formants import word
from audio.segment import segment
from audio.utterance import DEFAULT_RADIUS, cluster_medoids
from bench import Row

TUNING_WORDS = ("apple", "river", "window", "seven", "tiger", "garden",
                "music", "yellow", "paper", "doctor", "monkey", "table")
HELD_OUT_WORDS = ("orange", "silver", "pocket", "dinner", "lemon", "candle",
                  "rabbit", "number", "water", "morning", "basket", "pencil")
FRESH_WORDS = ("finger", "button", "kitchen", "purple", "summer", "butter",
               "ladder", "mirror", "pillow", "rocket", "sugar", "turtle")
Voice = tuple[str, int, int]
"""espeak-ng voice, words per minute, pitch (0–99)."""
TUNING_VOICES: tuple[Voice, ...] = (("en+f3", 140, 60), ("en+m3", 120, 35), ("en-us+f1", 170, 75),
                                    ("en+f4", 150, 55), ("en-gb-x-rp+m2", 130, 40), ("en-us+Annie", 155, 65))
OTHER_VOICES: tuple[Voice, ...] = (("en+m2", 145, 45), ("en+f5", 150, 65), ("en-us+m4", 160, 40))
OTHER_ACCENTS: tuple[Voice, ...] = (("en-gb-scotland+m4", 140, 40), ("en-029+f5", 150, 60),
                                    ("en-us+klatt", 160, 50))
RENDITIONS = ((0, 0), (25, -15))
"""Each voice says each word twice: as given, and 25 wpm faster 15 pitch steps lower."""
PHRASES = (((0.0, 60, 0.22), (0.25, 64, 0.22), (0.5, 67, 0.22), (0.75, 72, 0.22)),
           ((0.0, 69, 0.3), (0.35, 65, 0.15), (0.5, 62, 0.15), (0.65, 57, 0.5)),
           ((0.0, 55, 0.15), (0.2, 59, 0.15), (0.4, 62, 0.4), (0.9, 67, 0.3)))
"""(start in beats, MIDI pitch, length in beats): two tuning phrases and a held-out one."""
INSTRUMENTS = ("piano", "guitar", "flute", "organ", "strings")
LIFTERS = (0, 8, 16, 22)
STEPS = 161
"""Radii searched per corpus: log-spaced, ~1 % apart."""


@dataclass(frozen=True)
class Corpus:
    sounds: list[np.ndarray]
    labels: np.ndarray  # each sound's class (word, or instrument and phrase)
    speakers: np.ndarray  # each sound's voice (0 where there is one)
    rate: int


def have_espeak() -> bool:
    return shutil.which("espeak-ng") is not None


def speak(text: str, voice: str, speed: int, pitch: int, directory: Path) -> tuple[np.ndarray, int]:
    path = directory / f"{text}-{voice}-{speed}-{pitch}.wav"
    subprocess.run(["espeak-ng", "-s", str(speed), "-p", str(pitch), "-v", voice, "-w", str(path), text],
                   check=True, capture_output=True, timeout=30)
    samples, rate = sf.read(path, dtype="float32")
    return samples, rate


def heard(samples: np.ndarray, rate: int, rng: np.random.Generator, snr_db: float = 30.0) -> np.ndarray:
    """The sound as an ear cuts it out: padded with room noise, the longest segmented event."""
    pad = np.zeros(rate // 2, dtype=np.float32)
    x = np.concatenate([pad, samples, pad])
    x = x + (np.sqrt(np.mean(samples**2)) * 10 ** (-snr_db / 20) * rng.standard_normal(len(x))).astype(np.float32)
    events = segment(x, rate, min_length=0.1, hold=0.15)
    return max(events, key=lambda e: e.duration).samples


def spoken_corpus(words: tuple[str, ...], voices: tuple[Voice, ...], rng: np.random.Generator) -> Corpus:
    """Each voice says each word in each of :data:`RENDITIONS`."""
    sounds, labels, speakers = [], [], []
    with tempfile.TemporaryDirectory() as tmp:
        for v, (voice, speed, pitch) in enumerate(voices):
            for faster, lower in RENDITIONS:
                for k, text in enumerate(words):
                    samples, rate = speak(text, voice, speed + faster, max(0, pitch + lower), Path(tmp))
                    sounds.append(heard(samples, rate, rng))
                    labels.append(k)
                    speakers.append(v)
    return Corpus(sounds, np.array(labels), np.array(speakers), rate)


def synthetic_corpus(rng: np.random.Generator, copies: int = 6) -> Corpus:
    sounds, labels = [], []
    for k, name in enumerate(SYNTHETIC):
        for _ in range(copies):
            w = word(name, rng, stretch=rng.uniform(0.8, 1.25), f0=rng.uniform(100, 160),
                     rms=0.1 * 10 ** (rng.uniform(-12, 12) / 20))
            sounds.append(heard(w.astype(np.float32), SAMPLE_RATE, rng, snr_db=20.0))
            labels.append(k)
    return Corpus(sounds, np.array(labels), np.zeros(len(labels), dtype=int), SAMPLE_RATE)


def instrument_corpus(rng: np.random.Generator, phrases: tuple[tuple[tuple[float, int, float], ...], ...]) -> Corpus:
    """Each instrument plays each phrase at three velocities and tempi; a class per pair."""
    from bench._sampled import Note, render

    rate, sounds, labels = 22050, [], []
    for p, phrase in enumerate(phrases):
        for k, instrument in enumerate(INSTRUMENTS):
            for velocity, tempo in ((60, 1.0), (90, 1.25), (120, 0.8)):
                notes = [Note(0.3 + t * tempo, 0.3 + (t + length) * tempo, pitch, velocity)
                         for t, pitch, length in phrase]
                sounds.append(heard(render(notes, instrument, rate).mean(axis=1), rate, rng))
                labels.append(p * len(INSTRUMENTS) + k)
    return Corpus(sounds, np.array(labels), np.zeros(len(labels), dtype=int), rate)


# -- measuring ------------------------------------------------------------------------------


Analysis = Callable[[np.ndarray, int], np.ndarray]


def distances(corpus: Corpus, analysis: Analysis = cepstra) -> np.ndarray:
    return distance_matrix([analysis(s, corpus.rate) for s in corpus.sounds])


def class_accuracy(distances: np.ndarray, labels: np.ndarray, radius: float) -> float:
    """Fraction of sounds in their word's class. A word's class is the cluster holding most of
    its sounds, if most of that cluster is that word: a word split in two has its smaller part
    wrong, two words in one class the lesser word wrong, and unclustered sounds are wrong."""
    clusters = cluster_medoids(distances, radius, max_clusters=2 * len(set(labels.tolist())), min_members=2)
    where = np.full(len(labels), -1)
    for c, members in enumerate(clusters):
        where[members] = c
    right = 0
    for w in set(labels.tolist()):
        placed = where[(labels == w) & (where >= 0)]
        if len(placed):
            c = int(np.bincount(placed).argmax())
            if np.bincount(labels[clusters[c]]).argmax() == w:
                right += int(np.sum((labels == w) & (where == c)))
    return right / len(labels)


def nearest_other_voice(distances: np.ndarray, corpus: Corpus) -> float:
    """Fraction of sounds whose nearest sound by another voice is the same word."""
    apart = np.where(corpus.speakers[:, None] != corpus.speakers[None, :], distances, np.inf)
    return float(np.mean(corpus.labels[np.argmin(apart, axis=1)] == corpus.labels))


def radii_for(matrices: list[np.ndarray]) -> np.ndarray:
    """Radii to search: half the 1st to half the 60th percentile of the pairwise distances."""
    pairs = np.concatenate([d[np.triu_indices(len(d), 1)] for d in matrices])
    return np.geomspace(np.percentile(pairs, 1) / 2, np.percentile(pairs, 60) / 2, STEPS)


def accuracies(d: np.ndarray, labels: np.ndarray, radii: np.ndarray) -> np.ndarray:
    return np.array([class_accuracy(d, labels, r) for r in radii])


def window(ok: np.ndarray, radii: np.ndarray) -> tuple[float, float]:
    """The widest run of radii where ``ok`` holds; (nan, nan) if none."""
    runs = np.split(np.arange(len(ok)), np.flatnonzero(np.diff(ok.astype(int))) + 1)
    good = [r for r in runs if ok[r[0]]]
    if not good:
        return np.nan, np.nan
    widest = max(good, key=len)
    return float(radii[widest[0]]), float(radii[widest[-1]])


def chosen_radius(accuracy: list[np.ndarray], radii: np.ndarray) -> tuple[float, float, float]:
    """How DEFAULT_RADIUS was chosen: the geometric centre of the widest run of radii keeping
    every tuning corpus ≥ 90 % in class; returned with the run's ends."""
    low, high = window(np.min(accuracy, axis=0) >= 0.9, radii)
    return float(np.sqrt(low * high)), low, high


def mfcc_before(samples: np.ndarray, rate: int) -> np.ndarray:
    """The analysis the constants were first measured with: 13 MFCCs, lifter 22, mean
    normalised, no warps (one warp, so :func:`distance_matrix` compares it)."""
    y = np.pad(np.asarray(samples, dtype=np.float32), (0, max(0, 512 - len(samples))))
    m = librosa.feature.mfcc(y=y, sr=rate, n_mfcc=13, n_fft=512, hop_length=256, center=False, lifter=22).T
    return np.ascontiguousarray((m - m.mean(axis=0))[None], dtype=np.float64)


def _middle_warp(samples: np.ndarray, rate: int) -> np.ndarray:
    middle = len(WARPS) // 2
    return cepstra(samples, rate)[middle : middle + 1]


def variants() -> dict[str, Analysis]:
    """The shipped analysis's alternatives whose tuning windows the bench compares."""
    out: dict[str, Analysis] = {f"lifter {L}": functools.partial(cepstra, lifter=L) for L in LIFTERS}
    out["no warps"] = _middle_warp
    out["13 MFCCs, lifter 22, no warps (before)"] = mfcc_before
    return out


# -- three creatures' SAME ------------------------------------------------------------------


SAME_GRID = np.round(np.arange(0.4, 0.96, 0.05), 2)


def same_pairs(corpus: Corpus) -> dict[str, np.ndarray]:
    """Three creatures' profile correlations of pairs: same class (by one voice, and across
    voices where there are several) and other class."""
    from creatures.kinds.three_creatures import PROFILE, profile

    p = np.array([profile(s, corpus.rate) for s in corpus.sounds])
    r = p @ p.T / PROFILE
    same = (corpus.labels[:, None] == corpus.labels[None, :]) & ~np.eye(len(p), dtype=bool)
    one_voice = corpus.speakers[:, None] == corpus.speakers[None, :]
    pairs = {"same": r[same & one_voice], "other": r[~same & ~np.eye(len(p), dtype=bool)]}
    if (~one_voice).any():
        pairs["across voices"] = r[same & ~one_voice]
    return pairs


def youden(pairs: dict[str, np.ndarray], key: str = "same") -> np.ndarray:
    """Same-class pairs above each threshold of :data:`SAME_GRID` minus other-class pairs above it."""
    return np.array([np.mean(pairs[key] > t) - np.mean(pairs["other"] > t) for t in SAME_GRID])


def same_rows(tuning: dict[str, Corpus]) -> list[Row]:
    from creatures.kinds.three_creatures import SAME

    rows, total = [], np.zeros(len(SAME_GRID))
    for name, corpus in tuning.items():
        pairs = same_pairs(corpus)
        j = youden(pairs)
        total += j
        rows.append(Row(f"SAME: {name}: same-class pairs above {SAME:g}", 100 * np.mean(pairs["same"] > SAME), "%"))
        rows.append(Row(f"  other-class pairs above {SAME:g}", 100 * np.mean(pairs["other"] > SAME), "%"))
        if "across voices" in pairs:
            rows.append(Row(f"  same word across voices above {SAME:g}", 100 * np.mean(pairs["across voices"] > SAME),
                            "%"))
            rows.append(Row("  best J across voices (any threshold)", float(youden(pairs, "across voices").max()), "J"))
        rows.append(Row(f"  best threshold (J {j.max():.2f})", float(SAME_GRID[np.argmax(j)]), "r"))
    rows.append(Row("SAME: threshold of the largest J summed over the tuning corpora",
                    float(SAME_GRID[np.argmax(total)]), "r"))
    return rows


# -- the run ----------------------------------------------------------------------------------


def corpora(quick: bool) -> tuple[dict[str, Corpus], dict[str, Corpus], dict[str, Corpus]]:
    """Tuning, held-out and reported-only corpora (espeak-ng and fluidsynth where installed)."""
    from bench._sampled import have_sampler

    rng = np.random.default_rng(18)
    tuning = {"synthetic words": synthetic_corpus(rng)}
    held_out = {"synthetic words, another seed": synthetic_corpus(rng)}
    reported = {}
    if have_espeak():
        tuning["espeak-ng words, 6 voices"] = spoken_corpus(TUNING_WORDS, TUNING_VOICES, rng)
        held_out["fresh words, 3 other voices"] = spoken_corpus(FRESH_WORDS, OTHER_VOICES, rng)
        if not quick:
            held_out["other words, 6 voices"] = spoken_corpus(HELD_OUT_WORDS, TUNING_VOICES, rng)
            held_out["tuning words, 3 other voices"] = spoken_corpus(TUNING_WORDS, OTHER_VOICES, rng)
            reported["tuning words, other accents and Klatt"] = spoken_corpus(TUNING_WORDS, OTHER_ACCENTS, rng)
    if have_sampler():
        tuning["sampled instruments, 2 phrases"] = instrument_corpus(rng, PHRASES[:2])
        held_out["sampled instruments, another phrase"] = instrument_corpus(rng, PHRASES[2:])
    return tuning, held_out, reported


def run(quick: bool) -> list[Row]:
    tuning, held_out, reported = corpora(quick)
    matrices = {name: distances(c) for named in (tuning, held_out, reported) for name, c in named.items()}
    labelled = {**tuning, **held_out, **reported}
    radii = radii_for([matrices[name] for name in tuning])
    accuracy = {name: accuracies(matrices[name], c.labels, radii) for name, c in labelled.items()}
    radius, low, high = chosen_radius([accuracy[name] for name in tuning], radii)
    rows = [Row(f"radius chosen on the tuning corpora (shipped {DEFAULT_RADIUS:g})", radius, "distance"),
            Row(f"  every tuning corpus ≥ 90 % in class from radius {low:.3f} to", high, "distance")]
    for group, named in (("tuning", tuning), ("held out", held_out), ("reported", reported)):
        for name, c in named.items():
            low, high = window(accuracy[name] >= 0.9, radii)
            rows.append(Row(f"{group}: {name}: in own class at {DEFAULT_RADIUS:g}",
                            100 * class_accuracy(matrices[name], c.labels, DEFAULT_RADIUS), "%",
                            target=None if group == "reported" else 90.0))
            if np.isnan(low):
                best = int(np.argmax(accuracy[name]))
                rows.append(Row(f"  no radius keeps 90 %; best, at {radii[best]:.3f}", 100 * accuracy[name][best], "%"))
            else:
                rows.append(Row(f"  ≥ 90 % in class from radius {low:.3f} to", high, "distance"))
            if len(set(c.speakers.tolist())) > 1:
                rows.append(Row("  nearest sound by another voice is the same word",
                                100 * nearest_other_voice(matrices[name], c), "%"))
    if not quick:
        for label, analysis in variants().items():
            d = [distances(c, analysis) for c in tuning.values()]
            grid = radii_for(d)
            worst = np.min([accuracies(m, c.labels, grid) for m, c in zip(d, tuning.values())], axis=0)
            low, high = window(worst >= 0.9, grid)
            rows.append(Row(f"{label}: every tuning corpus ≥ 90 % over radii ×", high / low, "ratio"))
            rows.append(Row(f"  {label}: worst tuning corpus at the best radius", 100 * worst.max(), "%"))
    return rows + same_rows(tuning)
