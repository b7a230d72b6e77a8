"""Duration models (thesis: "temporal models", figure 11 low-integer-ratio duration models).

The rhythm fixture: notes of 1, ½, 2 and 1½ beats (quarter, eighth, half, dotted quarter)
with each inter-onset interval jittered uniformly by ±5 %, rendered as onset times and turned
back into intervals by :func:`inter_onset_intervals` (the path a MIDI or audio listener uses).
"""

from __future__ import annotations

import json
import math
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from creatures.behaviour import ActionTuple, DoUntil, WhateverPercept
from creatures.behaviour.action_tuple import Action
from creatures.temporal.durations import LowIntegerRatioModel, SimpleDurationModel
from creatures.temporal.onsets import inter_onset_intervals, merge_onsets, onsets_from_intervals

NOTES = np.array([1.0, 0.5, 2.0, 1.5])  # in beats: quarter, eighth, half, dotted quarter
WEIGHTS = np.array([0.4, 0.3, 0.15, 0.15])
JITTER = 0.05
SEEDS = range(8)


def rhythm(rng: np.random.Generator, n: int, bpm: float) -> tuple[np.ndarray, np.ndarray]:
    """(intervals in seconds, nominal lengths in beats) of ``n`` jittered notes."""
    beats = NOTES[rng.choice(NOTES.size, size=n, p=WEIGHTS)]
    onsets = onsets_from_intervals(beats * 60.0 / bpm * rng.uniform(1 - JITTER, 1 + JITTER, n))
    return inter_onset_intervals(onsets), beats


def ratio_values(model: LowIntegerRatioModel, labels: np.ndarray) -> np.ndarray:
    values = np.array([float(r) for r in model.ratios] + [np.nan])
    return values[labels]


def test_learns_the_beat_and_hears_each_note_as_its_ratio():
    """200 onsets at 100 BPM, for each of 200 seeded rhythms: the pulse is the beat within
    2 % and ≥ 95 % of the intervals carry their true ratio.

    Two sets of labels are measured. The *final* labels (what ``update_many`` returns) are
    the model's interpretation after revision: a re-anchoring rewrites the labels of the
    segment it reinterprets, and a change of metrical level renames every label — this is
    the ≥ 95 % the issue asks for. The *online* labels (what each ``update`` returned at the
    time, as a Du hears them) cannot all be right: the first six or so intervals come before
    any pulse is known, and an opening of mostly eighths cannot tell the eighth from the
    beat until a level check has seen more. Measured over these 200 seeds: ≥ 81 % of online
    labels right for every seed, 96 % on average, and from the 32nd note on ≥ 97 %.
    """
    failures = []
    online_share = []
    for seed in range(200):
        intervals, beats = rhythm(np.random.default_rng(seed), 199, bpm=100.0)  # 200 onsets
        model = LowIntegerRatioModel(prior_pulse=0.5)
        final = ratio_values(model, model.update_many(intervals))
        live = LowIntegerRatioModel(prior_pulse=0.5)
        online = ratio_values(live, np.array([live.update(d) for d in intervals]))
        values = (
            abs(model.pulse / 0.6 - 1.0),
            np.mean(final == beats),
            np.mean(online == beats),
            np.mean(online[32:] == beats[32:]),
        )
        online_share.append(values[2])
        # The pulse is the beat itself (not the eighth or dotted quarter the first bars might suggest).
        if not (values[0] <= 0.02 and values[1] >= 0.95 and values[2] >= 0.8 and values[3] >= 0.95):
            failures.append((seed, *(round(float(v), 3) for v in values)))
    assert not failures, f"(seed, pulse error, final, online, online from note 32): {failures}"
    assert np.mean(online_share) >= 0.95


