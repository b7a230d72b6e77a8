"""Motor-graph edit files and the body's cache (issue 16): edits keyed by labels and source
frames merge whatever their order; bad files, bad takes and stale or corrupt caches are named."""

from __future__ import annotations

import io
import logging
import zipfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from body_fixtures import HIERARCHY, heron_config, heron_frames, write_bvh
import installations
from creatures.config import ConfigError
from creatures.motor.bvh import BVHError, parse_bvh
from creatures.motor.graph_edits import EditError, read_edits
from creatures.motor import metric
from creatures.motor.graph import MotorGraph
from creatures.motor.search import PathFinder
from creatures.motor.material import fingerprint
from creatures.runtime.schema import load_installation


def body_of(config: Path):
    return load_installation(config).specs[0].body.material()


def keyed(graph) -> tuple[dict, dict, dict]:
    """The graph by node names (source@frame), not indices: edges with costs, favours, labels."""
    p = graph.poses
    frame = {s: 1.0 / 20.0 for s in p.sources}
    frame["rest"] = 1.0
    name = [f"{p.sources[s]}@{round(t / frame[p.sources[s]])}" for s, t in zip(p.source_ids, p.times)]
    edges = {(name[a], name[b]): round(c, 9) for (a, b), c in graph.edges().items()}
    return edges, {name[i]: f for i, f in enumerate(graph.favour) if f != 1.0}, {name[i]: l for i, l in enumerate(p.labels)}


def test_two_edit_files_written_apart_merge_in_either_order(tmp_path: Path):
    config = heron_config(tmp_path)
    base = body_of(config).graph
    stamp = fingerprint(base.skeleton)
    write_bvh(tmp_path / "higher.bvh", heron_frames(2.0) * [1, 1, 1, 1, 1, 1, 1, 1.3, 1, 1, 1.5, 1])
    (tmp_path / "alice.toml").write_text(f'''skeleton = "{stamp}"
[[forbid]]
from = "heron@10"
to = "heron@11"
[[favour]]
node = "peck"
multiplier = 0.5
[[blend]]
nodes = "heron@20..30"
file = "higher.bvh"
frames = [0, 10]
weight = 0.5
''')
    (tmp_path / "bob.toml").write_text(f'''skeleton = "{stamp}"
[[add]]
file = "higher.bvh"
labels = {{ stretch = [[5, 9]] }}
[[forge]]
from = "stretch"
to = "rest@0"
[[reweight]]
from = "heron@50"
to = "heron@51"
scale = 3.0
''')
    text = config.read_text()
    config.write_text(text.replace("[[creature.body.animations]]",
                                   'graph_edits = ["alice.toml", "bob.toml"]\n[[creature.body.animations]]'))
    forward = body_of(config).graph
    config.write_text(text.replace("[[creature.body.animations]]",
                                   'graph_edits = ["bob.toml", "alice.toml"]\n[[creature.body.animations]]'))
    backward = body_of(config).graph
    assert keyed(forward) == keyed(backward)
    edges, favour, labels = keyed(forward)
    assert ("heron@10", "heron@11") not in edges and ("heron@10", "heron@11") in keyed(base)[0]
    assert favour and all(v == 0.5 and "peck" in labels[k] for k, v in favour.items())
    assert ("higher@5", "rest@0") in edges  # bob's forged edge from alice-independent new material
    assert len(forward) == len(base) + 40
    p = forward.poses
    blended = p.rotations[(p.source_ids == 0) & (p.times >= 1.0) & (p.times <= 1.5)]
    original = base.poses.rotations[(base.poses.source_ids == 0) & (base.poses.times >= 1.0) & (base.poses.times <= 1.5)]
    assert not np.allclose(blended, original)  # node contents pulled toward the new take …
    from creatures.motor import quaternion as quat
    from creatures.motor.material import Animation, Conventions, read_animation

    take, _ = read_animation(Animation(tmp_path / "higher.bvh"), base.skeleton, Conventions(scale=0.01))
    expected = quat.slerp(original, take.rotations[:11], 0.5)  # … half way, node k toward frame k of 0..10
    assert quat.angle_between(blended, expected).max() < 1e-6  # (arccos near 1: float32-level noise)


