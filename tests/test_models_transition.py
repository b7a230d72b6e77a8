"""Forward transition models: p(i→j) with a prior and a recency window."""

from __future__ import annotations

import json

import numpy as np
import pytest

from creatures.behaviour.models.transition import TransitionModel


def test_formula_by_hand():
    model = TransitionModel(["A", "B", "C"], window=10, alpha=0.1)
    for j in ["B", "B", "C", "B"]:
        model.record("A", j)
    # N' = (0, 3, 1): p(A→B) = (3/4 + 0.1)/(1 + 0.1·3)
    assert model.probability("A", "B") == pytest.approx((0.75 + 0.1) / 1.3)
    assert model.probability("A", "A") == pytest.approx(0.1 / 1.3)
    assert model.probability("B", "C") == pytest.approx(1 / 3)  # never left B: uniform prior


def test_rows_sum_to_one(rng):
    names = [f"t{k}" for k in range(7)]
    model = TransitionModel(names, window=5, alpha=0.05)
    for _ in range(200):
        i, j = rng.choice(names, 2)
        model.record(str(i), str(j))
    matrix = model.probabilities()
    np.testing.assert_allclose(matrix.sum(axis=1), 1.0)
    for name in names:
        np.testing.assert_allclose(model.bias(name), matrix[model.index(name)])


def test_follows_a_change_within_the_window():
    model = TransitionModel(["A", "B", "C"], window=10, alpha=0.1)
    for _ in range(50):
        model.record("A", "B")  # A was always followed by B ...
    for k in range(10):
        model.record("A", "C")  # ... then the world changed
        if k < 9:
            assert model.probability("A", "B") > 0.1 / 1.3
    assert model.probability("A", "C") == pytest.approx(1.1 / 1.3)
    assert model.probability("A", "B") == pytest.approx(0.1 / 1.3)  # fully forgotten


def test_window_counts_match_a_plain_recount(rng):
    names = ["a", "b", "c", "d"]
    model = TransitionModel(names, window=6)
    history: dict[str, list[str]] = {n: [] for n in names}
    for _ in range(300):
        i, j = (str(x) for x in rng.choice(names, 2))
        model.record(i, j)
        history[i].append(j)
    for i in names:
        recent = history[i][-6:]
        np.testing.assert_array_equal(
            model.counts[model.index(i)], [recent.count(j) for j in names]
        )


def test_transitions_carrying_different_values_are_detected(rng):
    model = TransitionModel(["sit", "biscuit", "nothing", "beg"], window=40)
    for _ in range(40):
        j = "biscuit" if rng.random() < 0.5 else "nothing"
        model.record("sit", j, value=(100.0 if j == "biscuit" else 0.0) + rng.normal(0, 5))
        k = "biscuit" if rng.random() < 0.5 else "nothing"
        model.record("beg", k, value=50.0 + rng.normal(0, 5))
    n, mean, std = model.value_stats("sit", "biscuit")
    assert n > 10 and mean == pytest.approx(100.0, abs=5.0) and std == pytest.approx(5, rel=0.5)
    assert model.value_contrast("sit") > 0.9  # where "sit" led to decides its value
    assert model.value_contrast("beg") < 0.2  # "beg" earns the same either way
    assert model.value_stats("sit", "beg")[0] == 0


def test_value_contrast_by_hand():
    model = TransitionModel(["i", "x", "y"], window=4)
    for j, v in [("x", 1.0), ("x", 3.0), ("y", 5.0), ("y", None)]:
        model.record("i", j, v)
    # valued: x:{1,3} y:{5}; grand mean 3; total SS = 4+0+4 = 8; between = 2·1 + 1·4 = 6
    assert model.value_contrast("i") == pytest.approx(6 / 8)


def test_round_trip_is_exact(rng):
    names = ["a", "b", "c"]
    model = TransitionModel(names, window=4, alpha=0.2)
    for _ in range(11):
        i, j = (str(x) for x in rng.choice(names, 2))
        model.record(i, j, float(rng.normal()) if rng.random() < 0.7 else None)
    data = json.loads(json.dumps(model.to_dict()))
    again = TransitionModel.from_dict(data)
    assert again.to_dict() == model.to_dict()
    np.testing.assert_array_equal(again.probabilities(), model.probabilities())
    for i in names:
        assert again.value_contrast(i) == model.value_contrast(i)
    model.record("a", "b")
    again.record("a", "b")
    np.testing.assert_array_equal(again.counts, model.counts)


def test_bad_input_is_refused():
    model = TransitionModel(["a"])
    with pytest.raises(KeyError, match="'b'"):
        model.record("a", "b")
    with pytest.raises(ValueError, match="finite"):
        model.record("a", "a", float("nan"))
    data = model.to_dict()
    data["recent"] = [[["ghost", None]]]
    with pytest.raises(ValueError, match=r"recent\['a'\]\[0\] names unknown tuple 'ghost'"):
        TransitionModel.from_dict(data)
    with pytest.raises(ValueError, match="window"):
        TransitionModel(window=0)


@pytest.mark.parametrize("value", [1.0 / 3.0, 0.1, 64.0, 0.0])
def test_a_constant_credit_has_no_value_contrast_whatever_its_last_bits(value):
    """Ten credits of 1/3, half to each of two destinations, read as a contrast of 1 (the
    grounds for fission): their mean is a rounding away from 1/3, and only those bits differed."""
    model = TransitionModel(["a", "b", "c"], window=10)
    for k in range(10):
        model.record("a", "b" if k % 2 else "c", value)
    assert model.value_contrast("a") == 0.0
    model.record("a", "b", value * (1.0 + 1e-3) + 1e-3)  # a real difference still tells
    assert model.value_contrast("a") > 0.0
