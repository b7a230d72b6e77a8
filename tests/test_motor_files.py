"""Motor files: BVH, skeleton descriptions and saved graphs; bad files name file and line."""

from __future__ import annotations

import copy
import json
import re

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from creatures.motor import quaternion as quat
from creatures.motor.animations import creature_skeleton, strike
from creatures.motor.bvh import BVHError, load_bvh, load_bvh_set, parse_bvh, read_bvh_skeleton, save_bvh
from creatures.motor.graph import MotorGraph
from creatures.motor.skeleton import Skeleton, SkeletonFileError
from creatures.persist import StateFileError

GOOD_BVH = """HIERARCHY
ROOT hips
{
  OFFSET 0 1 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT arm
  {
    OFFSET 1 0 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    End Site
    {
      OFFSET 1 0 0
    }
  }
}
MOTION
Frames: 2
Frame Time: 0.5
0 0 0 0 0 0 0 0 0
1 0 0 0 0 0 90 0 0
"""


def test_bvh_hierarchy_channels_and_euler_order(tmp_path):
    path = tmp_path / "wave.bvh"
    path.write_text(GOOD_BVH)
    skeleton, poses = load_bvh(path)
    assert skeleton.names == ("hips", "arm", "arm_end")
    assert skeleton.end_effectors == ("arm_end",)
    assert [p.time for p in poses] == [0.0, 0.5]
    assert poses[0].source == "wave"
    assert np.allclose(poses[0].end_effector("arm_end"), [2, 1, 0])
    # Frame 2: root moved 1 along x; the arm turned 90° about z, so its tip points up.
    assert np.allclose(poses[1].end_effector("arm_end"), [2, 2, 0], atol=1e-9)


def test_bvh_euler_order_is_intrinsic_in_channel_order():
    text = GOOD_BVH.replace("1 0 0 0 0 0 90 0 0", "0 0 0 0 0 0 90 90 0")
    poses = parse_bvh(text)
    # Zrotation then Xrotation (intrinsic): R = Rz(90°) · Rx(90°).
    expected = quat.multiply(
        quat.from_axis_angle(np.array([0, 0, 1.0]), np.pi / 2), quat.from_axis_angle(np.array([1.0, 0, 0]), np.pi / 2)
    )
    assert quat.distance(poses.rotations[1, 1], expected) < 1e-12


def test_bvh_round_trip_of_a_procedural_animation(tmp_path):
    animation = strike(creature_skeleton())
    save_bvh(tmp_path / "strike.bvh", animation)
    loaded = load_bvh_set(tmp_path / "strike.bvh")
    assert loaded.skeleton.names == animation.skeleton.names
    assert np.allclose(loaded.times, animation.times, atol=1e-6)
    assert np.allclose(loaded.positions, animation.positions, atol=1e-5)


@pytest.mark.parametrize(
    "edit, line, message",
    [
        (("HIERARCHY", "HIERARCHIE"), 1, "expected 'HIERARCHY'"),
        (("OFFSET 1 0 0\n    CHANNELS", "OFFSET 1 zero 0\n    CHANNELS"), 8, "expected a number for arm OFFSET"),
        (("CHANNELS 3 Zrotation", "CHANNELS 3 Wrotation"), 9, "unknown channel 'Wrotation'"),
        (("CHANNELS 3 Zrotation Xrotation Yrotation", "CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation"), 9, "position channels are only supported on the root"),
        (("1 0 0 0 0 0 90 0 0", "1 0 0 0 0 0 90 0"), 20, "frame row has 8 values, the hierarchy declares 9"),
        (("1 0 0 0 0 0 90 0 0", "1 0 0 0 0 0 ninety 0 0"), 20, "non-number"),
        (("Frames: 2", "Frames: 3"), 20, "file ends after 2 of 3 frames"),
        (("Frame Time: 0.5", "Frame Time: 0"), 18, "frame time must be at least"),
        (("    }\n  }\n}", "    }\n  }\n"), 16, "expected JOINT, End Site or '}' in joint 'hips', found 'MOTION'"),
    ],
)
def test_malformed_bvh_names_file_and_line(tmp_path, edit, line, message):
    path = tmp_path / "bad.bvh"
    old, new = edit
    assert old in GOOD_BVH
    path.write_text(GOOD_BVH.replace(old, new, 1))
    with pytest.raises(BVHError) as caught:
        load_bvh(path)
    assert str(caught.value).startswith(f"{path}:{line}: ")
    assert message in str(caught.value)