def test_disagreeing_edits_are_a_conflict_naming_both(tmp_path: Path):
    config = heron_config(tmp_path)
    stamp = fingerprint(body_of(config).graph.skeleton)
    for who, value in (("a", 0.5), ("b", 2.0)):
        (tmp_path / f"{who}.toml").write_text(f'skeleton = "{stamp}"\n\n[[favour]]\nnode = "heron@3"\nmultiplier = {value}\n')
    config.write_text(config.read_text().replace(
        "[[creature.body.animations]]", 'graph_edits = ["a.toml", "b.toml"]\n[[creature.body.animations]]'))
    with pytest.raises(ConfigError, match=r"b\.toml:3: conflicts with .*a\.toml:3 about the favour of heron@3$"):
        load_installation(config)  # the node as the edits name it (it was the graph's index: 'favour 3')
    for who in ("a", "b"):  # a forge of a forbidden edge
        (tmp_path / f"{who}.toml").write_text(f'skeleton = "{stamp}"\n\n[[{"forbid" if who == "a" else "forge"}]]\n'
                                             'from = "heron@3"\nto = "heron@200"\n')
    with pytest.raises(ConfigError, match=r"b\.toml:3: conflicts with .*a\.toml:3 about the edge heron@3 → heron@200$"):
        load_installation(config)


@pytest.mark.parametrize("edit, message", [
    ('skeleton = "000000000000"\n', r"edit file is for skeleton '000000000000'"),
    ('skeleton = "{s}"\n[[forbid]]\nfrom = "heron@999"\nto = "peck"\n', r"x\.toml:3: node 'heron@999'.*frames 0\.\.239"),
    ('skeleton = "{s}"\n[[favour]]\nnode = "nosuchlabel"\nmultiplier = 1\n', r"x\.toml:3: node 'nosuchlabel'"),
    ('skeleton = "{s}"\n[[favour]]\nnode = "peck"\nmultiplier = -1\n', r"x\.toml:4: \[\[favour\]\] multiplier"),
    ('skeleton = "{s}"\n[[smear]]\nnode = "peck"\n', r"unknown edit 'smear'"),
])
def test_bad_edit_files_are_named_with_their_line(tmp_path: Path, edit: str, message: str):
    config = heron_config(tmp_path)
    (tmp_path / "x.toml").write_text(edit.replace("{s}", fingerprint(body_of(config).graph.skeleton)))
    config.write_text(config.read_text().replace(
        "[[creature.body.animations]]", 'graph_edits = ["x.toml"]\n[[creature.body.animations]]'))
    with pytest.raises(ConfigError, match=message) as error:
        load_installation(config)
    assert "graph_edits" in str(error.value)


def _with_take(tmp_path: Path, text: str) -> Path:
    config = heron_config(tmp_path)
    (tmp_path / "heron.bvh").write_text(text)
    return config


FRAMES = "MOTION\nFrames: 2\nFrame Time: 0.05\n"
ROW = "0 10 0 0 0 0 1 2 3 4 5 6\n"


