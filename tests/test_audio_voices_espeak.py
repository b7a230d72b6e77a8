"""Sound classes on real voices: espeak-ng words in three voices, pitches and speeds, cut out
by the ear's segmenter and compared by time-warped cepstral distance (bench/sound_classes.py
measures the same corpus per liftering choice; docs/hearing.md has the numbers)."""

from __future__ import annotations

import numpy as np
import pytest

from audio.cepstrum import LIFTER
from bench.sound_classes import have_espeak, separation, spoken_corpus

pytestmark = pytest.mark.skipif(not have_espeak(), reason="needs espeak-ng")


@pytest.fixture(scope="module")
def corpus() -> tuple[list[np.ndarray], np.ndarray, int]:
    return spoken_corpus(np.random.default_rng(18))


def test_a_word_said_by_another_voice_is_nearest_its_own_word(corpus) -> None:
    sounds, labels, rate = corpus
    assert len(sounds) == 15 and len(set(labels)) == 5
    s = separation(sounds, labels, rate, LIFTER)
    print(f"nearest is the same word: {s['nearest']:.0%}; in own class at best radius "
          f"{s['radius']:.0f}: {s['accuracy']:.0%}")
    assert s["nearest"] >= 0.8  # measured 87 %; chance is 2 in 14


@pytest.mark.xfail(strict=False, reason="measured 2026-12-01: fixed-radius classes hold at most 67 % (lifter 22) "
                   "or 80 % (lifter 6) of the words across three voices; radius 250 puts each in a class of its own")
def test_ninety_percent_of_words_fall_in_their_own_class_across_three_voices(corpus) -> None:
    sounds, labels, rate = corpus
    assert separation(sounds, labels, rate, LIFTER)["shipped"] >= 0.9