def test_a_windows_export_with_a_byte_order_mark_reads_as_the_plain_file(tmp_path):
    """A BOM, CRLF line ends and tabs, as a Windows exporter writes: the same take and rig."""
    windows = "\ufeff" + GOOD_BVH.replace("  ", "\t").replace("\n", "\r\n")
    (tmp_path / "plain.bvh").write_text(GOOD_BVH, encoding="utf-8")
    (tmp_path / "windows.bvh").write_bytes(windows.encode("utf-8"))
    plain, exported = load_bvh_set(tmp_path / "plain.bvh"), load_bvh_set(tmp_path / "windows.bvh")
    assert exported.skeleton.names == plain.skeleton.names
    assert np.array_equal(exported.rotations, plain.rotations) and np.array_equal(exported.roots, plain.roots)
    assert read_bvh_skeleton(tmp_path / "windows.bvh").names == plain.skeleton.names


def test_missing_bvh_file_is_named(tmp_path):
    with pytest.raises(BVHError, match="nothing.bvh: cannot read"):
        load_bvh(tmp_path / "nothing.bvh")


def test_shipped_skeleton_loads_as_json_and_toml(tmp_path):
    skeleton = creature_skeleton()
    assert "hand_r" in skeleton.end_effectors
    lines = ['end_effectors = ["hand"]']
    for joint in ({"name": "root", "offset": [0, 0, 0]}, {"name": "hand", "parent": "root", "offset": [0, 1, 0], "mass": 0.5}):
        lines.append("[[joints]]")
        lines += [f"{k} = {json.dumps(v)}" for k, v in joint.items()]
    path = tmp_path / "small.toml"
    path.write_text("\n".join(lines) + "\n")
    small = Skeleton.load(path)
    assert small.names == ("root", "hand") and small.masses.tolist() == [2.0, 0.5]
    path.write_text("\ufeff" + "\n".join(lines) + "\n", encoding="utf-8")  # as a Windows editor saves it
    assert Skeleton.load(path).names == ("root", "hand")
    round_trip = Skeleton.from_dict(skeleton.to_dict())
    assert round_trip.names == skeleton.names and np.allclose(round_trip.offsets, skeleton.offsets)


@pytest.mark.parametrize(
    "text, where, message",
    [
        ('{"joints": [\n {"name": "a"},\n {"name": "b", "parent": "zz"}\n]}', ":3: ", "parent 'zz' is not listed before it"),
        ('{"joints": [\n {"name": "a"},\n {"name": "a"}\n]}', ":3: ", "listed twice"),
        ('{"joints": [\n {"name": "a", "offset": [1, 2]}\n]}', ":2: ", "'offset' must be three numbers"),
        ('{"joints": [\n {"name": "a"}\n],\n "end_effectors": ["hand"]}', ":4: ", "end-effector 'hand' is not a joint"),
        ('{"joints": [\n {"name": "a"},,\n]}', ":2: ", "malformed JSON"),
        ('{"end_effectors": [],\n "joints": []}', ":2: ", "non-empty list 'joints'"),
        ('{"joints": [\n {"name": "a"},\n {"name": "b", "mass": true}\n]}', ":3: ", "'mass' must be a non-negative number"),
    ],
)
def test_malformed_skeleton_json_names_file_and_line(tmp_path, text, where, message):
    path = tmp_path / "creature.json"
    path.write_text(text)
    with pytest.raises(SkeletonFileError) as caught:
        Skeleton.load(path)
    assert str(caught.value).startswith(f"{path}{where}")
    assert message in str(caught.value)


@pytest.mark.parametrize(
    "text, line",
    [('[[joints]]\nname = "a"\nmass = = 2\n', 3), ('[[joints]]\nname = "a"\noffset = [0, 0\n', 3)],
)
def test_malformed_skeleton_toml_names_the_line(tmp_path, text, line):
    path = tmp_path / "creature.toml"
    path.write_text(text)
    with pytest.raises(SkeletonFileError, match=rf"{path}:{line}: malformed TOML"):
        Skeleton.load(path)


