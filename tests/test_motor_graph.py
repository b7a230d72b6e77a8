"""Motor graph: topology, metric, A*, playback, editing and JSON persistence."""

from __future__ import annotations

from fractions import Fraction

import networkx as nx
import numpy as np
import pytest

from creatures.motor import metric
from creatures.motor import quaternion as quat
from creatures.motor.animations import creature_skeleton, example_animations
from creatures.motor.graph import MotorGraph
from creatures.motor.neighbours import EXACT_BELOW, nearest_edges
from creatures.motor.note_space import exchange_metric
from creatures.motor.playback import Playback
from creatures.motor.pose import PoseSet
from creatures.motor.search import GraphPosition, NoPath, PathFinder
from motor_fixtures import fastest_source_step


@pytest.fixture(scope="module")
def poses() -> PoseSet:
    return PoseSet.concatenate(example_animations(creature_skeleton()))


@pytest.fixture
def graph(poses) -> MotorGraph:
    return MotorGraph.build(poses, k=5)


def as_networkx(graph: MotorGraph, start: GraphPosition | None = None) -> nx.DiGraph:
    g = nx.DiGraph()
    g.add_nodes_from(range(len(graph)))
    for (a, b), cost in graph.edges().items():
        g.add_edge(a, b, weight=cost)
    if start is not None and start.next is not None:
        edge = graph.edge_cost(start.node, start.next)
        g.add_edge("here", start.next, weight=(1 - start.fraction) * edge)
        g.add_edge("here", start.node, weight=start.fraction * edge)
    return g


def check_against_networkx(graph: MotorGraph, rng: np.random.Generator, queries: int = 60) -> None:
    finder = PathFinder(graph, landmarks=4)
    reference = as_networkx(graph)
    for _ in range(queries):
        a, b = (int(x) for x in rng.integers(len(graph), size=2))
        try:
            expected = nx.shortest_path_length(reference, a, b, weight="weight")
        except nx.NetworkXNoPath:
            with pytest.raises(NoPath):
                finder.path(a, [b])
            continue
        path = finder.path(a, [b])
        assert path.cost == pytest.approx(expected, rel=1e-9, abs=1e-12)
        assert path.nodes[0] == a and path.nodes[-1] == b
        walked = sum(graph.edge_cost(x, y) for x, y in zip(path.nodes, path.nodes[1:]))
        assert walked == pytest.approx(path.cost)


def test_topology_links_neighbours_and_successors(graph, poses):
    next_frame = metric.successors(poses)
    for a in range(len(poses)):
        if next_frame[a] >= 0:
            assert graph.has_edge(a, int(next_frame[a]))
    out_degree = np.diff(graph.adjacency.indptr)
    assert out_degree.min() >= 5
    # Edges join different animations too: that is what lets the body move between them.
    sources = poses.source_ids
    assert any(sources[a] != sources[b] for a, b in graph.edges())


def brute_force_nearest(poses: PoseSet, k: int) -> np.ndarray:
    """The k smallest edge costs out of every pose, over all pairs (metric.pairwise)."""
    table = metric.pairwise(poses, np.arange(len(poses)), np.arange(len(poses)), metric.MetricWeights())
    np.fill_diagonal(table, np.inf)
    return np.sort(table, axis=1)[:, :k]


def found_nearest(poses: PoseSet, k: int) -> np.ndarray:
    """The k smallest edge costs out of every pose among the edges nearest_edges proposes."""
    found = nearest_edges(poses, np.arange(len(poses)), np.arange(len(poses)), k, metric.MetricWeights())
    costs = [[] for _ in range(len(poses))]
    for (a, _), cost in found.items():
        costs[a].append(cost)
    return np.array([sorted(c)[:k] for c in costs])


def test_nearest_neighbours_are_exact_on_small_graphs(poses):
    """Below EXACT_BELOW poses the k nearest by the full metric are found exactly (compared
    by cost, so ties may pick either pose); the KD-tree search missed 1.5% here."""
    assert len(poses) <= EXACT_BELOW
    assert np.allclose(found_nearest(poses, 5), brute_force_nearest(poses, 5), rtol=1e-12, atol=0.0)


def test_approximate_nearest_neighbours_stay_close(poses, monkeypatch):
    """Large graphs use KD-tree candidates instead: nearly all of the true nearest."""
    monkeypatch.setattr("creatures.motor.neighbours.EXACT_BELOW", 0)
    exact = brute_force_nearest(poses, 5)
    found = found_nearest(poses, 5)
    assert np.all(found >= exact - 1e-12)  # never better than exact: they are real costs
    assert np.mean(np.isclose(found, exact, rtol=1e-12)) > 0.95


def test_successor_edges_cost_nothing_for_time():
    poses = PoseSet.concatenate(example_animations(creature_skeleton()))
    weights = metric.MetricWeights()
    next_frame = metric.successors(poses)
    a = np.flatnonzero(next_frame >= 0)[:20]
    assert np.all(metric.time_term(poses, a, next_frame[a], weights, next_frame) == 0.0)
    # A nearby but not subsequent frame of the same source is inhibited.
    assert np.all(metric.time_term(poses, a, a + 2, weights, next_frame) > 0.5 * weights.jump)