def test_follows_a_tempo_change_within_sixteen_beats():
    """100 → 130 BPM after 200 onsets, for each of 200 seeded rhythms: from 16 beats after
    the change on, the pulse is the new beat within 2.5 %, and within 2 % for ≥ 97 % of the
    seeds (from 24 beats on, for all).

    Why not 2 % for every seed from 16 beats: after re-anchoring, the pulse is the mean of
    the dozen or so durations heard at the new tempo, and with ±5 % uniform jitter that
    mean has a spread of about 0.8 % (measured: 0.82 %, unbiased), so a few seeds in 200
    touch 2.1 % for a beat or two — noise, not a failure to follow.
    """
    new_beat = 60.0 / 130.0
    worst = []
    for seed in range(200):
        rng = np.random.default_rng(seed)
        model = LowIntegerRatioModel(prior_pulse=0.5)
        model.update_many(rhythm(rng, 199, bpm=100.0)[0])
        assert model.pulse == pytest.approx(0.6, rel=0.02)
        intervals, beats = rhythm(rng, 60, bpm=130.0)
        error = []
        for d in intervals:
            model.update(d)
            error.append(abs(model.pulse / new_beat - 1.0))
        assert model.reanchors >= 2  # the first anchoring and the tempo change
        elapsed = np.cumsum(beats)
        worst.append((max(np.array(error)[elapsed >= 16.0]), max(np.array(error)[elapsed >= 24.0])))
    from_16, from_24 = np.array(worst).T
    assert from_16.max() <= 0.025, np.flatnonzero(from_16 > 0.025)
    assert np.mean(from_16 <= 0.02) >= 0.97
    assert from_24.max() <= 0.02, np.flatnonzero(from_24 > 0.02)


@pytest.mark.parametrize(("before", "after"), [(100.0, 130.0), (130.0, 100.0), (100.0, 150.0)])
def test_a_steady_beat_follows_a_tempo_change_within_sixteen_beats(before, after):
    """Quarters only, then a jump by about a modulating ratio (100 → 130 BPM is within 2.5 %
    of 4:3): the new quarters are heard as 3:4 notes, familiar after two of them, so only
    the steady run of one modulating ratio shows the change. Before that rule the pulse
    stayed behind for ~190 notes (until the metrical level check); now, on 50 seeds, it is
    the new beat within 2.5 % from the 16th beat on and stays there."""
    late = []
    for seed in range(50):
        rng = np.random.default_rng(seed)
        model = LowIntegerRatioModel(prior_pulse=0.5)
        model.update_many(60.0 / before * rng.uniform(1 - JITTER, 1 + JITTER, 200))
        beat = 60.0 / after
        error = []
        for d in beat * rng.uniform(1 - JITTER, 1 + JITTER, 200):
            model.update(d)
            error.append(abs(model.pulse / beat - 1.0))
        if max(error[15:]) > 0.025:
            late.append((seed, int(np.argmax(np.array(error) <= 0.025)) + 1))
    assert not late, f"(seed, beats until followed): {late}"


def test_a_run_of_eighths_keeps_the_beat():
    """Sixteen and more eighths after a passage of quarters are eighths at the same tempo: the
    steady-run rule is for modulating ratios only (the metrical level check decides, later,
    whether a piece is counted in eighths)."""
    rng = np.random.default_rng(3)
    model = LowIntegerRatioModel(prior_pulse=0.5)
    model.update_many(0.6 * rng.uniform(1 - JITTER, 1 + JITTER, 200))
    anchors = model.reanchors
    labels = model.update_many(0.3 * rng.uniform(1 - JITTER, 1 + JITTER, 40))
    assert model.reanchors == anchors and model.pulse == pytest.approx(0.6, rel=0.03)
    assert set(ratio_values(model, labels)) == {0.5}


@pytest.mark.parametrize("seed", range(4))
def test_follows_a_gradual_accelerando(seed):
    """Consistent drift (100 → 140 BPM over 100 notes) is followed by the FIFO and, when it
    falls behind, by re-anchoring — without ever losing the metrical level."""
    rng = np.random.default_rng(seed)
    bpm = np.concatenate((np.full(100, 100.0), np.linspace(100.0, 140.0, 100), np.full(60, 140.0)))
    beats = NOTES[rng.choice(NOTES.size, size=bpm.size, p=WEIGHTS)]
    intervals = beats * 60.0 / bpm * rng.uniform(1 - JITTER, 1 + JITTER, bpm.size)
    model = LowIntegerRatioModel()
    error = []
    for d, tempo in zip(intervals, bpm):
        model.update(d)
        error.append(model.pulse / (60.0 / tempo) - 1.0)
    error = np.abs(error)
    assert error[100:].max() < 0.1  # lags the ramp by at most the tolerance, never by a level
    assert error[-20:].max() < 0.02  # and settles on the final beat


