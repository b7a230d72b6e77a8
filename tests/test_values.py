"""Value implementations (thesis: "complex value implementations", "value chaining",
"expectations about value", "emotional tags")."""

from __future__ import annotations

import json
import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from creatures.behaviour.value import (
    VALUE_KINDS,
    ChainValue,
    Comparison,
    GaussianValue,
    ProcessedValue,
    ScalarValue,
    StanceValue,
    Value,
    restored,
    value_from_dict,
)
from creatures.clock import SimulatedClock

finite = st.floats(-1e6, 1e6, allow_nan=False)
alphas = st.floats(0.01, 1.0)
sources = st.dictionaries(st.sampled_from(["eat", "drink", "sleep"]), st.floats(0, 10), max_size=3)


@st.composite
def values(draw) -> Value:
    kind = draw(st.sampled_from(sorted(VALUE_KINDS)))
    v = draw(finite)
    if kind == "chain":
        return ChainValue(v, distances=draw(sources))
    if kind == "gaussian":
        return GaussianValue(v, spread=draw(st.floats(0.1, 100)))
    if kind == "stance":
        return StanceValue(v, stance=draw(st.floats(-1, 1)))
    return ScalarValue(v)


# -- the metric axioms the thesis asks of every V ------------------------------------------
@given(values(), values())
def test_distance_zero_means_same(v1, v2):
    if v1.distance_to(v2) == 0:
        assert v1.compare_to(v2) is Comparison.SAME
    else:
        assert v1.compare_to(v2) is not Comparison.SAME


@given(values(), values(), alphas)
def test_blending_toward_never_increases_distance(v1, v2, alpha):
    before = v1.distance_to(v2)
    v2.blend_to(v1, alpha)
    after = v1.distance_to(v2)
    assert after <= before
    if before > 1e-6 * max(1.0, abs(v1.to_float())):
        assert after < before  # strictly closer whenever there was room to move


@given(values())
@settings(max_examples=60)
def test_every_kind_round_trips_exactly_through_json(v):
    v.blend_to(ScalarValue(3.5), 0.3)
    data = json.loads(json.dumps(v.to_dict()))
    again = value_from_dict(data)
    assert type(again) is type(v)
    assert again.to_dict() == v.to_dict()
    assert again.to_float() == v.to_float()


def test_bad_records_are_refused_by_name():
    with pytest.raises(ValueError, match="unknown value kind 'nope'"):
        value_from_dict({"kind": "nope"})
    with pytest.raises(ValueError, match="stance value is missing key 'stance'"):
        value_from_dict({"kind": "stance", "value": 1.0})


# -- value chaining: the tracer dye ------------------------------------------------------------
def test_dye_blend_by_hand():
    eat = ChainValue(100.0, source="eat")
    a = ChainValue(0.0, max_distance=10.0)
    a.blend_to(eat, 0.5)
    # D ← (1 − α)·10 + α·(0 + 1) = 5.5; the scalar low-pass as usual.
    assert a.distances == {"eat": 5.5}
    assert a.value == 50.0
    b = ChainValue(0.0)
    b.blend_to(a, 0.5)
    assert b.distances == {"eat": 0.5 * 10.0 + 0.5 * (5.5 + 1.0)}
    eat.blend_to(a, 1.0)
    assert eat.distances["eat"] == 0.0  # a source stays at distance zero from itself


def test_dye_gravitates_to_the_source_a_tuple_precedes():
    """Thesis figure: A chases animals before "eat", B follows the river before "drink"."""
    eat = ChainValue(100.0, source="eat")
    drink = ChainValue(100.0, source="drink")
    a, b = ChainValue(0.0), ChainValue(0.0)
    for _ in range(40):
        a.blend_to(eat, 0.2)
        b.blend_to(drink, 0.2)
    # D − 1 shrinks by (1 − α) per blend from 10 − 1: D = 1 + 9·0.8⁴⁰.
    assert a.distance_from("eat") == pytest.approx(1.0 + 9.0 * 0.8**40)
    assert a.distance_from("drink") == 10.0
    assert b.distance_from("drink") == pytest.approx(1.0 + 9.0 * 0.8**40)


def test_motivation_reweights_whole_chains():
    importance = {"eat": 1.0, "drink": 1.0}
    near_food = ChainValue(40.0, distances={"eat": 1.0, "drink": 10.0}, importance=importance)
    near_water = ChainValue(40.0, distances={"eat": 10.0, "drink": 1.0}, importance=importance)
    assert near_food.to_float() == near_water.to_float() == 40.0  # equal drives: no change

    importance.update(eat=1.0, drink=0.0)  # hungry, not thirsty
    w1, w10 = 2.0**-1, 2.0**-10
    assert near_food.to_float() == pytest.approx(40.0 * w1 / (w1 + w10))
    assert near_water.to_float() == pytest.approx(40.0 * w10 / (w1 + w10))
    # Comparison and distance ignore the mood: the learned values are still equal.
    assert near_food.compare_to(near_water) is Comparison.SAME


