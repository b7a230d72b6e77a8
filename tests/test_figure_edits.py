"""A shipped figure is a body from files like any other (issue 16): ``[creature.body] clips``
reads an animator's one BVH of named clips, the shipped dog is exactly such a file, and the
generic body keys (edits, joint limits, effectors, rest labels) edit ``figure = "dog"``."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import installations
from creatures.clock import SimulatedClock
from creatures.config import ConfigError
from creatures.events import EventLog
from creatures.kinds.figures import BODIES, figure_graph
from creatures.kinds.parts import Body
from creatures.motor import quaternion as quat
from creatures.motor.material import MaterialError, read_clips
from creatures.motor.pose import LOW_ENERGY
from creatures.runtime.schema import load_installation
from creatures.runtime.session import Session
from midi.sinks import MemorySink

FETCH_BODY = '[creature.body]\nfigure = "dog"\n'


def fetch_with(tmp_path: Path, body: str) -> Path:
    """installations/fetch.toml with its ``[creature.body]`` table replaced by ``body``."""
    text = installations.path("fetch").read_text(encoding="utf-8")
    assert FETCH_BODY in text
    config = tmp_path / "fetch.toml"
    config.write_text(text.replace(FETCH_BODY, body), encoding="utf-8")
    return config


def node_names(graph) -> list[str]:
    """Each node as an edit file names it: ``source@frame`` (frames of the source's file)."""
    p = graph.poses
    return [f"{p.sources[s]}@{round(t * 15.0)}" for s, t in zip(p.source_ids.tolist(), p.times.tolist())]


def test_a_clips_file_of_ones_own_is_the_shipped_dog(tmp_path: Path):
    """The dog's own BVH and clips file, copied as a user's and named by ``clips``, build the
    very graph the shipped figure has: same poses, edges, walking steps and labels."""
    for name in ("dog.bvh", "dog.labels.toml"):
        (tmp_path / name).write_bytes((BODIES / name).read_bytes())
    config = fetch_with(tmp_path, '[creature.body]\nclips = "dog.labels.toml"\neffectors = ["nose_end"]\n')
    mine = load_installation(config).specs[0].body.material().graph
    shipped = figure_graph("dog")
    np.testing.assert_array_equal(mine.poses.rotations, shipped.poses.rotations)
    np.testing.assert_array_equal(mine.poses.roots, shipped.poses.roots)
    np.testing.assert_array_equal(mine.advances, shipped.advances)
    assert mine.poses.labels == shipped.poses.labels and mine.poses.sources == shipped.poses.sources
    assert mine.edges() == pytest.approx(shipped.edges())
    assert mine.advances[:, 2].sum() > 0.5  # the walk clip walks, the others stay in place
    sit = mine.poses.sources.index("sit")
    assert not mine.advances[mine.poses.source_ids == sit].any()
    assert np.ptp(mine.poses.roots[mine.poses.source_ids == sit, 1]) > 0.1  # its hips lower as recorded


def test_the_config_edits_the_shipped_dog(tmp_path: Path):
    """``figure = "dog"`` with edits, a joint limit, an effector and a rest label: the graph
    loses the forbidden edge and gains the forged one, beg rests, the front paw strikes, and
    the neck never turns further than its limit however the body moves."""
    shipped = figure_graph("dog")
    names = node_names(shipped)
    sources = shipped.poses.source_ids
    cut = next((a, b) for a, b in shipped.edges() if sources[a] != sources[b])
    far = next((a, b) for a in range(len(names)) for b in range(len(names) - 1, 0, -1)
               if sources[a] != sources[b] and not shipped.has_edge(a, b))
    config = fetch_with(tmp_path, f'''[creature.body]
figure = "dog"
effectors = ["front_paw_r_end"]
joint_limits = {{ neck = 0.25 }}
rest_labels = ["beg"]
[[creature.body.edits.forbid]]
from = "{names[cut[0]]}"
to = "{names[cut[1]]}"
[[creature.body.edits.forge]]
from = "{names[far[0]]}"
to = "{names[far[1]]}"
''')
    spec = load_installation(config).specs[0].body
    assert spec.custom
    body = Body(np.random.default_rng(3), spec=spec, figure="dog")
    graph = body.graph
    assert not graph.has_edge(*cut) and graph.has_edge(*far)
    assert shipped.has_edge(*cut)  # the shipped figure's shared graph is untouched
    assert set(graph.poses.labelled("beg").tolist()) <= set(graph.poses.labelled(LOW_ENERGY).tolist())
    assert body.effector == "front_paw_r_end"
    neck = graph.skeleton.index("neck")
    source_neck = quat.angle_between(graph.poses.rotations[:, neck], quat.identity(())).max()
    assert source_neck > 0.4  # the limit is tighter than what the material shows
    rng = np.random.default_rng(5)
    angles = []
    for t in np.arange(0.0, 30.0, 0.04):
        if body.motor.arrived(t):
            body.motor.set_course(t, body.motor.course(t, [int(rng.integers(len(graph)))]))
        angles.append(quat.angle_between(body.update(t).rotations[neck], quat.identity(())))
    assert 0.2 < max(angles) <= 0.25 + 1e-9


def test_without_material_keys_the_figure_shares_its_graph(tmp_path: Path):
    spec = load_installation(fetch_with(tmp_path, FETCH_BODY)).specs[0].body
    assert not spec.custom
    assert Body(np.random.default_rng(0), spec=spec, figure="dog").graph is figure_graph("dog")


@pytest.mark.parametrize("body,message", [
    ('figure = "dog"\nanimations = [{ file = "x.bvh" }]', r"body: .*figure = 'dog' and animations both name the body"),
    ('figure = "dog"\nroot_motion = true', r"body: root_motion: the dog's clips file says which of its clips walk"),
    ('joint_limits = { neck = 0.3 }', r"body: joint_limits describe a body of its own, which needs animations"),
    ('figure = "dog"\nscale = 0.01', r"body: scale: the dog's own clips are in metres, y up"),
    ('figure = "dog"\neffectors = ["tail9"]', r"body\.effectors\.tail9: no joint 'tail9' in the body"),
    ('clips = "none.labels.toml"', r"body\.clips: .*none\.labels\.toml:1: cannot read clips file"),
])
def test_a_figure_named_with_what_it_cannot_take_is_refused_at_its_line(tmp_path: Path, body: str, message: str):
    with pytest.raises(ConfigError, match=r"fetch\.toml:\d+: creature\.0\." + message):
        load_installation(fetch_with(tmp_path, f"[creature.body]\n{body}\n"))


def test_duncan_on_an_edited_dog_still_offers_its_tricks(tmp_path: Path):
    """The shipped Duncan with a joint limit on its dog: built from the figure's clips (its
    tricks, rest and beg label checked on the built body), and it offers tricks unbidden."""
    text = installations.path("duncan").read_text(encoding="utf-8")
    config = tmp_path / "duncan.toml"
    config.write_text(text.replace('figure = "dog"\n', 'figure = "dog"\njoint_limits = { tail1 = 0.5 }\n', 1),
                      encoding="utf-8")
    inst = load_installation(config)
    assert inst.specs[0].body.custom
    session = Session(inst, SimulatedClock(), EventLog(keep_in_memory=100_000), MemorySink())
    for step in range(1, int(40.0 / inst.settings.tick)):
        t = step * inst.settings.tick
        session.clock.advance_to(t)
        session.step(t, int(inst.settings.tick * inst.settings.audio.sample_rate), None, audio=False)
    held = {e["trick"] for e in session.world.log.records if e["kind"] == "trick held"}
    assert held & {"sit", "lie down", "beg"}, held


BIRDSONG = """title = "birdsong"
seed = 3
tick = 0.02
duration = 10.0
[audio]
sample_rate = 22050
air = true
[input]
generate = "speech"
[output]
frames = false
[[creature]]
name = "wren"
kind = "soundcreature"
[creature.body]
figure = "bird"
"""


def test_a_mouth_sings_through_its_own_bodys_joints(tmp_path: Path):
    """A sound creature on the bird opens its rib cage with the bird's wings and bends its back
    at the bird's chest (the stick figure's joint indices read on the bird were other joints);
    the amplitude it logs follows that body over its own range. A mouth naming joints the body
    lacks is refused at its key."""
    config = tmp_path / "birdsong.toml"
    config.write_text(BIRDSONG, encoding="utf-8")
    inst = load_installation(config)
    session = Session(inst, SimulatedClock(), EventLog(keep_in_memory=100_000), MemorySink())
    wren = session.creatures[0]
    names = wren.body.skeleton.names
    features = wren.aural.mouth.features
    assert [names[j] for j in features.rib_cage] == ["wing_l", "wing_r"]
    assert [names[j] for j in features.back] == ["pelvis", "chest", "head"]
    for step in range(1, int(8.0 / inst.settings.tick)):
        t = step * inst.settings.tick
        session.clock.advance_to(t)
        session.step(t, int(inst.settings.tick * inst.settings.audio.sample_rate), None, audio=False)
    assert sum(e["kind"] == "voice" for e in session.world.log.records) >= 10
    poses = wren.body.graph.poses
    wings = np.linalg.norm(poses.positions[:, names.index("wing_l")] - poses.positions[:, names.index("wing_r")], axis=-1)
    mouth, spec = wren.aural.mouth, inst.specs[0].mouth
    assert mouth.amplitude(poses.pose(int(wings.argmin()))) == pytest.approx(spec.quiet)  # wings folded: quiet
    assert mouth.amplitude(poses.pose(int(wings.argmax()))) == pytest.approx(spec.loud)  # spread: loud
    config.write_text(BIRDSONG + '[creature.mouth]\nrib_cage = ["elbow_l", "elbow_r"]\n', encoding="utf-8")
    with pytest.raises(ConfigError, match=r"birdsong\.toml:\d+: creature\.0\.mouth\.rib_cage: the body has no joint "
                                          r"'elbow_l'"):
        load_installation(config)


def test_curve_creatures_on_a_body_of_their_own_approach_and_mirror(tmp_path: Path):
    """Two curve creatures on the dog from its clips file (a body from files, not the stick
    figure): its elbows and wrists push the strings, they approach and mirror each other, and
    a mirror goal is a dog pose whose mirror image is the other dog's (or its copy)."""
    from creatures.kinds.curve import MIRROR_TOLERANCE, mirror_nodes

    for name in ("dog.bvh", "dog.labels.toml"):
        (tmp_path / name).write_bytes((BODIES / name).read_bytes())
    text = installations.path("curve").read_text(encoding="utf-8").replace('body = { metric = "spline" }\n', "")
    body = '[creature.body]\nclips = "dog.labels.toml"\neffectors = ["nose_end"]\nmetric = "spline"\n'
    parts = text.split("[[creature]]")
    config = tmp_path / "curve.toml"
    config.write_text(parts[0] + "".join("[[creature]]" + p.rstrip("\n") + "\n" + body + "\n" for p in parts[1:3]),
                      encoding="utf-8")
    inst = load_installation(config)
    inst.settings.output.frames = False
    session = Session(inst, SimulatedClock(), EventLog(keep_in_memory=200_000), MemorySink())
    a, b = session.creatures
    names = a.body.skeleton.names
    assert len(names) == 31 and [names[j] for j in a.limbs] == ["elbow_l", "wrist_l", "elbow_r", "wrist_r"]
    for step in range(1, int(60.0 / inst.settings.tick)):
        t = step * inst.settings.tick
        session.clock.advance_to(t)
        session.step(t, int(inst.settings.tick * inst.settings.audio.sample_rate), None, audio=False)
    chosen = {e["tuple"] for e in session.world.log.records if e["kind"] == "selection"}
    assert {"approach", "mirror"} <= chosen, chosen
    graph = a.body.graph
    mirror = mirror_nodes(graph)
    p = graph.poses.positions
    swap = [names.index(n[:-2] + ("_r" if n.endswith("_l") else "_l")) if n[-2:] in ("_l", "_r") else i
            for i, n in enumerate(names)]
    reflected = np.linalg.norm(p[mirror][:, swap] * [-1.0, 1.0, 1.0] - p, axis=-1).mean(axis=-1)
    copies = mirror == np.arange(len(mirror))
    assert (reflected[~copies] <= MIRROR_TOLERANCE + 1e-12).all() and (~copies).sum() > 50


@pytest.mark.parametrize("old, new, line, message", [
    ("root_motion = true", "root_moton = true", 21, "[[clip]] has no key 'root_moton' (did you mean 'root_motion'?)"),
    ('name = "low energy"\n', 'name = "low energy"\nframe = [0, 30]\n', 12,
     "[[label]] has no key 'frame' (did you mean 'frames'?)"),
    ('bvh = "dog.bvh"\n', 'bvh = "dog.bvh"\nskeleton = "x.bvh"\n', 5,
     "a clips file has no key 'skeleton' (keys: bvh, clip, label)"),
])
def test_a_clips_file_with_a_key_it_does_not_take_is_refused_at_its_line(tmp_path: Path, old: str, new: str,
                                                                         line: int, message: str):
    """A typo in a clips file was read as nothing: ``root_moton = true`` left the walk in place
    with no word. Each key it does not take is refused at its own line, with the nearest."""
    text = (BODIES / "dog.labels.toml").read_text(encoding="utf-8")
    assert old in text
    clips = tmp_path / "dog.labels.toml"
    clips.write_text(text.replace(old, new, 1).replace('bvh = "dog.bvh"', f'bvh = "{BODIES / "dog.bvh"}"'),
                     encoding="utf-8")
    with pytest.raises(MaterialError) as caught:
        read_clips(clips)
    assert str(caught.value) == f"{clips}:{line}: {message}"