@pytest.mark.parametrize("text, message", [
    (HIERARCHY + FRAMES + ROW, r"heron\.bvh:\d+: file ends after 1 of 2 frames"),
    (HIERARCHY + "MOTION\nFrames: 0\nFrame Time: 0.05\n", r"heron\.bvh:22: frame count must be a positive"),
    (HIERARCHY + FRAMES + ROW + "0 10 0 0 0 0 1 2 3 4 5\n", r"heron\.bvh:25: frame row has 11 values.*12 channels"),
    (HIERARCHY + FRAMES + ROW + "0 10 0 0 0 0 1 nan 3 4 5 6\n", r"heron\.bvh:25: .*non-finite"),
    (HIERARCHY + FRAMES + ROW + "0 10 0 0 0 0 1 1e300 3 4 5 6\n", r"heron\.bvh:25: .*beyond"),
    (HIERARCHY.replace("JOINT head", "JOINT neck") + FRAMES + ROW * 2, r"heron\.bvh:10: joint 'neck' is named twice"),
    (HIERARCHY[:200], r"heron\.bvh:\d+: unexpected end of file"),
    (HIERARCHY + "MOTION\nFrames: 2\nFrame Time: 1e-300\n" + ROW * 2, r"heron\.bvh:23: frame time must be at least"),
])
def test_bad_takes_are_named_with_their_line(tmp_path: Path, text: str, message: str):
    with pytest.raises(ConfigError, match=message) as error:
        load_installation(_with_take(tmp_path, text))
    assert "heron.toml" in str(error.value) and "animations" in str(error.value)


def test_labels_for_frames_a_take_lacks_are_named(tmp_path: Path):
    config = heron_config(tmp_path)
    config.write_text(config.read_text().replace("[[100, 104]]", "[[100, 400]]"))
    with pytest.raises(ConfigError, match=r"heron\.toml:\d+: creature\.0\.body\.animations\.0\.labels.*"
                                          r"100\.\.400, but .*heron\.bvh has frames 0\.\.239"):
        load_installation(config)


def test_a_restart_loads_the_cache_and_a_stale_or_corrupt_one_is_rebuilt(tmp_path: Path, caplog, monkeypatch):
    config = heron_config(tmp_path)
    first = body_of(config).graph
    (cache,) = (tmp_path / ".motor-cache").glob("*.npz")
    import creatures.motor.body_build as body_build
    built = []
    real = body_build.build
    monkeypatch.setattr(body_build, "build", lambda *a: built.append(1) or real(*a))
    again = body_of(config).graph
    assert not built and again.edges() == first.edges()  # a restart does not rebuild
    # nor search the graph for its A* landmarks: they come with it, as a fresh search makes them
    kept = again.landmark_tables
    assert kept is not None and kept.version == again.version
    fresh = PathFinder(again.copy())
    fresh.prepare()
    assert np.array_equal(fresh.landmarks, kept.nodes) and np.allclose(fresh._forward, kept.forward)
    caplog.set_level(logging.WARNING)
    cache.write_bytes(cache.read_bytes()[:1000])  # truncated
    assert body_of(config).graph.edges() == first.edges() and built == [1]
    assert "corrupt" in caplog.text and str(cache) in caplog.text
    with np.load(cache, allow_pickle=False) as data:  # well-formed, its own key, a node that does not exist
        arrays = {name: data[name] for name in data.files}
    arrays["edge_to"] = arrays["edge_to"].copy()
    arrays["edge_to"][0] = len(first)
    caplog.clear()
    np.savez(cache, **arrays)
    assert body_of(config).graph.edges() == first.edges() and built == [1, 1]
    assert "corrupt" in caplog.text and "outside" in caplog.text
    for name, bad in (("label_ids", -1), ("source_ids", 7)):  # well-formed numbers outside its own tables
        with np.load(cache, allow_pickle=False) as data:
            arrays = {k: data[k] for k in data.files}
        arrays[name] = arrays[name].copy()
        arrays[name][0] = bad
        caplog.clear()
        np.savez(cache, **arrays)
        assert body_of(config).graph.poses.labels == first.poses.labels
        assert "corrupt" in caplog.text and "outside the cache's own tables" in caplog.text
    with zipfile.ZipFile(cache) as archive:  # a damaged shape: numpy would ask for terabytes before reading
        members = {info.filename: archive.read(info) for info in archive.infolist()}
    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(header, {"descr": "<f8", "fortran_order": False, "shape": (10**12, 4)})
    members["rotations.npy"] = header.getvalue() + bytes(64)
    with zipfile.ZipFile(cache, "w") as archive:
        for name, data in members.items():
            archive.writestr(name, data)
    caplog.clear()
    assert body_of(config).graph.poses.labels == first.poses.labels and built == [1, 1, 1, 1, 1]
    assert "corrupt" in caplog.text and "claims" in caplog.text
    built.clear()
    rows = heron_frames()
    rows[:, 10] *= 0.5
    write_bvh(tmp_path / "heron.bvh", rows)  # a source changed: the cache is stale
    changed = body_of(config).graph
    assert built == [1] and "stale" in caplog.text
    assert not np.allclose(changed.poses.rotations, first.poses.rotations)