@pytest.mark.parametrize("seed", SEEDS)
def test_samples_lie_on_the_learned_lattice_with_the_heard_ratio_histogram(seed):
    """Every generated duration lies on the lattice (ratio × learned pulse) within the jitter
    that was heard — ±5 % of the true beat, so ±5 % × beat/pulse of the learned one — with
    the spread of the heard jitter, and the ratios come in the proportions heard."""
    rng = np.random.default_rng(seed)
    model = LowIntegerRatioModel(prior_pulse=0.5)
    intervals, beats = rhythm(rng, 400, bpm=100.0)
    model.update_many(intervals)
    beat = 0.6
    assert model.pulse == pytest.approx(beat, rel=0.02)
    samples = model.sample_many(rng, 5000)
    scalar = np.array([model.sample(rng) for _ in range(5000)])
    lattice = np.array([float(r) for r in model.ratios]) * model.pulse
    for drawn in (samples, scalar):
        relative = drawn[:, None] / lattice - 1.0
        nearest = np.abs(relative).argmin(axis=1)
        off = relative[np.arange(drawn.size), nearest]
        assert np.abs(off).max() <= JITTER * beat / model.pulse + 1e-12
        # The spread around the lattice is the heard jitter (uniform ±5 %: sd ≈ 2.9 %).
        assert 0.015 < off.std() < 0.045
        # Ratio histogram of the samples vs the last `recency` notes heard (in beats).
        recent = beats[-model.to_dict()["recency"] :]
        heard = np.array([np.mean(recent == n) for n in NOTES])
        drawn_beats = np.array([float(model.ratios[j]) for j in nearest])
        produced = np.array([np.mean(drawn_beats == n) for n in NOTES])
        assert 0.5 * np.abs(heard - produced).sum() + 0.5 * (1 - produced.sum()) <= 0.1


def test_figure_11_two_point_one_is_twice_the_pulse():
    model = LowIntegerRatioModel(prior_pulse=1.0, reanchor_window=16)
    index = model.update(2.1)
    assert model.ratios[index] == Fraction(2)
    assert model.to_dict()["fifo"][-1] == pytest.approx(1.05)
    # Asking (without learning) how other durations would be heard:
    heard = [model.ratios[j] if j >= 0 else None for j in model.interpret([0.5, 1.52, 1.2, 3.1])]
    assert heard == [Fraction(1, 2), Fraction(3, 2), None, Fraction(3)]


def test_update_many_is_update_in_a_loop():
    rng = np.random.default_rng(3)
    first, _ = rhythm(rng, 150, bpm=100.0)
    second, _ = rhythm(rng, 150, bpm=130.0)
    stream = np.concatenate((first, second))
    batch, scalar = LowIntegerRatioModel(block=64), LowIntegerRatioModel()
    batch.update_many(stream)
    for d in stream:
        scalar.update(d)
    a, b = batch.to_dict(), scalar.to_dict()
    assert a["labels"] == b["labels"] and a["reanchors"] == b["reanchors"] >= 2
    assert np.allclose(a["fifo"], b["fifo"], rtol=1e-12)


@pytest.mark.parametrize("bad", [0.0, -1.0, math.nan, math.inf, -math.inf, 7200.0])
def test_update_rejects_bad_durations_loudly(bad):
    for model in (LowIntegerRatioModel(), SimpleDurationModel(1.0, 0.1)):
        before = model.to_dict()
        with pytest.raises(ValueError, match="duration"):
            model.update(bad)
        assert model.to_dict() == before  # nothing learnt, nothing lost


