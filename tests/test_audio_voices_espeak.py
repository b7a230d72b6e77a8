"""Sound classes on real voices (issue 18): twelve espeak-ng words, each said by three voices at
two speeds and pitches, cut out by the ear's segmenter and clustered at the shipped radius.

The voices are not those the radius was chosen on (bench/sound_classes.py chose it on six
others, with synthetic words and sampled instruments; docs/hearing.md has the numbers), and
the room noise is another seed's."""

from __future__ import annotations

import numpy as np
import pytest

from audio.utterance import DEFAULT_RADIUS
from bench.sound_classes import (
    OTHER_VOICES,
    TUNING_WORDS,
    Corpus,
    class_accuracy,
    distances,
    have_espeak,
    nearest_other_voice,
    spoken_corpus,
)

pytestmark = pytest.mark.skipif(not have_espeak(), reason="needs espeak-ng")


@pytest.fixture(scope="module")
def corpus() -> Corpus:
    return spoken_corpus(TUNING_WORDS, OTHER_VOICES, np.random.default_rng(7))


@pytest.fixture(scope="module")
def matrix(corpus: Corpus) -> np.ndarray:
    return distances(corpus)


def test_ninety_percent_of_words_fall_in_their_own_class_across_three_voices(corpus, matrix) -> None:
    assert len(set(corpus.speakers.tolist())) == 3 and len(set(corpus.labels.tolist())) == 12
    # Not on a knife edge: 10 % either side of the shipped radius holds as well.
    for radius in (0.9 * DEFAULT_RADIUS, DEFAULT_RADIUS, 1.1 * DEFAULT_RADIUS):
        accuracy = class_accuracy(matrix, corpus.labels, radius)
        print(f"radius {radius:.3f}: {accuracy:.0%} in own class")
        assert accuracy >= 0.9


def test_a_word_said_by_another_voice_is_nearest_its_own_word(corpus, matrix) -> None:
    assert nearest_other_voice(matrix, corpus) >= 0.9  # chance is 1 in 12


def test_a_random_classifier_does_not_pass(corpus, matrix) -> None:
    """The measure cannot be met by chance: the same distances with the words shuffled, or
    the same distances scattered at random over the pairs, leave most sounds out of class."""
    rng = np.random.default_rng(0)
    assert class_accuracy(matrix, rng.permutation(corpus.labels), DEFAULT_RADIUS) < 0.3
    upper = np.triu_indices(len(matrix), 1)
    scattered = np.zeros_like(matrix)
    scattered[upper] = rng.permutation(matrix[upper])
    assert class_accuracy(scattered + scattered.T, corpus.labels, DEFAULT_RADIUS) < 0.3


def test_split_and_merged_words_count_as_wrong() -> None:
    """Two words of four sounds each, on a line: a word's class is the cluster holding most of
    it, if that cluster is mostly that word."""
    labels = np.array([0, 0, 0, 0, 1, 1, 1, 1])
    apart = np.array([0.0, 0.1, 0.2, 0.3, 5.0, 5.1, 5.2, 5.3])
    split = np.array([0.0, 0.1, 3.0, 3.1, 5.0, 5.1, 5.2, 5.3])
    for points, radius, expected in ((apart, 0.5, 1.0), (split, 0.5, 0.75), (apart, 10.0, 0.5)):
        d = np.abs(points[:, None] - points[None, :])
        assert class_accuracy(d, labels, radius) == expected
