"""curve's platform, its motor half (thesis, "curve (technology)": "a new BodyPose representation
suitable for encoding 3 dimensional splines"): a line body's motor graph measures its poses as
the lines they draw (``[creature.body] metric = "spline"``), and everything built on the graph —
A*, playback, the shipped drawing and curve's creatures — works on it."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra
from scipy.spatial.distance import directed_hausdorff

import installations
from creatures.config import ConfigError
from creatures.events import read_events
from creatures.kinds.moves import head_for
from creatures.kinds.parts import Body, shared_graph, shared_material
from creatures.motor import line_metric, metric, quaternion as quat, spline
from creatures.motor.drawing import drawing_lines, resample
from creatures.motor.graph import MotorGraph
from creatures.motor.metric import MetricWeights, WeightError
from creatures.motor.pose import PoseSet
from creatures.motor.search import PathFinder
from creatures.motor.skeleton import Skeleton
from creatures.runtime.offline import run_offline
from creatures.runtime.schema import load_installation

SPLINE = MetricWeights(content="spline")
ROTATIONS = MetricWeights()
Z = np.array([0.0, 0.0, 1.0])


def hausdorff(a: np.ndarray, b: np.ndarray) -> float:
    return max(directed_hausdorff(a, b)[0], directed_hausdorff(b, a)[0])


def chain(joints: int = 12, bone: float = 0.1) -> Skeleton:
    """A straight line of ``joints`` equal bones along x, as a drawing's body is."""
    offsets = np.zeros((joints, 3))
    offsets[1:, 0] = bone
    return Skeleton(tuple(f"j{i}" for i in range(joints)), np.arange(-1, joints - 1), offsets, np.ones(joints), (f"j{joints - 1}",))


def turned(skeleton: Skeleton, *turns: tuple[int, float]) -> np.ndarray:
    """Rotations of ``skeleton`` with each ``(joint, radians)`` turned about z, the rest straight."""
    rotations = quat.identity((skeleton.joint_count,))
    for joint, angle in turns:
        rotations[joint] = quat.from_axis_angle(Z, angle)
    return rotations


def still(skeleton: Skeleton, rotations: list[np.ndarray]) -> PoseSet:
    """Poses at rest, each its own source (so the time term is the same jump between any two)."""
    n = len(rotations)
    return PoseSet(skeleton, np.stack(rotations), np.zeros((n, skeleton.joint_count, 3)), np.zeros((n, 3)),
                   np.zeros(n), np.arange(n), [f"s{i}" for i in range(n)], [frozenset()] * n)


@pytest.fixture(scope="module")
def scribble():
    inst = load_installation(installations.path("scribble"))
    return inst, inst.specs[0].body.material().graph


def test_equal_joint_angles_are_not_equal_lines():
    """A 20° turn at the root swings the whole line; at the last joint, only its last bone."""
    body = chain()
    poses = still(body, [turned(body), turned(body, (0, 0.35)), turned(body, (10, 0.35))])
    rows = np.array([0])
    rotations = metric.pose_gap(poses, rows, np.array([1, 2]), ROTATIONS)[0]
    lines = metric.pose_gap(poses, rows, np.array([1, 2]), SPLINE)[0]
    assert rotations[0] == pytest.approx(rotations[1], rel=1e-9)
    assert lines[0] > 10 * lines[1]
    # on the line, a whole-body turn by θ costs about θ · Σ masses (the rotations' scale)
    assert lines[0] == pytest.approx(0.35 * body.masses.sum(), rel=0.05)


def test_the_graphs_nearest_pose_is_the_nearest_line():
    """Root turned 20°, the tip's joint 25°: by joint angles the first is nearer the straight
    line, by the line the second, and each graph's cheapest edge from the straight pose says so."""
    body = chain()
    poses = still(body, [turned(body), turned(body, (0, np.radians(20))), turned(body, (10, np.radians(25)))])
    nearest = {}
    for name, weights in (("rotations", ROTATIONS), ("spline", SPLINE)):
        graph = MotorGraph.build(poses, k=1, weights=weights)
        out = {b: cost for (a, b), cost in graph.edges().items() if a == 0}
        nearest[name] = min(out, key=out.get)
    assert nearest == {"rotations": 1, "spline": 2}