@settings(max_examples=60, deadline=None)
@given(
    st.lists(
        st.one_of(
            st.floats(0.05, 5.0),
            st.sampled_from([0.0, -1.0, math.nan, math.inf, -math.inf, 7200.0]),
        ),
        max_size=300,
    )
)
def test_update_many_skips_and_counts_bad_durations_and_never_diverges(stream):
    stream = np.array(stream, dtype=float)
    good = stream[np.isfinite(stream) & (stream > 0) & (stream <= 3600)]
    ratio, simple = LowIntegerRatioModel(prior_pulse=0.5), SimpleDurationModel(0.5, 0.1)
    labels = ratio.update_many(stream)
    accepted = simple.update_many(stream)
    assert labels.size == accepted == good.size
    assert ratio.rejected == simple.rejected == stream.size - good.size
    lo = min([0.5] + list(good / 4)) * math.exp(-ratio.tolerance)
    hi = max([0.5] + list(good * 4)) * math.exp(ratio.tolerance)
    assert lo <= ratio.pulse <= hi
    assert math.isfinite(simple.pulse) and simple.std > 0
    rng = np.random.default_rng(0)
    assert np.isfinite(ratio.sample_many(rng, 100)).all() and ratio.sample(rng) > 0
    assert simple.sample(rng) >= simple.min_duration


def test_json_round_trip_is_exact():
    rng = np.random.default_rng(11)
    model = LowIntegerRatioModel()
    model.update_many(np.concatenate((rhythm(rng, 120, 100.0)[0], [0.0, math.nan])))
    data = json.loads(json.dumps(model.to_dict()))
    again = LowIntegerRatioModel.from_dict(data)
    assert again.to_dict() == model.to_dict()
    follow = rhythm(rng, 40, 130.0)[0]
    assert np.array_equal(again.update_many(follow), model.update_many(follow))
    steady = np.full(40, 60.0 / 170.0)  # a steady beat 130 → 170 BPM: saved mid-run, re-anchors alike
    for d in steady[:20]:
        model.update(d)
    again = LowIntegerRatioModel.from_dict(json.loads(json.dumps(model.to_dict())))
    assert np.array_equal(again.update_many(steady[20:]), model.update_many(steady[20:]))
    assert again.pulse == model.pulse and again.reanchors == model.reanchors
    assert again.pulse == model.pulse
    simple = SimpleDurationModel(2.0, 0.5)
    simple.update_many([1.0, 3.0, -2.0])
    assert SimpleDurationModel.from_dict(json.loads(json.dumps(simple.to_dict()))).to_dict() == simple.to_dict()


def test_state_missing_a_key_is_a_clear_error():
    data = LowIntegerRatioModel().to_dict()
    del data["fifo"]
    with pytest.raises(ValueError, match="'fifo'"):
        LowIntegerRatioModel.from_dict(data)


def test_do_until_samples_and_teaches_the_shared_model(rng):
    model = LowIntegerRatioModel(prior_pulse=0.5)
    model.update_many(rhythm(np.random.default_rng(1), 100, 100.0)[0])
    tuples = [ActionTuple(f"t{i}", WhateverPercept(), Action("play"), DoUntil(model), 1.0) for i in range(2)]
    planned = []
    for k, tp in enumerate(tuples):
        tp.start(10.0 * k, rng)
        planned.append(tp.do_until.planned)
        tp.stop(10.0 * k + 1.2)
    ratios = np.array(planned) / model.pulse
    assert np.all(np.min(np.abs(np.log(ratios[:, None] / [0.5, 1, 1.5, 2])), axis=1) <= model.tolerance)
    assert model.to_dict()["labels"][-2:] == [model.ratios.index(Fraction(2))] * 2  # 1.2 s = 2 beats


def test_simple_duration_model_learns_around_five_seconds(rng):
    model = SimpleDurationModel(2.0, 0.5, size=16, prior_weight=0.1)
    heard = rng.normal(5.0, 0.2, 64)
    for d in heard:
        model.update(d)
    assert model.pulse == pytest.approx(0.9 * heard[-16:].mean() + 0.1 * 2.0)  # FIFO pooled with the prior
    assert (model.sample_many(rng, 1000) >= model.min_duration).all()


def test_onsets_merge_chords_and_give_positive_intervals():
    onsets = [0.0, 0.004, 0.6, 0.6, 1.2, 0.9]
    assert np.allclose(merge_onsets(onsets, min_gap=0.02), [0.0, 0.6, 0.9, 1.2])
    assert np.allclose(inter_onset_intervals(onsets, min_gap=0.02), [0.6, 0.3, 0.3])
    with pytest.raises(ValueError, match="onset 1"):
        inter_onset_intervals([0.0, math.nan])


CHANGES = {"100 → 130 BPM": 130.0, "100 → 77 BPM": 77.0, "100 → 160 BPM": 160.0, "triplet eighths": None}