def test_an_add_in_one_file_keeps_the_edges_another_file_reweights(tmp_path: Path):
    """Bob reweights an edge of the body's own graph; Alice adds a take whose poses are nearer to
    its ends than they were to each other. Merged, the edge is still there, reweighted: adding
    material adds edges, never takes the body's own away (it did: "graph has no edge")."""
    config = heron_config(tmp_path)
    base = body_of(config).graph
    stamp = fingerprint(base.skeleton)
    write_bvh(tmp_path / "near.bvh", heron_frames(6.0) * [1, 1, 1, 1, 1, 1, 1, 1.02, 1, 1, 1.02, 1])
    (tmp_path / "alice.toml").write_text(f'skeleton = "{stamp}"\n[[add]]\nfile = "near.bvh"\n')
    text = config.read_text()
    config.write_text(text.replace("[[creature.body.animations]]",
                                   'graph_edits = ["alice.toml"]\n[[creature.body.animations]]'))
    frames = {s: 1.0 / 20.0 for s in base.poses.sources}
    added = body_of(config).graph
    crowded = MotorGraph.build(added.poses, k=6)  # the nearest poses alone, with the take among them
    lost = [(a, b) for (a, b) in base.edges() if not crowded.has_edge(a, b)]
    assert lost, "the take was meant to crowd some own edges out: make it nearer"
    assert all(added.has_edge(x, y) for x, y in lost)
    a, b = lost[0]
    name = {n: f"{base.poses.sources[base.poses.source_ids[n]]}@{round(base.poses.times[n] / frames['heron'])}"
            for n in (a, b)}
    (tmp_path / "bob.toml").write_text(f'skeleton = "{stamp}"\n[[reweight]]\nfrom = "{name[a]}"\nto = "{name[b]}"\n'
                                       'scale = 3.0\n')
    config.write_text(text.replace("[[creature.body.animations]]",
                                   'graph_edits = ["alice.toml", "bob.toml"]\n[[creature.body.animations]]'))
    merged = body_of(config).graph
    assert merged.has_edge(a, b)
    assert merged.edge_cost(a, b) == pytest.approx(3.0 * float(metric.edge_costs(
        merged.poses, np.array([a]), np.array([b]), merged.weights)[0]))
    assert all(merged.has_edge(x, y) for x, y in base.edges())  # every own edge is kept


def test_two_creatures_on_the_same_takes_with_other_edits_keep_their_own_caches(tmp_path: Path, monkeypatch):
    """One cache file per body as configured: two creatures on the same take, one with an edit,
    each load their own on a restart (they shared one file by the takes' names, and each start
    found the other's there and rebuilt)."""
    import creatures.motor.body_build as body_build

    config = heron_config(tmp_path)
    stamp = fingerprint(body_of(config).graph.skeleton)
    (tmp_path / "cut.toml").write_text(f'skeleton = "{stamp}"\n[[forbid]]\nfrom = "heron@10"\nto = "heron@11"\n')
    text = config.read_text()
    second = text[text.index("[[creature]]"):].replace('name = "heron"', 'name = "egret"').replace(
        "[[creature.body.animations]]", 'graph_edits = ["cut.toml"]\n[[creature.body.animations]]')
    config.write_text(text + "\n" + second)
    specs = load_installation(config).specs
    plain, edited = (spec.body.material().graph for spec in specs)
    assert len(list((tmp_path / ".motor-cache").glob("*.npz"))) == 2
    built = []
    real = body_build.build
    monkeypatch.setattr(body_build, "build", lambda *a: built.append(1) or real(*a))
    again = [spec.body.material().graph for spec in load_installation(config).specs]
    assert not built  # a restart rebuilds neither
    assert again[0].edges() == plain.edges() and again[1].edges() == edited.edges() != plain.edges()