def test_chain_value_with_scalar_partner_forgets_toward_max():
    a = ChainValue(0.0, distances={"eat": 2.0})
    a.blend_to(ScalarValue(10.0), 0.5)  # a partner with no dye is max_distance away
    assert a.distances["eat"] == 0.5 * 2.0 + 0.5 * (10.0 + 1.0)
    a.blend_to(ScalarValue(10.0), 1.0)
    assert a.distances["eat"] == 10.0  # never beyond the default maximum


# -- expectations about value --------------------------------------------------------------------
def _trained(clock=None) -> GaussianValue:
    v = GaussianValue(10.0, spread=1.0, size=16, threshold=0.05, clock=clock)
    for x in [9.5, 10.5] * 8:
        v.blend_to(ScalarValue(x), 0.3)
    return v


def test_surprising_value_is_flagged_and_expected_is_not():
    v = _trained()
    assert v.surprise(10.2) == 0.0
    assert v.surprise(25.0) > 0.9
    # likelihood by hand around V_l with the model's σ
    z = (25.0 - v.value) / v.model.std
    assert v.likelihood(25.0) == pytest.approx(math.exp(-0.5 * z * z))


def test_confidence_falls_when_recently_wrong():
    v = _trained()
    assert v.confidence() == pytest.approx(1.0)
    v.blend_to(ScalarValue(40.0), 1.0)
    # reliability ← r + reliance·α·(0 − r) = 1 − 0.2
    assert v.confidence() == pytest.approx(0.8)
    assert v.surprise(200.0) < 1.0 * 0.81  # less surprising now that it has been wrong


def test_confidence_falls_when_untested_for_a_long_time():
    clock = SimulatedClock()
    v = _trained(clock)
    fresh = v.surprise(30.0)
    clock.advance(v.memory)
    assert v.confidence() == pytest.approx(math.exp(-1.0))
    assert v.surprise(30.0) == pytest.approx(fresh * math.exp(-1.0))
    v.blend_to(ScalarValue(10.0), 0.3)  # tested again: trust comes back
    assert v.confidence() == pytest.approx(1.0)


def test_zero_alpha_changes_nothing():
    v = _trained()
    before = v.to_dict()
    v.blend_to(ScalarValue(1000.0), 0.0)
    assert v.to_dict() == before


# -- emotional tags --------------------------------------------------------------------------------
def test_startle_accumulates_positive_stance_from_food():
    startle = StanceValue(5.0, stance=-1.0)  # run away
    food = StanceValue(100.0, stance=1.0)
    startle.blend_to(food, 0.25)
    assert startle.stance == pytest.approx(-1.0 * 0.75 + 1.0 * 0.25)
    assert startle.perturb(0.0, 0.5) == pytest.approx(0.5 * startle.stance)
    with pytest.raises(ValueError, match="stance"):
        StanceValue(1.0, stance=2.0)


def test_a_restart_takes_what_a_value_learnt_and_the_settings_the_config_now_gives_it():
    """A value saved learnt comes back learnt, with the settings edited in the config since the
    save: before, a leak, its rest, a chain's source or a Gaussian value's memory came back as
    saved, though every other setting is the config's at a restart."""
    leaky = restored(ProcessedValue(1.0, leak=0.5, rest=0.2, momentum=0.3),
                     ProcessedValue(3.0, leak=0.0, rest=0.0, momentum=0.0, velocity=0.4))
    assert (leaky.value, leaky.velocity, leaky.leak, leaky.rest, leaky.momentum) == (3.0, 0.4, 0.5, 0.2, 0.3)
    chain = restored(ChainValue(1.0, source="drink", max_distance=8.0, half_distance=2.0),
                     ChainValue(2.5, distances={"eat": 1.5, "play": 9.0}, source="sleep"))
    assert (chain.value, chain.source, chain.max_distance, chain.half_distance) == (2.5, "drink", 8.0, 2.0)
    assert chain.distances == {"eat": 1.5, "play": 8.0, "drink": 0.0}  # learnt, clamped; the new source 0
    learnt = GaussianValue(4.0, threshold=0.2, reliance=0.2, memory=600.0)
    learnt.reliability = 0.7
    gaussian = restored(GaussianValue(1.0, threshold=0.5, reliance=0.4, memory=60.0), learnt)
    assert (gaussian.value, gaussian.reliability, gaussian.threshold, gaussian.reliance, gaussian.memory) == (
        4.0, 0.7, 0.5, 0.4, 60.0)
    assert restored(ScalarValue(5.0, plasticity=0.0), ScalarValue(2.0)).value == 5.0  # a reward is the config's
