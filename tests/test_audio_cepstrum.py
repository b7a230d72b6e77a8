"""Cepstral analysis and time-warped distance between utterances (audio/cepstrum.py)."""

from __future__ import annotations

import librosa
import numpy as np
import pytest

from audio.cepstrum import N_MFCC, cepstra, dtw_cost, dtw_distance, nearest
from audio.sources import load_audio
from audio_fixtures import SR, WORDS, Recorder, recording, word, warm_librosa  # noqa: F401

pytestmark = pytest.mark.usefixtures("warm_librosa")


def spoken(name: str, rng: np.random.Generator, *, snr_db: float = 20.0) -> np.ndarray:
    """One utterance of a word: random speed 0.8–1.25×, voice pitch, gain ±12 dB, noise."""
    x = word(name, rng, stretch=rng.uniform(0.8, 1.25), f0=rng.uniform(100.0, 160.0))
    x *= 10 ** (rng.uniform(-12.0, 12.0) / 20)
    return x + np.sqrt(np.mean(x**2)) * 10 ** (-snr_db / 20) * rng.standard_normal(len(x))


def test_numba_dtw_matches_librosa(rng: np.random.Generator) -> None:
    for n, m in [(37, 52), (60, 20), (1, 9), (25, 25)]:
        a, b = rng.standard_normal((n, N_MFCC)), rng.standard_normal((m, N_MFCC))
        D, path = librosa.sequence.dtw(X=a.T, Y=b.T, metric="euclidean")
        cost, length = dtw_cost(a, b)
        assert cost == pytest.approx(D[-1, -1], rel=1e-12)
        assert length == len(path)


def test_distance_is_symmetric_and_zero_on_itself(rng: np.random.Generator) -> None:
    a, b = cepstra(spoken("ai", rng), SR), cepstra(spoken("oe", rng), SR)
    assert dtw_distance(a, a) == 0.0
    assert dtw_distance(a, b) == pytest.approx(dtw_distance(b, a))
    assert dtw_distance(a, b) > 0.0


def test_cepstra_shape_and_mean_normalisation(rng: np.random.Generator) -> None:
    x = spoken("ieu", rng)
    c = cepstra(x, SR)
    assert c.shape == (1 + (len(x) - 512) // 256, N_MFCC)
    np.testing.assert_allclose(c.mean(axis=0), 0.0, atol=1e-9)
    assert cepstra(x[:100], SR).shape == (1, N_MFCC)  # shorter than one window: padded


def test_gain_does_not_change_the_cepstra(rng: np.random.Generator) -> None:
    # Holds while the quietest bins stay above librosa's −100 dB floor (amin), as a real
    # room's noise does; the 20 dB SNR noise here scales with the word.
    x = spoken("eao", rng)
    np.testing.assert_allclose(cepstra(0.05 * x, SR), cepstra(x, SR), atol=1e-2)


def test_five_words_recognised_by_nearest_template(rng: np.random.Generator, record: Recorder) -> None:
    def recorded(name: str) -> np.ndarray:  # float WAV: the ±12 dB gain goes past full scale
        return load_audio(record(spoken(name, rng), subtype="FLOAT"))

    templates, labels = [], []
    for k, name in enumerate(WORDS):
        for _ in range(3):
            templates.append(cepstra(recorded(name), SR))
            labels.append(k)
    trials = [(k, recorded(name)) for k, name in enumerate(WORDS) for _ in range(20)]
    correct = sum(labels[nearest(cepstra(x, SR), templates)[0]] == k for k, x in trials)
    assert correct / len(trials) >= 0.95, f"accuracy {correct}/{len(trials)}"


def test_mismatched_cepstra_are_refused() -> None:
    with pytest.raises(ValueError, match="cannot warp"):
        dtw_cost(np.zeros((5, 13)), np.zeros((5, 12)))
    with pytest.raises(ValueError, match="cannot warp"):
        dtw_cost(np.zeros((0, 13)), np.zeros((5, 13)))