_TOKENS = st.sampled_from(["HIERARCHY", "ROOT", "JOINT", "End", "Site", "{", "}", "OFFSET", "CHANNELS", "3", "6",
                           "Xrotation", "Zposition", "MOTION", "Frames:", "Frame", "Time:", "0.1", "1", "-2",
                           "nan", "1e308", "a", "\n"])


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.one_of(st.lists(_TOKENS, max_size=80).map(" ".join),
                 st.integers(0, 600).map(lambda cut: (HIERARCHY + FRAMES + ROW * 2)[:cut]),
                 st.text(max_size=200)))
def test_fuzzed_bvh_is_parsed_or_refused_with_a_line(text: str):
    try:
        parse_bvh(text, source="fuzz.bvh")
    except BVHError as exc:
        assert str(exc).startswith("fuzz.bvh")


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.one_of(st.text(max_size=300),
                 st.lists(st.sampled_from(['skeleton = "x"', "[[forbid]]", "[[favour]]", "[[add]]", "[[blend]]",
                                           'from = "a@1"', 'to = "b"', "node = 3", "multiplier = -1", "weight = 2",
                                           'frames = [3, 1]', "labels = { a = [[1]] }", 'file = ""', "x = 1",
                                           "[forbid]", "scale = nan"]), max_size=20).map("\n".join)))
def test_fuzzed_edit_files_are_read_or_refused_with_their_name(tmp_path_factory, text: str):
    path = tmp_path_factory.mktemp("edits") / "e.toml"
    path.write_text(text)
    try:
        read_edits(path)
    except EditError as exc:
        assert str(exc).startswith(str(path))


def test_edits_written_in_the_config_apply_and_merge_with_edit_files(tmp_path: Path):
    config = heron_config(tmp_path)
    base = body_of(config).graph
    (tmp_path / "a.toml").write_text(f'skeleton = "{fingerprint(base.skeleton)}"\n\n[[forbid]]\nfrom = "heron@10"\n'
                                     'to = "heron@11"\n')
    config.write_text(config.read_text().replace("[[creature.body.animations]]", '''graph_edits = ["a.toml"]
edits.favour = [{ node = "peck", multiplier = 0.25 }]
edits.forbid = [{ from = "heron@20", to = "heron@21" }]
[[creature.body.animations]]'''))
    edges, favour, labels = keyed(body_of(config).graph)
    assert ("heron@10", "heron@11") not in edges and ("heron@20", "heron@21") not in edges
    assert favour and set(favour.values()) == {0.25} and all("peck" in labels[k] for k in favour)
    config.write_text(config.read_text().replace('node = "peck"', 'node = "preen"'))
    with pytest.raises(ConfigError, match=r"heron\.toml:\d+: creature\.0\.body\.edits\.favour\.0\.node: node 'preen'"):
        load_installation(config)