def test_a_line_heading_somewhere_is_nearer_it_than_one_heading_away():
    """The transit term on the lines: a root swinging ``0.5 sin(2πt)``; at t = 0 and t = 0.5 the
    line is straight, heading up and heading down; the pose at t = 0.125 is ahead of the first."""
    body = chain()
    times = np.arange(24) / 24
    rotations = np.stack([turned(body, (0, 0.5 * np.sin(2 * np.pi * t))) for t in times])
    poses = PoseSet.animation(body, rotations, np.zeros((24, 3)), times, "swing")
    no_time = MetricWeights(content="spline", time=0.0)
    up, down = metric.edge_costs(poses, np.array([0, 12]), np.array([3, 3]), no_time)
    pose = metric.pose_gap(poses, np.array([0, 12]), np.array([3]), no_time)[:, 0]
    assert pose[0] == pytest.approx(pose[1], abs=1e-9)  # the same straight line, apart from where it heads
    assert down == pytest.approx((1 + no_time.transit) * pose[1])  # heading away: the whole way is left
    assert up < pose[0] * (1 + 0.25 * no_time.transit)  # heading there: most of the way is covered


def test_on_the_shipped_drawing_the_spline_graph_joins_lines_that_look_alike(scribble):
    """By Hausdorff distance — neither metric — the poses an edge joins are closer on the
    spline graph than on the rotation graph of the same frames."""
    _, graph = scribble
    assert graph.weights.content == "spline"  # scribble.toml: metric = "spline"
    points = graph.poses.positions - graph.poses.positions[:, :1]
    apart = {}
    for name, weights in (("rotations", ROTATIONS), ("spline", SPLINE)):
        edges = MotorGraph.build(graph.poses, weights=weights).edges()
        apart[name] = np.mean([hausdorff(points[a], points[b]) for a, b in edges])
    assert apart["spline"] < 0.8 * apart["rotations"]


def test_three_samples_a_bone_measure_what_sixteen_do(monkeypatch):
    """SAMPLES' claim: every distance between the stick figure's poses within 1 %."""
    poses = shared_material()
    every = np.arange(len(poses))
    gaps = {}
    shipped = spline.SAMPLES
    for samples in (shipped, 16):
        monkeypatch.setattr(spline, "SAMPLES", samples)
        copy = poses.subset(every)  # a fresh pose set: its lines are made with these samples
        gaps[samples] = line_metric.pose_difference(copy, every, every)
    apart = gaps[16] > 1e-6
    assert shipped < 16 and apart.sum() > len(poses) ** 2 // 2
    assert (np.abs(gaps[shipped] - gaps[16])[apart] / gaps[16][apart]).max() <= 0.01


@pytest.mark.parametrize("which", ["stick", "drawing"])
def test_astar_on_the_spline_graph_reaches_its_goals_by_the_shortest_path(which, scribble):
    graph = shared_graph(metric="spline") if which == "stick" else scribble[1]
    assert graph.weights.content == "spline"
    finder = PathFinder(graph)
    adj = graph.adjacency
    n = len(graph)
    shortest = dijkstra(csr_matrix((adj.costs, adj.indices, adj.indptr), shape=(n, n)))
    edges = graph.edges()
    rng = np.random.default_rng(3)
    for start, goal in rng.integers(n, size=(60, 2)).tolist():
        path = finder.path(start, [goal])
        route = (start, *path.nodes) if path.nodes[0] != start else path.nodes
        assert route[-1] == goal and all((a, b) in edges for a, b in zip(route, route[1:]))
        assert path.cost == pytest.approx(shortest[start, goal], rel=1e-9, abs=1e-9)
    label = "curl" if which == "drawing" else "low energy"
    assert label in graph.poses.labels[finder.to_label(0, label).goal]