def test_pairwise_matches_edge_costs(poses):
    rows, cols = np.arange(0, 40, 3), np.arange(5, 60, 7)
    table = metric.pairwise(poses, rows, cols, metric.MetricWeights())
    direct = np.array([[metric.edge_costs(poses, np.array([r]), np.array([c]), metric.MetricWeights())[0] for c in cols] for r in rows])
    assert np.allclose(table, direct)
    # Staying put costs only the local-inhibition penalty: no pose change, no transit.
    w = metric.MetricWeights()
    assert np.allclose(np.diag(metric.pairwise(poses, rows, rows, w)), w.time * w.jump, atol=1e-6)


def test_exchange_metric_favours_low_integer_ratios(poses):
    weights = exchange_metric(limit=4, tolerance=0.05)
    assert Fraction(1, 2) in weights.ratios and Fraction(2, 3) in weights.ratios
    sway = np.flatnonzero(poses.source_ids == poses.sources.index("sway"))
    length = poses.times[sway[-1]] - poses.times[sway[0]]
    next_frame = metric.successors(poses)
    start = sway[0]
    half = sway[np.argmin(np.abs(poses.times[sway] - length / 2))]
    odd = sway[np.argmin(np.abs(poses.times[sway] - 0.37 * length))]
    cost = metric.time_term(poses, np.array([start, start]), np.array([half, odd]), weights, next_frame)
    assert cost[0] < 0.1 * cost[1]


def test_astar_matches_networkx(graph, rng):
    check_against_networkx(graph, rng)


def test_astar_from_the_middle_of_an_edge(graph, rng):
    finder = PathFinder(graph)
    edges = list(graph.edges())
    for _ in range(20):
        a, b = edges[int(rng.integers(len(edges)))]
        start = GraphPosition(a, b, float(rng.uniform(0.05, 0.95)))
        goal = int(rng.integers(len(graph)))
        reference = as_networkx(graph, start)
        expected = nx.shortest_path_length(reference, "here", goal, weight="weight")
        assert finder.path(start, [goal]).cost == pytest.approx(expected)


def test_labels_and_low_energy_goals(graph):
    finder = PathFinder(graph)
    path = finder.to_labels(40, ["strike", "sway left"])
    labels = graph.poses.labels[path.goal]
    assert labels & {"strike", "sway left"}
    reference = as_networkx(graph)
    goals = [i for i, tags in enumerate(graph.poses.labels) if tags & {"strike", "sway left"}]
    best = min(nx.shortest_path_length(reference, 40, g, weight="weight") for g in goals)
    assert path.cost == pytest.approx(best)
    rest = finder.to_rest(path.goal)
    assert "low energy" in graph.poses.labels[rest.goal]
    with pytest.raises(NoPath, match="no node is labelled"):
        finder.to_label(0, "somersault")


def test_playback_is_smooth_and_timed_from_the_source(graph, clock):
    finder = PathFinder(graph)
    path = finder.to_label(GraphPosition(3, 4, 0.5), "strike")
    playback = Playback(graph, path, clock.now())
    frame = 1.0 / 60.0
    times = np.arange(clock.now(), playback.end_time + frame, frame)
    rotations, _ = playback.sample_rotations(times)
    per_frame = quat.angle_between(rotations[1:], rotations[:-1]).max()
    assert per_frame < 1.25 * fastest_source_step(frame)  # no pops: never much faster than the source
    assert quat.distance(rotations[-1], graph.poses.rotations[path.goal]).max() < 1e-9
    check_source_timing(graph, playback)
    # Sampling follows the clock, not the number of calls: half-way in time, the body is
    # between the path nodes whose key times bracket that moment.
    middle = 0.5 * playback.end_time
    position = playback.position(middle)
    k = int(np.searchsorted(playback.key_times, middle, side="right")) - 1
    assert position.node in (3, 4) if k == 0 else position.node == path.nodes[k - 1]
    assert playback.visited(middle) == list(path.nodes[:k])
    assert playback.visited(playback.end_time) == list(path.nodes)


def check_source_timing(graph: MotorGraph, playback: Playback) -> None:
    """Source steps between source steps keep the source's timing; one beside a jump or
    the path's start may only be slowed (its squad curve bends there), never hurried."""
    succ = metric.successors(graph.poses)
    nodes = playback.key_nodes.tolist()
    for k, (a, b) in enumerate(zip(nodes, nodes[1:])):
        if succ[a] == b:
            gap = playback.key_times[k + 2] - playback.key_times[k + 1]
            source = graph.poses.times[b] - graph.poses.times[a]
            inside_a_run = k > 0 and succ[nodes[k - 1]] == a and (k + 2 == len(nodes) or succ[b] == nodes[k + 2])
            if inside_a_run:
                assert gap == pytest.approx(source)
            else:
                assert gap >= source * (1 - 1e-12)