@pytest.fixture
def saved_graph(tmp_path):
    graph = MotorGraph.build(strike(creature_skeleton()), k=3)
    path = tmp_path / "graph.json"
    graph.save(path)
    return graph, path


def corrupt(path, old: str, new: str) -> int:
    """Replace the first line containing ``old``; returns that line's number."""
    lines = path.read_text().splitlines()
    number = next(i for i, line in enumerate(lines) if old in line)
    lines[number] = lines[number].replace(old, new)
    path.write_text("\n".join(lines) + "\n")
    return number + 1


def test_graph_file_with_a_bad_edge_names_the_line(saved_graph):
    graph, path = saved_graph
    (a, b), _ = sorted(graph.edges().items())[2]
    line = corrupt(path, f'"{a} {b} ', f'"{a} 9999 ')
    with pytest.raises(StateFileError, match=rf"{path}:{line}: edge .* names a node outside"):
        MotorGraph.load(path)


def test_graph_file_with_a_bad_node_names_the_line(saved_graph):
    graph, path = saved_graph
    rotations = " ".join(f"{x:.9g}" for x in graph.poses.rotations[4].ravel())
    line = corrupt(path, rotations, "1 0 0")
    with pytest.raises(StateFileError, match=rf"{path}:{line}: node 4 is malformed"):
        MotorGraph.load(path)


def test_graph_file_that_is_not_json_or_not_a_graph(saved_graph, tmp_path):
    _, path = saved_graph
    text = path.read_text()
    path.write_text(text[: len(text) // 2])
    with pytest.raises(StateFileError, match=rf"{path}:\d+: malformed JSON"):
        MotorGraph.load(path)
    other = tmp_path / "other.json"
    other.write_text('{"format": "gesture-model", "version": 1}')
    with pytest.raises(StateFileError, match="not a 'motor-graph' file"):
        MotorGraph.load(other)


def rewrite(path, mutate) -> str:
    """Apply ``mutate`` to the saved document and write it back the way ``save_json`` does."""
    document = json.loads(path.read_text())
    mutate(document)
    text = json.dumps(document, indent=1, sort_keys=True)
    path.write_text(text)
    return text


def line_with(text: str, snippet: str) -> int:
    """The one line holding ``snippet``."""
    lines = [n for n, line in enumerate(text.splitlines(), start=1) if snippet in line]
    assert len(lines) == 1, (snippet, lines)
    return lines[0]


def copy_rotations_then(node: int, mutate):
    """Give ``node`` the rotations of node 3 (a string that now appears twice), then ``mutate``."""

    def both(document):
        document["nodes"][node]["rotations"] = document["nodes"][3]["rotations"]
        mutate(document)

    return both


@pytest.mark.parametrize(
    "mutate, snippet, message",
    [
        (lambda d: d["weights"].update(bogus=1), '"bogus"', "unknown metric weight 'bogus'"),
        (lambda d: d["weights"].update(time="x"), '"time": "x"', "metric weight 'time' must be a non-negative"),
        (lambda d: d["weights"].update(horizon=0), '"horizon": 0', "metric weight 'horizon' must be a positive"),
        (lambda d: d["weights"].update(ratios=["1/0"]), '"ratios": [', "ratio '1/0' must be a fraction"),
        (lambda d: d.update(weights=[1]), '"weights": [', "metric weights must be an object"),
        (lambda d: d.update(edges=5), '"edges": 5', "'edges' must be a list"),
        (lambda d: d.update(forbidden="0 1"), '"forbidden": "0 1"', "'forbidden' must be a list"),
        (lambda d: d["edges"].__setitem__(4, "0 1 -1 1"), '"0 1 -1 1"', "needs a finite cost ≥ 0"),
        (lambda d: d["edges"].__setitem__(4, "0 1 0.5 0"), '"0 1 0.5 0"', "finite scale > 0"),
        (lambda d: d["edges"].__setitem__(4, "2 2 0.5 1"), '"2 2 0.5 1"', "joins node 2 to itself"),
        (lambda d: d["nodes"][7].update(favour=-0.25), '"favour": -0.25', "node 7 is malformed: 'favour' must be positive"),
        (lambda d: d["nodes"][7].update(labels="low"), '"labels": "low"', "node 7 is malformed: 'labels' must be a list"),
        (lambda d: d["nodes"][7].update(source=3), '"source": 3', "node 7 is malformed: 'source' must be a string"),
        (copy_rotations_then(30, lambda d: d["nodes"][30].update(time="x")), '"time": "x"', "node 30 is malformed: 'time'"),
        (lambda d: d["nodes"][5].update(rotations=" ".join(["0"] * len(d["nodes"][5]["rotations"].split()))),
         '"rotations": "0 0 0', "node 5 is malformed: 'rotations' holds a zero quaternion"),
        (lambda d: d["skeleton"]["joints"][2].update(mass="x"), '"mass": "x"', "'mass' must be a non-negative number"),
    ],
)
def test_graph_file_errors_name_the_line_of_the_element(saved_graph, mutate, snippet, message):
    _, path = saved_graph
    text = rewrite(path, mutate)
    with pytest.raises(StateFileError) as caught:
        MotorGraph.load(path)
    assert str(caught.value).startswith(f"{path}:{line_with(text, snippet)}: ")
    assert message in str(caught.value)


def test_graph_file_node_missing_a_key_names_the_node_line(saved_graph):
    graph, path = saved_graph
    graph.set_favour(12, 0.123456)  # favour sorts first: the node opens on the line before it
    graph.save(path)
    text = rewrite(path, lambda d: d["nodes"][12].pop("rotations"))
    with pytest.raises(StateFileError, match=rf"{path}:{line_with(text, '0.123456') - 1}: node 12 is malformed: no 'rotations'"):
        MotorGraph.load(path)


json_values = st.recursive(
    st.none() | st.booleans() | st.integers(-5, 10**6) | st.floats(allow_nan=False, allow_infinity=False) | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=6), inner, max_size=3),
    max_leaves=6,
)
bad_tokens = st.sampled_from(["-1", "-0.5", "0", "nan", "inf", "1e999", "x", "", "99999", "3.5", "1 2"])