def audible(intervals: np.ndarray, beat: float, tolerance: float = 0.08) -> int:
    """Index of the first interval no note of the old style (:data:`NOTES` at ``beat``)
    could have been: before it the change cannot be heard (four dotted quarters at 77 BPM
    are halves at 100, within 1 %)."""
    off = np.abs(np.log(intervals[:, None] / (NOTES * beat))).min(axis=1) > tolerance
    return int(np.argmax(off)) if off.any() else len(intervals)


@pytest.mark.parametrize("change", CHANGES)
def test_surprise_fires_within_four_notes_of_a_rhythm_change_and_rarely_on_a_steady_one(change):
    """Surprise as a percept (thesis, "expectations about value"): for each of 200 seeded
    rhythms, ``surprised`` holds on at most 5 % of the 199 intervals of a steady rhythm
    (measured: at most 3.5 %, nearly all in the first 32, before the model has anchored;
    0.6 % at most after) and on one of the first 4 notes after the rhythm audibly changes
    — its tempo, or its style (triplet eighths at the same tempo, a ratio never heard).
    Measured: on the first audible note for 82–100 % of seeds, by the 4th for all."""
    late = []
    for seed in range(200):
        rng = np.random.default_rng(seed)
        model = LowIntegerRatioModel(prior_pulse=0.5)
        steady = []
        for d in rhythm(rng, 199, bpm=100.0)[0]:
            model.update(d)
            steady.append(model.surprised)
        assert np.mean(steady) <= 0.05, seed
        bpm = CHANGES[change]
        changed = (rhythm(rng, 12, bpm=bpm)[0] if bpm is not None
                   else 0.6 / 3 * rng.uniform(1 - JITTER, 1 + JITTER, 12))
        first = audible(changed, 0.6)
        surprised = []
        for d in changed[: first + 4]:
            model.update(d)
            surprised.append(model.surprised)
        late += [] if any(surprised[first:]) else [seed]
    assert not late, f"no surprise within 4 notes of the change for seeds {late}"


def test_a_pulse_longer_than_the_longest_duration_saves_and_loads_back():
    """Gaps of an hour, fifty minutes, fifty minutes (accepted durations) are heard as ratios
    below 1 of a pulse of about 4600 s: the saved FIFO of pulses was refused on load (read as
    durations, at most 3600 s), and the creature's learnt pulse with it."""
    model = LowIntegerRatioModel(0.5)
    for k in range(200):
        model.update(3600.0 if k % 3 == 0 else 3000.0)
    assert model.pulse > model.max_duration
    again = LowIntegerRatioModel.from_dict(json.loads(json.dumps(model.to_dict())))
    assert again.pulse == model.pulse and list(again._labels) == list(model._labels)
    damaged = model.to_dict()
    damaged["fifo"][0] = 4.0 * model.max_duration + 1.0  # no duration is heard as that pulse
    with pytest.raises(ValueError, match="fifo"):
        LowIntegerRatioModel.from_dict(damaged)


@pytest.mark.parametrize("model", [SimpleDurationModel(5.0, 1.0), LowIntegerRatioModel(5.0)],
                         ids=["simple", "ratio"])
def test_a_tuple_held_open_for_two_hours_ends_without_teaching_its_model(model):
    """A 5 s tuple held open by another (interval constraint 'during') for two hours of lived
    time, ticked every second: its model refused the 7200 s with a ValueError in the group's
    tick, and the creature stopped."""
    from creatures.behaviour.action_group import ActionGroup
    from creatures.behaviour.percept import FunctionPercept
    from creatures.temporal.intervals import ConstrainedDoUntil

    hold = [1.0]
    du = ConstrainedDoUntil(DoUntil(model), hold=FunctionPercept("held", lambda t: hold[0]))
    tuple_ = ActionTuple("sing", WhateverPercept(), Action("sing"), du, 1.0)
    group = ActionGroup("g", [tuple_], rng=np.random.default_rng(0), alpha=0.0)
    before = model.to_dict()
    for t in range(7200):
        group.tick(float(t))
    hold[0] = 0.0
    group.tick(7200.0)
    assert tuple_.stopped_at == 7200.0 and model.to_dict() == before
