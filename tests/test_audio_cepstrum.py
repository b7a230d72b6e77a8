"""Cepstral analysis and time-warped distance between utterances (audio/cepstrum.py)."""

from __future__ import annotations

import librosa
import numpy as np
import pytest

from audio.cepstrum import N_CEPSTRA, WARPS, cepstra, dtw_cost, nearest, utterance_distance
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
        a, b = rng.standard_normal((n, N_CEPSTRA)), rng.standard_normal((m, N_CEPSTRA))
        D, path = librosa.sequence.dtw(X=a.T, Y=b.T, metric="euclidean")
        cost, length = dtw_cost(a, b)
        assert cost == pytest.approx(D[-1, -1], rel=1e-12)
        assert length == len(path)


def test_distance_is_symmetric_and_zero_on_itself(rng: np.random.Generator) -> None:
    a, b = cepstra(spoken("ai", rng), SR), cepstra(spoken("oe", rng), SR)
    assert utterance_distance(a, a) == 0.0
    assert utterance_distance(a, b) == pytest.approx(utterance_distance(b, a))
    assert utterance_distance(a, b) > 0.0


def test_cepstra_shape_and_normalisation(rng: np.random.Generator) -> None:
    x = spoken("ieu", rng)
    c = cepstra(x, SR)
    assert c.shape == (len(WARPS), 1 + (len(x) - 512) // 256, N_CEPSTRA)
    np.testing.assert_allclose(c.mean(axis=1), 0.0, atol=1e-9)  # each warp mean-normalised
    np.testing.assert_allclose(np.mean(np.sum(c**2, axis=2), axis=1), 1.0, rtol=1e-6)  # unit RMS frame norm
    assert cepstra(x[:100], SR).shape == (len(WARPS), 1, N_CEPSTRA)  # shorter than one window: padded


def test_levinson_and_lpc_cepstra_match_a_direct_solution(rng: np.random.Generator) -> None:
    """The vectorised Levinson–Durbin recursion solves the normal equations (scipy's Toeplitz
    solver), and the LPC cepstrum is that of 1 / A(z): the Fourier series of its log power."""
    import scipy.linalg

    from audio.cepstrum import _levinson, _lpc_cepstra

    x = rng.standard_normal(4096)
    r = np.array([x[: len(x) - k] @ x[k:] for k in range(6)])[:, None]  # (lags, one frame)
    a = _levinson(r)[0]
    np.testing.assert_allclose(a, scipy.linalg.solve_toeplitz(r[:5, 0], -r[1:, 0]), rtol=1e-9)
    spectrum = np.abs(np.fft.rfft(np.r_[1.0, a], 4096))
    expected = np.fft.irfft(-np.log(spectrum**2))[1:9]
    np.testing.assert_allclose(_lpc_cepstra(a[None], 8)[0], expected, atol=1e-6)


def test_gain_does_not_change_the_cepstra(rng: np.random.Generator) -> None:
    # Holds while the quietest bands stay well above the analysis's floor (1e-12 of power),
    # as a real room's noise does; the 20 dB SNR noise here scales with the word.
    x = spoken("eao", rng)
    np.testing.assert_allclose(cepstra(0.05 * x, SR), cepstra(x, SR), atol=1e-4)


def test_a_scaled_vocal_tract_is_met_at_the_opposite_warps(rng: np.random.Generator) -> None:
    """A word whose formants are all 9 % higher (a shorter vocal tract) is nearer itself than
    any unwarped comparison makes it: the warps meet it where its spectrum lines up."""
    base = {"f0": 120.0, "stretch": 1.0}
    x = word("ai", np.random.default_rng(1), **base)
    higher = librosa.resample(x, orig_sr=SR, target_sr=SR / 1.09)  # every frequency × 1.09 at SR
    a, b = cepstra(x, SR), cepstra(higher[: len(x)], SR)
    middle = len(WARPS) // 2
    unwarped = utterance_distance(a[middle : middle + 1], b[middle : middle + 1])
    assert utterance_distance(a, b) < 0.8 * unwarped


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
    with pytest.raises(ValueError, match="cannot warp"):  # one warp against five
        utterance_distance(np.zeros((1, 5, 8)), np.zeros((5, 5, 8)))
    with pytest.raises(ValueError, match="cannot warp"):  # an analysis of another shape
        utterance_distance(np.zeros((5, 7)), np.zeros((5, 7)))