def paths_of(value, prefix=()):
    """Every path (keys and indices) into a JSON document, the document itself included."""
    yield prefix
    children = value.items() if isinstance(value, dict) else enumerate(value) if isinstance(value, list) else ()
    for key, child in children:
        yield from paths_of(child, (*prefix, key))


@pytest.fixture(scope="module")
def small_graph_document(tmp_path_factory):
    path = tmp_path_factory.mktemp("fuzz") / "graph.json"
    graph = MotorGraph.build(strike(creature_skeleton()).subset(np.arange(6)), k=2)
    graph.forbid(*next(iter(graph.edges())))
    graph.set_favour(2, 0.5)
    graph.save(path)
    document = json.loads(path.read_text())
    paths = [p for p in paths_of(document) if p and p[0] not in ("format", "version")]
    return path, document, paths


def corrupt_at(document, path, action, value, token):
    """Replace, delete or (for strings of numbers) re-spell one token of the value at ``path``."""
    *parents, last = path
    container = document
    for step in parents:
        container = container[step]
    if action == "delete":
        del container[last]
    elif action == "token" and isinstance(container[last], str):
        words = container[last].split() or [""]
        words[len(words) // 2] = token
        container[last] = " ".join(words)
    else:
        container[last] = value


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_fuzzed_graph_files_fail_only_with_a_located_state_file_error(small_graph_document, data):
    """Random corruptions of a saved graph: it loads (and then has no negative cost or favour)
    or raises StateFileError naming the file and a line, never a raw TypeError/KeyError."""
    path, original, paths = small_graph_document
    document = copy.deepcopy(original)
    for _ in range(data.draw(st.integers(1, 3))):
        alive = [p for p in paths if _exists(document, p)]
        corrupt_at(
            document,
            data.draw(st.sampled_from(alive)),
            data.draw(st.sampled_from(["replace", "delete", "token", "token"])),
            data.draw(json_values),
            data.draw(bad_tokens),
        )
    path.write_text(json.dumps(document, indent=1, sort_keys=True))
    try:
        graph = MotorGraph.load(path)
    except StateFileError as exc:
        assert re.match(rf"{re.escape(str(path))}:\d+: ", str(exc)), str(exc)
    else:
        costs = np.array(list(graph.edges().values()))
        assert np.all(np.isfinite(costs) & (costs >= 0.0)) and np.all(graph.favour > 0.0)


def _exists(document, path) -> bool:
    for step in path:
        try:
            document = document[step]
        except (KeyError, IndexError, TypeError):
            return False
    return True