@pytest.mark.parametrize("written, key", [
    ('edits.favour = [{ node = "peck", multiplier = -0.5 }]', "edits.favour.0.multiplier"),
    ('edits.favor = [{ node = "peck", multiplier = 0.5 }]', "edits.favor"),
])
def test_a_malformed_edit_in_the_config_is_named_at_its_own_line(tmp_path: Path, written: str, key: str):
    """An edit the config writes that cannot be read (a bad value, an unknown operation) is an error
    at its own key's line, as one that names a missing node is (it was the [creature.body] line)."""
    config = heron_config(tmp_path)
    config.write_text(config.read_text().replace("[[creature.body.animations]]", f"{written}\n[[creature.body.animations]]"))
    line = config.read_text().splitlines().index(written) + 1
    with pytest.raises(ConfigError, match=rf"heron\.toml:{line}: creature\.0\.body\.{key.replace('.', '[.]')}: "):
        load_installation(config)


def test_files_written_with_a_byte_order_mark_read_as_without(tmp_path: Path):
    """The config, its clips file and its edit file saved by a Windows editor (a UTF-8 BOM first)
    make the same body as without: the BOM was 'invalid TOML (Invalid statement)' at line 1."""
    graphs = []
    for bom in ("", "\ufeff"):
        (tmp_path / f"bom{len(bom)}").mkdir()
        config = heron_config(tmp_path / f"bom{len(bom)}")
        skeleton = fingerprint(body_of(config).graph.skeleton)
        (config.parent / "heron.labels.toml").write_text(
            f'{bom}bvh = "heron.bvh"\n[[clip]]\nname = "heron"\nframes = [0, 239]\n'
            '[[label]]\nname = "peck"\nframes = [100, 104]\n', encoding="utf-8")
        (config.parent / "e.toml").write_text(f'{bom}skeleton = "{skeleton}"\n[[favour]]\nnode = "peck"\n'
                                              'multiplier = 0.5\n', encoding="utf-8")
        text = config.read_text().split("[[creature.body.animations]]")[0]
        config.write_text(f'{bom}{text}clips = "heron.labels.toml"\ngraph_edits = ["e.toml"]\n', encoding="utf-8")
        graphs.append(keyed(body_of(config).graph))
    assert graphs[1] == graphs[0] and set(graphs[0][1].values()) == {0.5}


def test_a_curves_limbs_are_checked_on_its_shipped_figure(tmp_path: Path):
    text = installations.path("curve").read_text(encoding="utf-8")
    config = tmp_path / "curve.toml"
    config.write_text(text.replace('kind = "curve"\n', 'kind = "curve"\nlimbs = ["wrist_k"]\n', 1), encoding="utf-8")
    with pytest.raises(ConfigError, match=r"curve\.toml:\d+: creature\.0: .*limbs: the \w+ has no joint 'wrist_k' "
                                          r"\(did you mean 'wrist_\w'\?\)"):
        load_installation(config)


def test_a_curves_limbs_are_checked_on_its_body_of_files(tmp_path: Path):
    config = heron_config(tmp_path, kind="curve")
    assert load_installation(config).specs[0].body.custom  # curve takes a body of files like any kind
    config.write_text(config.read_text().replace('kind = "curve"\n', 'kind = "curve"\nlimbs = ["nek"]\n'))
    with pytest.raises(ConfigError, match=r"heron\.toml:\d+: creature\.0\.body: limbs: the body has no joint 'nek' "
                                          r"\(did you mean 'neck'\?\)"):
        load_installation(config)


@pytest.mark.parametrize("old, new, message", [
    ("rest_pose = { neck = [20.0, 0.0, 0.0] }\n", "", r"body\.rest_labels: the body has no pose to rest in"),
    ('effectors = ["head_end"]', 'effectors = ["tail"]', r"body\.effectors.*no joint 'tail'"),
    ("rest_pose = { neck = [20.0, 0.0, 0.0] }", "rest_pose = { neck = [1e300, 0.0, 0.0] }", r"body\.rest_pose"),
    ("scale = 0.01", "scale = 1e-300", r"body\.scale"),
])
def test_a_body_key_that_cannot_make_a_body_is_refused_at_its_line(tmp_path: Path, old: str, new: str, message: str):
    config = heron_config(tmp_path)
    config.write_text(config.read_text().replace(old, new))
    with pytest.raises(ConfigError, match=r"heron\.toml:\d+: creature\.0\." + message):
        load_installation(config)


