"""The live benchmark's heard → answered measure (bench/live.py): each note is matched to its
own answer, never to a later answer of the same pitch."""

from __future__ import annotations

import numpy as np

from bench.live import UNANSWERED, answer_latencies


def test_each_note_is_matched_to_its_own_answer_or_counted_unanswered() -> None:
    sent = [{"pitch": 60, "sent": 10.0}, {"pitch": 62, "sent": 10.05}, {"pitch": 60, "sent": 11.8},
            {"pitch": 62, "sent": 11.85}]
    arrivals = {
        (0, 60): [10.001, 11.8025],  # both answered
        (0, 62): [11.851],  # the first 62 got no answer: the next one's answer is not its own
        (1, 62): [10.0505],  # another creature's channel does not count
    }
    latency = answer_latencies(sent, arrivals, channel=0)
    assert np.allclose(latency[[0, 2, 3]], [1.0, 2.5, 1.0])
    assert latency[1] == UNANSWERED


def test_an_arrival_before_the_send_is_not_an_answer() -> None:
    sent = [{"pitch": 60, "sent": 10.0}]
    latency = answer_latencies(sent, {(0, 60): [9.999]}, channel=0)
    assert latency[0] == UNANSWERED