def test_every_edge_keeps_to_the_source_speed(graph):
    """No edge is timed so short that a joint outruns the source animations' fastest turn."""
    pairs = np.array(list(graph.edges()))
    seconds = graph.transit_times(pairs[:, 0], pairs[:, 1])
    turn = quat.angle_between(graph.poses.rotations[pairs[:, 0]], graph.poses.rotations[pairs[:, 1]]).max(axis=1)
    assert np.all(turn <= graph.timing.max_speed * seconds * (1 + 1e-9))
    assert graph.timing.max_speed / 60.0 < 1.25 * fastest_source_step(1.0 / 60.0)


def test_playback_of_many_random_paths_never_jumps(graph):
    """300 seeded paths, a third starting mid-edge: no frame turns a joint faster than the
    smoothness test's limit (an estimated transit once clipped to 1 ms broke this)."""
    rng = np.random.default_rng(300)
    finder = PathFinder(graph)
    frame = 1.0 / 60.0
    limit = 1.25 * fastest_source_step(frame)
    edges = list(graph.edges())
    worst = 0.0
    for i in range(300):
        goal = int(rng.integers(len(graph)))
        if i % 3:
            start = GraphPosition(int(rng.integers(len(graph))))
        else:
            a, b = edges[int(rng.integers(len(edges)))]
            start = GraphPosition(a, b, float(rng.uniform(0.05, 0.95)))
        playback = Playback(graph, finder.path(start, [goal]), 0.0)
        rotations, _ = playback.sample_rotations(np.arange(0.0, playback.end_time + frame, frame))
        worst = max(worst, float(quat.angle_between(rotations[1:], rotations[:-1]).max(initial=0.0)))
        check_source_timing(graph, playback)
    assert worst < limit


def test_json_round_trip(graph, tmp_path):
    graph.forbid(*next(iter(graph.edges())))
    a, b = list(graph.edges())[3]
    graph.reweight(a, b, 2.5)
    graph.set_favour(7, 0.5)
    graph.label(9, "favourite")
    path = tmp_path / "graph.json"
    graph.save(path)
    loaded = MotorGraph.load(path)
    assert loaded.edges() == pytest.approx(graph.edges())
    assert loaded.forbidden == graph.forbidden
    assert loaded.poses.labels == graph.poses.labels
    assert np.allclose(loaded.poses.rotations, graph.poses.rotations, atol=1e-8)
    assert np.allclose(loaded.poses.positions, graph.poses.positions, atol=1e-7)
    assert loaded.favour[7] == 0.5
    # The file is diffable text: one line per edge.
    text = path.read_text()
    assert f'"{a} {b} ' in text


def test_edits_change_paths_and_keep_astar_exact(graph, rng):
    finder = PathFinder(graph)
    path = finder.path(0, [110])
    a, b = path.nodes[0], path.nodes[1]
    graph.forbid(a, b)
    assert not graph.has_edge(a, b)
    detour = finder.path(0, [110])
    assert (a, b) not in zip(detour.nodes, detour.nodes[1:])
    assert detour.cost >= path.cost - 1e-12
    # Making some routes much cheaper must not break the (landmark) heuristic.
    for x, y in list(graph.edges())[::7]:
        graph.reweight(x, y, 0.05)
    check_against_networkx(graph, rng, queries=30)
    graph.connect(0, 110, cost=0.01)
    assert finder.path(0, [110]).nodes == (0, 110)
    with pytest.raises(ValueError):
        graph.connect(3, 3)


def test_new_material_is_patched_in(graph, rng):
    before = len(graph)
    extra = example_animations(creature_skeleton())[0]
    new = graph.add_poses(extra, k=4)
    assert len(graph) == before + len(extra)
    assert np.array_equal(new, np.arange(before, len(graph)))
    finder = PathFinder(graph)
    assert finder.path(0, [int(new[-1])]).goal == new[-1]
    assert finder.path(int(new[0]), [5]).goal == 5
    check_against_networkx(graph, rng, queries=20)


def test_low_energy_annotation_marks_still_poses(graph):
    nodes = graph.annotate_low_energy(speed=0.05, label="still")
    speeds = np.linalg.norm(graph.poses.velocities, axis=-1) @ graph.skeleton.masses / graph.skeleton.masses.sum()
    assert set(nodes.tolist()) == set(np.flatnonzero(speeds < 0.05).tolist())
    assert all("still" in graph.poses.labels[n] for n in nodes)


def test_landmark_heuristic_never_overestimates(graph, rng):
    finder = PathFinder(graph, landmarks=6)
    reverse = as_networkx(graph).reverse()
    for goal in rng.integers(len(graph), size=3).tolist():
        exact = nx.single_source_dijkstra_path_length(reverse, goal, weight="weight")
        bound = finder.heuristic(np.array([goal]))
        for node, distance in exact.items():
            assert bound[node] <= distance + 1e-9
        assert bound[goal] == 0.0