def test_a_drawing_plays_back_on_its_spline_graph_as_drawn(scribble):
    """The scribble's body (spline graph, its joint limits) heads by A* for frames of the
    drawing and arrives within 1 % (Hausdorff) of each drawn line; on the way the line keeps
    its length, which the point-by-point average of two of its lines would not."""
    inst, graph = scribble
    body = Body(np.random.default_rng(0), spec=inst.specs[0].body)
    lines, _, _ = drawing_lines(installations.path("scribble").parent / "bodies" / "line.svg")
    bones = np.linalg.norm(graph.skeleton.offsets[1:], axis=1)
    t = 0.0
    for frame in (40, 10, 25, 6, 24):
        node = int(np.flatnonzero(np.isclose(graph.poses.times, frame * 0.08333))[0])
        assert head_for(body, t, [node])
        lengths = []
        while not body.motor.arrived(t) or t == 0.0:
            t += 0.04
            joints = body.update(t).positions
            lengths.append(np.linalg.norm(np.diff(joints, axis=0), axis=1).sum())
        drawn = (lines[frame] - lines[0][0]) * 0.01  # scale 0.01: user units to metres
        played = resample(body.update(t).positions[:, :2], 4000)  # the bones as the shape they draw
        assert hausdorff(played, drawn) <= 0.01 * np.ptp(drawn, axis=0).max(), frame
        assert np.allclose(lengths, bones.sum(), rtol=1e-6)
    reach, wave = (graph.poses.positions[int(np.flatnonzero(np.isclose(graph.poses.times, f * 0.08333))[0])]
                   for f in (6, 24))  # the last course's two ends
    average = (reach + wave) / 2
    assert np.linalg.norm(np.diff(average, axis=0), axis=1).sum() < 0.7 * bones.sum()


def test_curve_runs_offline_on_spline_graphs(tmp_path):
    inst = load_installation(installations.path("curve"))
    assert [spec.body.metric for spec in inst.specs] == ["spline"] * 3
    inst.settings.output.report = False
    summary = run_offline(inst, tmp_path, duration=8.0)
    events = read_events(tmp_path / "events.jsonl")
    for spec in inst.specs:
        nodes = {e["node"] for e in events if e["kind"] == "motor" and e.get("creature") == spec.name}
        assert len(nodes) >= 3, spec.name  # each body moves about its graph
    assert summary.notes_played >= 3


def test_the_metric_content_is_kept_with_the_graph_and_checked(tmp_path, scribble):
    """Saved and read back, a graph goes on adding poses on the lines; a wrong name is refused."""
    _, graph = scribble
    graph.save(tmp_path / "graph.json")
    again = MotorGraph.load(tmp_path / "graph.json")
    assert again.weights == graph.weights and again.weights.content == "spline"
    assert again.edges() == pytest.approx(graph.edges())
    (new,) = again.add_poses(graph.poses.subset([40])).tolist()
    out = [(a, b) for a, b in again.edges() if a == new]
    a, b = np.array(out).T
    assert [again.edges()[e] for e in out] == pytest.approx(metric.edge_costs(again.poses, a, b, SPLINE).tolist())
    assert not np.allclose(metric.edge_costs(again.poses, a, b, ROTATIONS), metric.edge_costs(again.poses, a, b, SPLINE))
    assert MetricWeights.from_dict(SPLINE.to_dict()) == SPLINE
    assert MetricWeights.from_dict({"pose": 1.0}).content == "rotations"  # graphs saved before the key
    with pytest.raises(WeightError, match="'splines' is not one of 'rotations', 'spline'") as err:
        MetricWeights.from_dict({"content": "splines"})
    assert err.value.key == "content"
    bad = tmp_path / "curve.toml"
    bad.write_text(installations.path("curve").read_text().replace('body = { metric = "spline" }', 'body = { metric = "splines" }', 1))
    with pytest.raises(ConfigError, match=r"curve.toml:\d+: creature.0.body.metric: .*'rotations' or 'spline'"):
        load_installation(bad)
