"""State objects: bounded history, inhibition, habituation, acausal masking."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from creatures.behaviour.state_object import Habituation, StateObject


def test_history_is_bounded_and_chronological():
    state = StateObject("level", history=5)
    for i in range(23):  # wraps the internal double-length buffer twice
        state.push(float(i), i)
    assert len(state) == 5
    assert state.times == [18, 19, 20, 21, 22]  # list-like, as the old deques were
    assert state.data == [18, 19, 20, 21, 22] and state.saliencies == state.data
    assert state.latest() == 22
    assert state.window(19.5, 21.0) == [(20.0, 20, 20.0), (21.0, 21, 21.0)]
    np.testing.assert_array_equal(state.times_array, state.times)
    with pytest.raises(ValueError):
        state.times_array[0] = 0.0  # array views of the history are read-only


@given(st.integers(1, 20), st.lists(st.floats(0, 1), max_size=80))
def test_history_keeps_exactly_the_newest_samples(history, xs):
    state = StateObject("x", history=history)
    for k, x in enumerate(xs):
        state.push(float(k), x)
    kept = xs[-history:] if xs else []
    assert state.data == kept
    np.testing.assert_array_equal(state.saliencies, kept)
    np.testing.assert_array_equal(state.times, np.arange(len(xs))[len(xs) - len(kept) :])


def test_recall_at_a_time():
    state = StateObject("pitch", saliency_fn=lambda d: d / 100)
    assert state.datum_at(1.0) is None and state.saliency_at(1.0) == 0.0
    state.push(1.0, 60)
    state.push(2.0, 72)
    assert state.datum_at(1.5) == 60
    assert state.datum_at(2.0) == 72
    assert state.saliency_at(0.5) == 0.0
    assert state.saliency_at(5.0) == pytest.approx(0.72)


def test_time_must_not_go_backwards_and_nothing_is_lost():
    state = StateObject("x")
    state.push(2.0, 1.0)
    with pytest.raises(ValueError, match="x: time went backwards"):
        state.push(1.0, 5.0)
    assert state.data == [1.0]


def test_inhibition_by_another_state_object():
    """Figure 6: the creature's own singing inhibits what it hears."""
    singing = StateObject("singing")
    hearing = StateObject("hearing")
    hearing.inhibit_by(singing, strength=0.8)
    assert hearing.push(0.0, 1.0) == 1.0  # silent: heard in full
    singing.push(1.0, 0.5)
    assert hearing.push(1.5, 1.0) == pytest.approx(1.0 - 0.8 * 0.5)
    singing.push(2.0, 0.0)
    assert hearing.push(2.5, 1.0) == 1.0


def test_habituation_lowers_repeated_saliency_and_recovers_after_rest():
    state = StateObject("click", habituation=Habituation(rate=0.5, recovery=20.0))
    first = state.push(0.0, 1.0)
    repeated = [state.push(0.1 * k, 1.0) for k in range(1, 51)]
    assert first == 1.0
    assert all(b < a for a, b in zip(repeated, repeated[1:]))
    assert repeated[-1] < 0.6
    state.push(5.1, 0.0)  # the stimulus stops
    assert state.push(5.1 + 100.0, 1.0) > 0.99  # five recovery constants later


def test_habituation_exact_solution_by_hand():
    hab = Habituation(rate=2.0, recovery=4.0)
    hab.advance(1.0, 0.5)
    k = 2.0 * 0.5 + 0.25
    h_eq = 1.0 / k
    assert hab.h == pytest.approx(h_eq * (1.0 - math.exp(-k)))


def test_habituation_depends_on_elapsed_time_not_sample_count():
    coarse = StateObject("a", habituation=Habituation(rate=0.3, recovery=5.0))
    fine = StateObject("b", habituation=Habituation(rate=0.3, recovery=5.0))
    for t in np.arange(0.0, 4.01, 0.5):
        coarse.push(float(t), 1.0)
    for t in np.arange(0.0, 4.001, 0.01):
        fine.push(float(t), 1.0)
    assert coarse.saliency_at(4.0) == pytest.approx(fine.saliency_at(4.0), rel=1e-9)


def test_strong_stimuli_sensitise():
    state = StateObject(
        "sound", habituation=Habituation(rate=0.0, sensitise=1.0, threshold=1.0, calm=2.0)
    )
    state.push(0.0, 3.0)  # a bang
    later = state.push(1.0, 0.5)
    # z = sensitise·(3 − 1)·calm·(1 − e^(−1/2)) after one second
    assert later == pytest.approx(0.5 * (1.0 + 4.0 * (1.0 - math.exp(-0.5))))
    state.push(1.0, 0.0)
    assert state.push(41.0, 0.5) == pytest.approx(0.5, rel=1e-6)  # calmed down


def test_most_salient_in_a_window():
    state = StateObject("level")
    for t, x in [(0.0, 0.1), (1.0, 0.9), (2.0, 0.3), (3.0, 0.9)]:
        state.push(t, x)
    assert state.most_salient(0.5, 3.0) == (1.0, 0.9, 0.9)  # earliest of the ties
    assert state.most_salient(1.5, 2.5) == (2.0, 0.3, 0.3)
    assert state.most_salient(10.0, 11.0) is None


def test_salient_events_mask_forwards_and_backwards():
    state = StateObject("level")
    events = [(0.0, 0.5), (0.9, 0.2), (1.0, 1.0), (1.2, 0.5), (3.0, 0.3)]
    for t, x in events:
        state.push(t, x)
    masked = state.masked_saliencies(0.0, 3.0, reach=1.0)
    # kernel 1 − |Δt|/reach from the loud event at t = 1:
    # t=0.0: 1.0·0 = 0 ≤ 0.5, survives; t=0.9: 0.9 > 0.2, masked backwards;
    # t=1.2: 0.8 > 0.5, masked forwards; t=3.0: out of reach, survives.
    np.testing.assert_allclose(masked, [0.5, 0.0, 1.0, 0.0, 0.3])
    assert [t for t, _, _ in state.unmasked(0.0, 3.0, reach=1.0)] == [0.0, 1.0, 3.0]
    # A masker just outside the queried window still masks inside it.
    assert state.masked_saliencies(1.1, 1.3, reach=1.0).tolist() == [0.0]
    with pytest.raises(ValueError):
        state.masked_saliencies(0.0, 1.0, reach=0.0)


def test_masking_matches_a_plain_loop(rng):
    state = StateObject("noise", history=200)
    times = np.cumsum(rng.exponential(0.1, 300))
    for t, x in zip(times, rng.random(300)):
        state.push(float(t), float(x))
    start, end, reach = times[150], times[250], 0.4
    got = state.masked_saliencies(start, end, reach=reach)
    ts, ss = state.times_array, state.saliencies_array
    expected = []
    for ti, si in zip(ts, ss):
        if start <= ti <= end:
            masker = max(s * max(0.0, 1 - abs(ti - tj) / reach) for tj, s in zip(ts, ss))
            expected.append(si if si >= masker else 0.0)
    np.testing.assert_allclose(got, expected)
