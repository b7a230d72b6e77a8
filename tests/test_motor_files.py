"""Motor files: BVH, skeleton descriptions and saved graphs; bad files name file and line."""

from __future__ import annotations

import json

import numpy as np
import pytest

from creatures.motor import quaternion as quat
from creatures.motor.animations import creature_skeleton, strike
from creatures.motor.bvh import BVHError, load_bvh, load_bvh_set, parse_bvh, save_bvh
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
        (("Frame Time: 0.5", "Frame Time: 0"), 18, "frame time must be positive"),
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
    round_trip = Skeleton.from_dict(skeleton.to_dict())
    assert round_trip.names == skeleton.names and np.allclose(round_trip.offsets, skeleton.offsets)


@pytest.mark.parametrize(
    "text, where, message",
    [
        ('{"joints": [\n {"name": "a"},\n {"name": "b", "parent": "zz"}\n]}', ":3: ", "parent 'zz' is not listed before it"),
        ('{"joints": [\n {"name": "a"},\n {"name": "a"}\n]}', ":2: ", "listed twice"),
        ('{"joints": [\n {"name": "a", "offset": [1, 2]}\n]}', ":2: ", "'offset' must be three numbers"),
        ('{"joints": [\n {"name": "a"}\n],\n "end_effectors": ["hand"]}', ":4: ", "end-effector 'hand' is not a joint"),
        ('{"joints": [\n {"name": "a"},,\n]}', ":2: ", "malformed JSON"),
        ('{"joints": []}', ": ", "non-empty list 'joints'"),
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
