"""The rolling-buffer Gaussian model with a prior (thesis figure 8) and its percept."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from creatures.behaviour.action_tuple import DoUntil
from creatures.behaviour.models.gaussian import GaussianModel, GaussianPercept
from creatures.behaviour.state_object import StateObject


def test_starts_as_the_prior_without_an_rng():
    model = GaussianModel(5.0, 2.0, size=64, prior_weight=0.1)
    # Evenly spaced prior quantiles: symmetric around the prior mean, spread close to σ₀.
    assert model.mean == pytest.approx(5.0, abs=1e-12)
    assert model.std == pytest.approx(2.0, rel=0.05)
    assert np.all(np.diff(model.buffer) > 0)


def test_pooled_moments_by_hand():
    model = GaussianModel(0.0, 1.0, size=4, prior_weight=0.25)
    for x in (2.0, 4.0, 2.0, 4.0):
        model.update(x)
    # buffer mean 3, population variance 1; pooled with the prior N(0, 1) at w = 1/4.
    assert model.mean == pytest.approx(0.75 * 3.0 + 0.25 * 0.0)
    assert model.std == pytest.approx(math.sqrt(0.75 * 1.0 + 0.25 * 1.0))


def test_std_is_floored_by_the_prior():
    model = GaussianModel(0.0, 2.0, size=8, prior_weight=0.1)
    for _ in range(8):
        model.update(3.0)  # a buffer with no spread at all
    assert model.std == pytest.approx(math.sqrt(0.1) * 2.0)
    assert model.likelihood(model.mean) == pytest.approx(1.0)


def test_converges_to_the_rewarded_distribution(rng):
    model = GaussianModel(0.0, 1.0, size=200, prior_weight=0.05, rng=rng)
    for x in rng.normal(10.0, 0.5, 2000):
        model.update(float(x))
    assert model.mean == pytest.approx(0.95 * 10.0, abs=0.15)
    expected_std = math.sqrt(0.95 * 0.25 + 0.05 * 1.0)
    assert model.std == pytest.approx(expected_std, rel=0.15)
    draws = np.array([model.sample(rng) for _ in range(4000)])
    assert draws.mean() == pytest.approx(model.mean, abs=0.05)
    assert draws.std() == pytest.approx(model.std, rel=0.05)


def test_fifo_forgets_oldest_first():
    model = GaussianModel(0.0, 1.0, size=3, prior_weight=0.5)
    for x in (100.0, 1.0, 1.0, 1.0):
        model.update(x)
    assert 100.0 not in model.buffer
    assert model.mean == pytest.approx(0.5)


def test_weighted_observation_counts_partially():
    model = GaussianModel(0.0, 1.0, size=2, prior_weight=0.5)
    model.update(0.0)
    model.update(4.0, weight=0.25)
    # buffer mean (1·0 + 0.25·4)/1.25 = 0.8
    assert model.mean == pytest.approx(0.5 * 0.8)


def test_likelihood_is_unnormalised_and_vectorised():
    model = GaussianModel(1.0, 2.0, size=4, prior_weight=1.0)  # pure prior: mean 1, std 2
    xs = np.array([1.0, 3.0, -3.0])
    expected = np.exp(-0.5 * ((xs - 1.0) / 2.0) ** 2)
    np.testing.assert_allclose(model.likelihood(xs), expected)
    assert model.likelihood(1.0) == 1.0


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), -float("inf")])
def test_rejects_non_finite_observations_and_keeps_state(bad):
    model = GaussianModel(0.0, 1.0, size=4)
    before = model.to_dict()
    with pytest.raises(ValueError, match="finite"):
        model.update(bad)
    assert model.to_dict() == before


@pytest.mark.parametrize(
    "kwargs", [dict(prior_std=0.0), dict(size=1), dict(prior_weight=0.0), dict(prior_weight=1.5)]
)
def test_rejects_bad_construction(kwargs):
    args = dict(prior_mean=0.0, prior_std=1.0) | kwargs
    with pytest.raises(ValueError):
        GaussianModel(args.pop("prior_mean"), args.pop("prior_std"), **args)


def test_round_trip_is_exact_through_json(rng):
    model = GaussianModel(3.0, 0.7, size=5, prior_weight=0.2, rng=rng)
    for x in rng.normal(2.0, 1.0, 7):
        model.update(float(x), weight=0.5)
    again = GaussianModel.from_dict(json.loads(json.dumps(model.to_dict())))
    assert again.mean == model.mean and again.std == model.std
    assert again.to_dict() == model.to_dict()
    # Same future: the FIFO order survived, so the same pushes evict the same samples.
    for x in (9.0, -9.0):
        model.update(x)
        again.update(x)
    assert again.mean == model.mean


def test_from_dict_names_the_missing_key():
    data = GaussianModel(0.0, 1.0).to_dict()
    del data["prior_std"]
    with pytest.raises(ValueError, match="prior_std"):
        GaussianModel.from_dict(data)


def test_is_a_duration_model_for_do_until(rng):
    """The "simple duration model": Du samples it at start and teaches it at stop."""
    model = GaussianModel(5.0, 1.0, size=8, prior_weight=0.1)
    du = DoUntil(model)
    for _ in range(8):
        du.begin(0.0, rng)
        du.end(2.0)  # the action actually lasted 2 s every time
    assert model.mean == pytest.approx(0.9 * 2.0 + 0.1 * 5.0)


def test_percept_evaluates_the_state_datum():
    state = StateObject("pitch")
    model = GaussianModel(60.0, 2.0, size=4, prior_weight=1.0)
    percept = GaussianPercept("about C4", state, model)
    assert percept.evaluate(0.0) == 0.0  # no data yet
    state.push(1.0, 62.0)
    assert percept.evaluate(1.5) == pytest.approx(math.exp(-0.5))
    assert percept.evaluate(0.5) == 0.0  # before the first datum


def test_percept_update_models_what_led_up_to_the_action():
    state = StateObject("pitch")
    for t, pitch in enumerate([50.0, 70.0, 55.0]):
        state.push(float(t), pitch)
    model = GaussianModel(0.0, 1.0, size=2, prior_weight=0.5)
    GaussianPercept("p", state, model).update(1.5, value=10.0)
    assert 70.0 in model.buffer  # the datum held at t = 1.5
    looking_back = GaussianModel(0.0, 1.0, size=2, prior_weight=0.5)
    GaussianPercept("q", state, looking_back, lookback=2.0).update(2.0, value=10.0)
    assert 70.0 in looking_back.buffer  # the most salient datum in [0, 2]


def test_acausally_masked_update_learns_each_event_but_not_its_echoes():
    """Two calls 1 s apart, each followed by a weaker echo 0.1 s later, before one reward."""
    state = StateObject("call loudness")
    for t, level in [(0.0, 60.0), (0.1, 40.0), (1.0, 70.0), (1.1, 45.0)]:
        state.push(t, level)
    model = GaussianModel(0.0, 1.0, size=8, prior_weight=0.5)
    GaussianPercept("calls", state, model, lookback=1.5, mask_reach=0.5).update(1.2, value=1.0)
    learnt = set(model.buffer.tolist())
    assert {60.0, 70.0} <= learnt  # both calls taught the model ...
    assert not {40.0, 45.0} & learnt  # ... their echoes did not
    most_salient = GaussianModel(0.0, 1.0, size=8, prior_weight=0.5)
    GaussianPercept("loudest", state, most_salient, lookback=1.5).update(1.2, value=1.0)
    assert {60.0, 70.0} & set(most_salient.buffer.tolist()) == {70.0}  # without masking: the loudest only
