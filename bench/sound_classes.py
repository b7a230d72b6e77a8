"""Sound classes on real voices and sampled instruments: where the hearing constants come from.

``python -m bench sound_classes`` measures, for each liftering choice, the time-warped cepstral
distances (:func:`audio.cepstrum.dtw_distance`) between utterances of the same and of different
words, and how many utterances fixed-radius clustering (:func:`audio.utterance.cluster_medoids`)
puts in the class of their own word, on three corpora:

* **espeak-ng words**: five words in three voices (female, male, a US variant) at different
  pitches and speeds, over room noise, each cut out by the amplitude segmenter as an ear does;
* **synthetic words** (:mod:`audio.formants`): gain ±12 dB, stretch 0.8–1.25×, 20 dB SNR —
  what the constants were first measured on;
* **sampled instruments** (fluidsynth): one phrase each on piano, guitar, flute, organ and
  strings, played at three velocities and two tempi: a "word" here is an instrument's phrase.

It also measures three creatures' profile correlation (:func:`creatures.kinds.three_creatures.
profile`) between same-class and different-class sounds, from which its ``SAME`` is read.
"""

from __future__ import annotations

import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np
import soundfile as sf

from audio.cepstrum import LIFTER, cepstra, distance_matrix
from audio.formants import WORDS as SYNTHETIC
from audio.formants import word
from audio.segment import segment
from audio.utterance import DEFAULT_RADIUS, cluster_medoids
from bench import Row

SPOKEN = ("apple", "river", "window", "seven", "tiger")
VOICES = (("en+f3", 140, 60), ("en+m3", 120, 35), ("en-us+f1", 170, 75))
"""espeak-ng voice, words per minute, pitch (0–99): three speakers, three speeds, three pitches."""
LIFTERS = (0, 6, 12, 22)


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


def spoken_corpus(rng: np.random.Generator) -> tuple[list[np.ndarray], np.ndarray, int]:
    sounds, labels = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for voice, speed, pitch in VOICES:
            for k, text in enumerate(SPOKEN):
                samples, rate = speak(text, voice, speed, pitch, Path(tmp))
                sounds.append(heard(samples, rate, rng))
                labels.append(k)
    return sounds, np.array(labels), rate


def synthetic_corpus(rng: np.random.Generator, copies: int = 3) -> tuple[list[np.ndarray], np.ndarray, int]:
    from audio.formants import SAMPLE_RATE

    sounds, labels = [], []
    for k, name in enumerate(SYNTHETIC):
        for _ in range(copies):
            w = word(name, rng, stretch=rng.uniform(0.8, 1.25), f0=rng.uniform(100, 160),
                     rms=0.1 * 10 ** (rng.uniform(-12, 12) / 20))
            sounds.append(heard(w.astype(np.float32), SAMPLE_RATE, rng, snr_db=20.0))
            labels.append(k)
    return sounds, np.array(labels), SAMPLE_RATE


def instrument_corpus(rng: np.random.Generator) -> tuple[list[np.ndarray], np.ndarray, int]:
    from bench._sampled import Note, render

    rate, sounds, labels = 22050, [], []
    phrase = [(0.0, 60), (0.25, 64), (0.5, 67), (0.75, 72)]
    for k, instrument in enumerate(("piano", "guitar", "flute", "organ", "strings")):
        for velocity, tempo in ((60, 1.0), (90, 1.25), (120, 0.8)):
            notes = [Note(0.3 + t * tempo, 0.3 + (t + 0.22) * tempo, p, velocity) for t, p in phrase]
            audio = render(notes, instrument, rate).mean(axis=1)
            sounds.append(heard(audio, rate, rng))
            labels.append(k)
    return sounds, np.array(labels), rate


def class_accuracy(distances: np.ndarray, labels: np.ndarray, radius: float) -> float:
    """Fraction of sounds in a class whose majority is their own word (unclustered: wrong)."""
    right = 0
    for members in cluster_medoids(distances, radius, max_clusters=2 * len(set(labels)), min_members=2):
        right += int(np.sum(labels[members] == np.bincount(labels[members]).argmax()))
    return right / len(labels)


def separation(sounds: list[np.ndarray], labels: np.ndarray, rate: int, lifter: int) -> dict[str, float]:
    """Same-word and different-word distance statistics, the best radius with its accuracy,
    the accuracy at the shipped radius, and nearest-neighbour word accuracy."""
    d = distance_matrix([cepstra(s, rate, lifter=lifter) for s in sounds])
    nearest = labels[np.argmin(d + np.diag(np.full(len(d), np.inf)), axis=1)]
    same = d[(labels[:, None] == labels[None, :]) & ~np.eye(len(labels), dtype=bool)]
    other = d[labels[:, None] != labels[None, :]]
    radii = np.linspace(np.percentile(same, 25), np.percentile(other, 25), 24)
    accuracy = [class_accuracy(d, labels, r) for r in radii]
    best = int(np.argmax(accuracy))
    return {"same_p90": float(np.percentile(same, 90)), "other_p10": float(np.percentile(other, 10)),
            "same_median": float(np.median(same)), "radius": float(radii[best]), "accuracy": accuracy[best],
            "shipped": class_accuracy(d, labels, DEFAULT_RADIUS), "nearest": float(np.mean(nearest == labels))}


def profile_correlations(sounds: list[np.ndarray], labels: np.ndarray, rate: int) -> tuple[float, float]:
    """Fractions of same-class and of other-class pairs whose profiles correlate above three
    creatures' ``SAME`` (counted as copies of one sound)."""
    from creatures.kinds.three_creatures import PROFILE, SAME, profile

    p = np.array([profile(s, rate) for s in sounds])
    r = p @ p.T / PROFILE
    same = r[(labels[:, None] == labels[None, :]) & ~np.eye(len(labels), dtype=bool)]
    other = r[labels[:, None] != labels[None, :]]
    return float(np.mean(same > SAME)), float(np.mean(other > SAME))


def run(quick: bool) -> list[Row]:
    from bench._sampled import have_sampler

    rng = np.random.default_rng(18)
    corpora = {"synthetic words": synthetic_corpus(rng)}
    if have_espeak():
        corpora["espeak-ng words, 3 voices"] = spoken_corpus(rng)
    if have_sampler():
        corpora["sampled instruments"] = instrument_corpus(rng)
    rows = []
    for name, (sounds, labels, rate) in corpora.items():
        for lifter in LIFTERS:
            s = separation(sounds, labels, rate, lifter)
            if lifter == LIFTER:
                rows.append(Row(f"{name}: in own class at the shipped radius {DEFAULT_RADIUS:g}",
                                100 * s["shipped"], "%", target=90.0))
                rows.append(Row(f"{name}: nearest other sound is the same word", 100 * s["nearest"], "%"))
            rows.append(Row(f"{name}, lifter {lifter}: in own class at the best radius ({s['radius']:.0f})",
                            100 * s["accuracy"], "%", target=90.0))
            rows.append(Row(f"  same-word p90 / other-word p10 distance, lifter {lifter}",
                            s["same_p90"] / s["other_p10"], "ratio", higher_is_better=False, target=1.0))
        same, other = profile_correlations(sounds, labels, rate)
        rows.append(Row(f"{name}: same-class pairs above three creatures' SAME", 100 * same, "%"))
        rows.append(Row(f"{name}: other-class pairs above SAME (taken for copies)", 100 * other, "%"))
    return rows
