"""Activation (clique) models: the D_ij update with β/γ compensation (thesis figure 9)."""

from __future__ import annotations

import json

import networkx as nx
import numpy as np
import pytest

from creatures.behaviour.models.activation import ActivationModel


def test_d_ij_update_by_hand():
    model = ActivationModel(["a", "b"], alpha=0.5, max_distance=10.0, max_ratio=4.0)
    model.observe(1.0, [])  # unchanged pattern: not an event
    model.observe(1.0, ["a", "b"])  # 1 s idle, then both start together
    model.deactivate(2.0, "b")
    # Both active for 1 s; each has been inactive 1 s and active 0 s, so the ratio
    # inactive/active is clipped to max_ratio = 4 and β = 0.5⁴.
    d = 10.0 * 0.5**4
    assert model.distance("a", "b") == pytest.approx(d)
    assert model.distance("b", "a") == pytest.approx(d)

    model.deactivate(4.0, "a")
    # a active, b inactive for 2 s; both have ratio 1 so β = γ = α: relax toward M.
    d = 0.5**2 * d + (1 - 0.5**2) * 10.0
    assert model.distance("a", "b") == pytest.approx(d)

    model.activate(6.0, "a")
    # Both inactive for 2 s: a (active 3 s, inactive 1 s) uses γ_a = 0.5^(3/1);
    # b (active 1 s, inactive 3 s) uses γ_b = 0.5^(1/3). D decays toward 0, asymmetrically.
    assert model.distance("a", "b") == pytest.approx(d * 0.5 ** (3 * 2))
    assert model.distance("b", "a") == pytest.approx(d * 0.5 ** (2 / 3))


def test_pairs_never_active_together_stay_at_m():
    model = ActivationModel(["5", "6", "7"], max_distance=10.0)
    for k in range(20):
        model.observe(float(k), ["5"] if k % 2 else ["6", "7"])
    assert model.distance("5", "6") == 10.0 and model.distance("5", "7") == 10.0
    assert model.distance("6", "7") < 1.0


def test_ticking_rate_does_not_matter():
    a = ActivationModel(["x", "y"])
    b = ActivationModel(["x", "y"])
    schedule = [(0.0, ["x", "y"]), (1.3, ["x"]), (2.0, []), (4.5, ["y"]), (5.0, ["x", "y"])]
    for t, on in schedule:
        a.observe(t, on)
    held: list[str] = []
    for t in np.arange(0.0, 5.001, 0.01):
        for when, on in schedule:
            if abs(when - t) < 1e-9:
                held = on
        b.observe(float(round(t, 2)), held)
    np.testing.assert_allclose(a.distances, b.distances)


def _figure_9(rng) -> ActivationModel:
    """Two correlated groups and tuple '8' that is active exactly when nothing else is.

    Everything starts active together for a second, so every pair is tracked from the
    start and the separation below is the Hebbian rule's doing; group members also fire
    spuriously 10% of the time outside their group's turn.
    """
    groups = [["1", "2", "3"], ["4", "5", "6", "7"]]
    model = ActivationModel([*groups[0], *groups[1], "8"], alpha=0.95)
    model.observe(0.0, model.names)
    t = 1.0
    for _ in range(100):
        choice = rng.integers(3)
        members = [*groups[0], *groups[1]]
        inside = groups[choice] if choice < 2 else []
        on = [n for n in members if rng.random() < (0.9 if n in inside else 0.1)]
        model.observe(t, on or ["8"])
        t += float(rng.uniform(0.2, 1.0))
    model.observe(t, [])
    return model


def test_clique_formation_of_figure_9(rng):
    model = _figure_9(rng)
    assert model.met.all()
    cliques = model.cliques(threshold=model.max_distance / 2)
    assert cliques == [["4", "5", "6", "7"], ["1", "2", "3"], ["8"]]
    assert min(model.distance("8", n) for n in model.names if n != "8") > 8.0


def test_cliques_agree_with_networkx(rng):
    model = _figure_9(rng)
    sym = 0.5 * (model.distances + model.distances.T)
    graph = nx.Graph()
    graph.add_nodes_from(model.names)
    for i, j in zip(*np.nonzero((sym < 3.0) & model.met)):
        graph.add_edge(model.names[i], model.names[j])
    expected = sorted(sorted(c, key=model.index) for c in nx.connected_components(graph))
    assert sorted(model.cliques(3.0)) == expected


def test_round_trip_and_bad_state(rng):
    model = _figure_9(rng)
    again = ActivationModel.from_dict(json.loads(json.dumps(model.to_dict())))
    assert again.to_dict() == model.to_dict()
    model.observe(1e3, ["1"])
    again.observe(1e3, ["1"])
    np.testing.assert_array_equal(again.distances, model.distances)
    data = model.to_dict()
    data["distances"] = data["distances"][:-1]
    with pytest.raises(ValueError, match="'distances' has shape"):
        ActivationModel.from_dict(data)


def test_bad_input_is_refused():
    model = ActivationModel(["a"])
    model.activate(2.0, "a")
    with pytest.raises(ValueError, match="time went backwards"):
        model.deactivate(1.0, "a")
    with pytest.raises(KeyError, match="'zz'"):
        model.activate(3.0, "zz")
    with pytest.raises(ValueError):
        ActivationModel(alpha=1.0)


def test_new_tuples_can_join_later():
    model = ActivationModel(["a"])
    model.activate(0.0, "a")
    assert model.add("b") == 1
    model.activate(1.0, "b")
    model.deactivate(3.0, "a")
    assert model.distance("a", "b") < model.max_distance