def test_edits_that_strand_a_pose_or_disagree_are_named_not_raised(tmp_path: Path):
    """Forbids that leave a pose no way out are a config error naming the edit file (it was a
    traceback); a reweight of an edge another file forbids names that file; a mistake in the
    config's own edits is named at the edits key's line."""
    config = heron_config(tmp_path)
    stamp = fingerprint(body_of(config).graph.skeleton)
    (tmp_path / "strand.toml").write_text(f'skeleton = "{stamp}"\n[[forbid]]\nfrom = "heron@239"\nto = "heron@0..239"\n'
                                          '[[forbid]]\nfrom = "heron@239"\nto = "rest@0"\n')
    text = config.read_text()
    config.write_text(text.replace("[[creature.body.animations]]", 'graph_edits = ["strand.toml"]\n'
                                                                   "[[creature.body.animations]]"))
    with pytest.raises(ConfigError, match=r"creature\.0\.body\.graph_edits: .*strand\.toml leave part of the graph "
                                          r"with no way to the rest"):
        load_installation(config)
    (tmp_path / "a.toml").write_text(f'skeleton = "{stamp}"\n[[forbid]]\nfrom = "heron@10"\nto = "heron@11"\n')
    (tmp_path / "b.toml").write_text(f'skeleton = "{stamp}"\n[[reweight]]\nfrom = "heron@10"\nto = "heron@11"\n'
                                     'scale = 2.0\n')
    config.write_text(text.replace("[[creature.body.animations]]", 'graph_edits = ["a.toml", "b.toml"]\n'
                                                                   "[[creature.body.animations]]"))
    with pytest.raises(ConfigError, match=r"b\.toml:\d+: \[\[reweight\]\].*conflicts with .*a\.toml:\d+, which forbids it"):
        load_installation(config)
    lines = text.replace("[[creature.body.animations]]", 'edits.favour = [{ node = "preen", multiplier = 0.5 }]\n'
                                                           "[[creature.body.animations]]")
    config.write_text(lines)
    at = next(n for n, line in enumerate(lines.splitlines(), 1) if line.startswith("edits.favour"))
    with pytest.raises(ConfigError, match=rf"heron\.toml:{at}: creature\.0\.body\.edits\.favour\.0\.node: .*'preen'"):
        load_installation(config)


def test_a_hierarchy_alone_is_a_skeleton(tmp_path: Path):
    config = heron_config(tmp_path)
    (tmp_path / "rig.bvh").write_text(HIERARCHY)  # no MOTION: how a rig is handed over
    text = config.read_text()
    config.write_text(text.replace("[[creature.body.animations]]", 'skeleton = "rig.bvh"\n[[creature.body.animations]]'))
    assert body_of(config).graph.skeleton.names == ("base", "neck", "head", "head_end")


@pytest.mark.parametrize("table, name", [
    ('[[blend]]\nnodes = "a"\nfile = "b.bvh"\nframes = 3\nweight = 0.5\n', "frames"),
    ('[[add]]\nfile = "b.bvh"\nlabels = [1, 2]\n', "labels"),
    ('[[add]]\nfile = "b.bvh"\nlabels = "beg"\n', "labels"),
])
def test_an_edit_field_of_the_wrong_kind_is_refused_at_its_line(tmp_path: Path, table: str, name: str):
    """``frames = 3`` or ``labels = "beg"`` was a TypeError / AttributeError out of the reader
    (``object of type 'int' has no len()``), not an error naming the file and line."""
    path = tmp_path / "e.toml"
    path.write_text(f'skeleton = "x"\n{table}')
    line = next(i for i, text in enumerate(path.read_text().splitlines(), 1) if text.startswith(name))
    with pytest.raises(EditError, match=rf"e\.toml:{line}: .* {name} = "):
        read_edits(path)
