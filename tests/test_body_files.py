"""A body from files (``[creature.body]`` skeleton, animations, limits; issue 16): a creature on a
hand-written three-joint BVH body strikes notes by A*, renders, and stays within its limits."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from body_fixtures import BODY, heron_config, heron_frames, write_bvh
from creatures.events import read_events
from creatures.cli import main
from creatures.config import ConfigError
from creatures.kinds.parts import Body
from creatures.motor.export import played, taken_path
from creatures.runtime.motion_export import exported_body
from creatures.motor.material import Animation, Conventions, read_animation
from creatures.motor import quaternion as quat
from creatures.runtime.offline import run_offline
from creatures.runtime.schema import load_installation
from midi.files import write_notes
from midi.notes import NoteEvent


def test_a_creature_on_a_bvh_body_strikes_notes_by_astar_within_its_limits(tmp_path: Path, monkeypatch):
    inst = load_installation(heron_config(tmp_path, duration=30.0))
    inst.settings.output.frames = True
    shown: list = []
    update = Body.update
    monkeypatch.setattr(Body, "update", lambda self, t: shown.append(update(self, t)) or shown[-1])
    phrase = tmp_path / "phrase.mid"
    write_notes(phrase, [NoteEvent(1.0 + 0.4 * i + 8.0 * r, p, 96, 0, 0.25)
                         for r in range(3) for i, p in enumerate([60, 64, 67, 72, 76])])
    run_offline(inst, tmp_path / "out", midi=phrase, progress=False)
    events = read_events(tmp_path / "out" / "events.jsonl")
    graph = [e for e in events if e["kind"] == "motor graph"]
    assert graph and graph[0]["effector"] == "head_end"
    assert len(graph[0]["hands"]) == 241  # 240 frames of the take and the rest pose
    seeks = [e for e in events if e["kind"] == "selection" and e.get("tuple") == "seek note"]
    notes = [e for e in events if e["kind"] == "note" and e["creature"] == "heron"]
    assert seeks and len(notes) >= 5, (len(seeks), len(notes))
    placed = {round(e["position"][1], 6) for e in events if e["kind"] == "placed"}
    assert len(placed) >= 3  # notes were placed where the beak (not a hand) reaches
    assert sorted((tmp_path / "out" / "frames").glob("*.png"))
    body = inst.specs[0].body.material()
    rotations = np.array([p.rotations for p in shown])
    times = np.array([p.time for p in shown])
    assert len(rotations) > 500
    turned = quat.angle_between(rotations, quat.identity(rotations.shape[1:2]))
    source = quat.angle_between(body.graph.poses.rotations, quat.identity(rotations.shape[1:2])).max(axis=0)
    assert np.all(turned <= np.minimum(body.limits, source) + 1e-9)
    assert turned[:, 1].max() > 0.5  # the neck really moved
    step = quat.angle_between(rotations[1:], rotations[:-1]) / np.maximum(np.diff(times), 1e-12)[:, None]
    assert step[np.diff(times) > 0].max() <= body.graph.timing.max_speed * (1 + 1e-6)


def test_joint_limits_hold_below_what_the_source_shows(tmp_path: Path):
    """A limit tighter than the take itself clips the shown neck at the limit."""
    inst = load_installation(heron_config(tmp_path))
    spec = inst.specs[0].body.model_copy(update={"joint_limits": {"neck": 0.3}})
    spec.resolve(tmp_path)
    body = Body(np.random.default_rng(0), spec=spec)
    angles = []
    for t in np.arange(0.0, 20.0, 0.04):
        if body.motor.arrived(t):
            body.motor.set_course(t, body.motor.course(t, [int(np.random.default_rng(int(t * 25)).integers(241))]))
        angles.append(quat.angle_between(body.update(t).rotations[1], quat.identity(())))
    assert 0.29 < max(angles) <= 0.3 + 1e-9


def test_without_body_keys_the_shipped_figure_is_unchanged():
    body = Body(np.random.default_rng(4))
    assert body.skeleton.joint_count == 19 and body.effector == "hand_r" and body.layers is None


def test_export_motion_round_trips_and_loads_back_as_an_animation(tmp_path: Path):
    """``creatures export-motion``: the path taken, as BVH; imported through the same body it gives
    the same poses (1e-6 rad per joint) at the same frame times, and merges into the graph."""
    config = heron_config(tmp_path, duration=20.0)
    run_offline(load_installation(config), tmp_path / "out", progress=False)
    out = tmp_path / "motion.bvh"
    assert main(["export-motion", str(tmp_path / "out"), "--creature", "heron", str(out), "--fps", "40"]) == 0
    spec = load_installation(config).specs[0]
    graph, _, limits = exported_body(spec)
    nodes, times = taken_path(read_events(tmp_path / "out" / "events.jsonl"), "heron", len(graph))
    assert len(nodes) >= 10
    expected = played(graph, nodes, 40.0, times, limits)
    # the take lasts as long as the body moved and waited, and never turns the neck past its limit
    assert abs(expected.times[-1] - (times[-1] - times[0])) <= 0.2
    neck = quat.angle_between(expected.rotations[:, 1], quat.identity(()))
    assert neck.max() <= spec.body.joint_limits["neck"] + 1e-9
    back, frame_time = read_animation(Animation(out), graph.skeleton, Conventions(scale=0.01))
    assert frame_time == 1.0 / 40.0
    assert len(back) == len(expected) > 40
    np.testing.assert_allclose(back.times, expected.times, rtol=0, atol=1e-12)
    assert quat.angle_between(back.rotations, expected.rotations).max() < 1e-6
    # Loaded back as one more take of the body, its frames are nodes of the graph.
    text = config.read_text() + '\n[[creature.body.animations]]\nfile = "motion.bvh"\n'
    config.write_text(text)
    merged = load_installation(config).specs[0].body.material().graph
    assert len(merged) == len(graph) + len(expected)
    assert "motion" in merged.poses.sources
    motion = merged.poses.source_ids == merged.poses.sources.index("motion")
    assert quat.angle_between(merged.poses.rotations[motion], expected.rotations).max() < 1e-6


@pytest.mark.parametrize("name,creature,figure,joints", [("fetch", "rex", "dog", 31), ("duncan", "duncan", "dog", 31),
                                                        ("wren", "wren", "bird", None)])
def test_export_motion_of_a_shipped_figure_is_that_figures_body(tmp_path: Path, name, creature, figure, joints):
    """A shipped figure's creature (fetch's terrier, Duncan, the wren): the exported take is its
    path on its own figure's graph, not the stick figure's; read back through that figure's
    skeleton it gives the same poses (1e-6 rad) at the same frame times."""
    import installations
    from creatures.kinds.figures import figure_graph

    inst = load_installation(installations.path(name))
    inst.settings.output.report = False
    run_offline(inst, tmp_path / "out", duration=20.0, progress=False)
    out = tmp_path / f"{creature}.bvh"
    assert main(["export-motion", str(tmp_path / "out"), "--creature", creature, str(out), "--fps", "30"]) == 0
    graph, _, limits = exported_body(inst.specs[[s.name for s in inst.specs].index(creature)])
    assert graph is figure_graph(figure)
    nodes, times = taken_path(read_events(tmp_path / "out" / "events.jsonl"), creature, len(graph))
    expected = played(graph, nodes, 30.0, times, limits)
    assert abs(expected.times[-1] - (times[-1] - times[0])) <= 0.2  # its waits too
    back, frame_time = read_animation(Animation(out), graph.skeleton, Conventions())
    assert graph.skeleton.joint_count == (joints or graph.skeleton.joint_count) != 19  # not the stick figure's
    assert len(back) == len(expected) > 30
    again = tmp_path / "from-log.bvh"  # the events log itself (a live run's --log) names the same path
    assert main(["export-motion", str(tmp_path / "out" / "events.jsonl"), "--creature", creature, str(again),
                 "--fps", "30"]) == 0
    assert again.read_bytes() == out.read_bytes()
    assert frame_time == 1.0 / 30.0
    np.testing.assert_allclose(back.times, expected.times, rtol=0, atol=1e-12)
    assert quat.angle_between(back.rotations, expected.rotations).max() < 1e-6
    # Its root too, travel and all: read as it was recorded (root "in place"), every joint is
    # where the creature put it (a fixed-root read stands the take where it began).
    placed, _ = read_animation(Animation(out, root="in place"), graph.skeleton, Conventions())
    np.testing.assert_allclose(placed.positions, expected.positions, rtol=0, atol=1e-6)


def test_export_motion_names_what_is_missing(tmp_path: Path, capsys):
    assert main(["export-motion", str(tmp_path), "--creature", "heron", str(tmp_path / "x.bvh")]) == 2
    assert "no events.jsonl" in capsys.readouterr().err
    config = heron_config(tmp_path, duration=2.0)
    run_offline(load_installation(config), tmp_path / "out", progress=False)
    assert main(["export-motion", str(tmp_path / "out"), "--creature", "egret", str(tmp_path / "x.bvh")]) == 2
    assert "no creature 'egret'" in capsys.readouterr().err
    assert main(["export-motion", str(tmp_path / "out"), "--creature", "heon", str(tmp_path / "x.bvh")]) == 2
    assert "no creature 'heon' (did you mean 'heron'?)" in capsys.readouterr().err
    assert not (tmp_path / "x.bvh").exists()


def test_an_authored_creature_takes_a_body_from_files(tmp_path: Path):
    """``body = true`` is the shipped figure; a ``[creature.body]`` table is a body of its own,
    for authored creatures as for the kinds: ada strikes on the heron's beak."""
    import installations

    heron_config(tmp_path)  # writes heron.bvh
    text = (Path(installations.__file__).parent / "exchange.toml").read_text()  # authored creatures
    marker = "tuples.rest.until.pulse = 2"
    line = next(row for row in text.splitlines() if row.startswith(marker))
    config = tmp_path / "authored.toml"
    config.write_text(text.replace(line, line + "\n" + BODY.format(extra="")))
    phrase = tmp_path / "phrase.mid"
    write_notes(phrase, [NoteEvent(1.0 + 0.4 * i + 8.0 * r, p, 96, 0, 0.25)
                         for r in range(3) for i, p in enumerate([60, 64, 67, 72, 76])])
    inst = load_installation(config)
    assert next(s for s in inst.specs if s.name == "ada").body.material().effectors == ("head_end",)
    run_offline(inst, tmp_path / "out", midi=phrase, duration=30.0, progress=False)
    events = read_events(tmp_path / "out" / "events.jsonl")
    graphs = {e["creature"]: e for e in events if e["kind"] == "motor graph"}
    assert graphs["ada"]["effector"] == "head_end" and graphs["bo"]["effector"] == "hand_r"
    assert len(graphs["ada"]["hands"]) == 241
    assert sum(e["kind"] == "note" and e["creature"] == "ada" for e in events) >= 3


def test_scale_and_a_z_up_file_give_the_same_body_as_y_up_metres(tmp_path: Path):
    """The heron written z-up in centimetres (up_axis = "z", scale = 0.01) is the heron in metres, y up."""
    from body_fixtures import HIERARCHY, write_bvh
    from creatures.motor.material import load_material, load_skeleton

    z_up = (HIERARCHY.replace("OFFSET 0 50 0", "OFFSET 0 0 50").replace("OFFSET 0 40 0", "OFFSET 0 0 40")
            .replace("OFFSET 0 0 30", "OFFSET 0 -30 0"))
    metres = HIERARCHY.replace("OFFSET 0 50 0", "OFFSET 0 0.5 0").replace("OFFSET 0 40 0", "OFFSET 0 0.4 0") \
        .replace("OFFSET 0 0 30", "OFFSET 0 0 0.3")
    rows = np.zeros((3, 12))
    rows[:, 3] = [0.0, 30.0, 60.0]  # the root turns about the file's up axis (Z channel z-up, Y channel y-up)
    rows[:, 7] = [10.0, 20.0, 40.0]  # the neck pitches about x
    y_rows = rows.copy()
    y_rows[:, [3, 5]] = rows[:, [5, 3]]
    y_rows[:, 1], rows[:, 2] = 0.1, 10.0
    bodies = []
    for name, text, table, conventions in (("z", z_up, rows, Conventions(scale=0.01, up_axis="z")),
                                           ("y", metres, y_rows, Conventions())):
        path = write_bvh(tmp_path / f"{name}.bvh", table, hierarchy=text)
        skeleton = load_skeleton(path, conventions)
        bodies.append(load_material(skeleton, [Animation(path)], Conventions(
            conventions.scale, conventions.up_axis, root_motion=True)).poses.positions)
    np.testing.assert_allclose(bodies[0], bodies[1], atol=1e-9)
    assert bodies[1][:, 3, 1].min() > 0.5  # the beak is up in the air, not lying along z


def test_a_walking_body_from_files_carries_its_root_motion(tmp_path: Path):
    """``root_motion = true`` on a user's walking takes (the shipped dog's clips, each written
    out as a BVH file of its own with its recorded travel): the body walks by the takes' own
    steps, so it goes somewhere, its planted paws stay put (≤ 1 cm a frame once in its gait),
    and every take's poses stand where the first began (no teleport to where a take was shot)."""
    from test_bodies import PAWS, WALKS, contact_slides

    from creatures.kinds.figures import BODIES
    from creatures.motor.bvh import load_bvh_set, save_bvh
    from creatures.motor.material import read_clips
    from creatures.motor.programs import ProgramStack, parse_programs

    whole = load_bvh_set(BODIES / "dog.bvh")
    tables = []
    for clip in read_clips(BODIES / "dog.labels.toml"):
        first, last = clip.frames
        save_bvh(tmp_path / f"{clip.name}.bvh", whole.subset(np.arange(first, last + 1)), frame_time=1.0 / 15.0)
        labels = {name: [[a - first, b - first] for a, b in spans] for name, spans in clip.labels.items()}
        labels.setdefault("rest", [[0, 0]])
        rows = ", ".join(f'"{k}" = {v}' for k, v in labels.items())
        tables.append(f'[[creature.body.animations]]\nfile = "{clip.name}.bvh"\nlabels = {{ {rows} }}\n')
    (tmp_path / "walker.toml").write_text(f"""title = "walker"
seed = 1
[[creature]]
name = "rex"
kind = "exchange"
[creature.body]
effectors = ["nose_end"]
root_motion = true
rest_labels = ["rest"]
{"".join(tables)}""", encoding="utf-8")
    inst = load_installation(tmp_path / "walker.toml")
    # exchange's bored manner, written for the stick figure, asks the chest the dog never turns: said, not refused
    assert ["tuples.bored manner.action: it turns chest 17° (the takes never turn it)" in n for n in inst.notes] == [True]
    spec = inst.specs[0].body
    body = Body(np.random.default_rng(4), spec=spec)
    graph = body.graph
    assert body.root_motion is not None and graph.advances.any()
    root = graph.skeleton.parents < 0
    assert np.ptp(graph.poses.roots[:, [0, 2]], axis=0).max() < 1e-9  # in place: travel is in the steps
    stack = ProgramStack(body.motor, parse_programs(WALKS["dog"])["walk"])
    stack.start(0.0)
    paws = [graph.skeleton.index(p) for p in PAWS["dog"]]
    shown = []
    for i in range(int(30.0 * 15)):
        stack.update(i / 15.0)
        shown.append(body.update(i / 15.0).positions)
    shown = np.array(shown)
    assert body.travelled[2] > 5.0 and shown[-1][root][0, 2] - shown[0][root][0, 2] > 5.0  # it walked on
    slides = contact_slides(shown[5 * 15:, paws])
    print(f"walked {body.travelled[2]:.2f} m; planted paws moved at most {slides.max() * 1e3:.1f} mm a frame")
    assert len(slides) > 100 and slides.max() <= 0.01


def dog_as_files(directory: Path, drop: str | None = None) -> str:
    """The shipped dog as a user's files: its BVH copied beside the config, its labels written as
    ``[[creature.body.animations]]`` labels over frame ranges (``drop`` one of them)."""
    import shutil
    import tomllib

    from creatures.kinds.figures import BODIES

    shutil.copy(BODIES / "dog.bvh", directory / "terrier.bvh")
    labelled: dict[str, list[list[int]]] = {}
    for label in tomllib.loads((BODIES / "dog.labels.toml").read_text())["label"]:
        if label["name"] != drop:
            labelled.setdefault(label["name"], []).append(label["frames"])
    labels = ", ".join(f'"{name}" = {ranges}' for name, ranges in labelled.items())
    return f"""
[creature.body]
effectors = ["nose_end"]
rest_labels = ["low energy"]

[[creature.body.animations]]
file = "terrier.bvh"
labels = {{ {labels} }}
"""


def test_duncan_takes_a_body_from_files_and_names_a_trick_it_lacks(tmp_path: Path):
    """Duncan on a body of the user's own (the dog's take and labels, as files): it loads, offers
    its tricks unbidden on that body; a body whose takes label no "beg" is refused at load,
    naming the body's line and the label."""
    import installations
    from creatures.clock import SimulatedClock
    from creatures.config import ConfigError
    from creatures.events import EventLog
    from creatures.runtime.session import Session
    from midi.sinks import MemorySink

    text = installations.path("duncan").read_text()
    head, _, _ = text.partition("[creature.body]")
    config = tmp_path / "terrier.toml"
    config.write_text(head + dog_as_files(tmp_path))
    inst = load_installation(config)
    assert inst.specs[0].body.custom
    session = Session(inst, SimulatedClock(), EventLog(keep_in_memory=100_000), MemorySink())
    dog = session.creatures[0]
    assert dog.body.graph is not None and dog.body.skeleton.joint_count == 31
    for step in range(1, int(40.0 / inst.settings.tick)):
        t = step * inst.settings.tick
        session.clock.advance_to(t)
        session.step(t, int(inst.settings.tick * inst.settings.audio.sample_rate), None, audio=False)
    held = {e["trick"] for e in session.world.log.records if e["kind"] == "trick held"}
    assert held & {"sit", "lie down", "beg"}, held  # it offers tricks unbidden on the body of files
    config.write_text(head + dog_as_files(tmp_path, drop="beg"))
    with pytest.raises(ConfigError, match=r"terrier.toml:\d+: .*the body has no motor label 'beg'"):
        load_installation(config)


def test_export_motion_from_a_state_folder_is_the_logged_path(tmp_path: Path):
    """A live run that kept no events log still keeps its body's path beside its learned state:
    exported from the state folder it is the take exported from the run's log, frame for frame;
    a state file without one is refused naming it."""
    from creatures.clock import SimulatedClock
    from creatures.events import EventLog
    from creatures.runtime.session import Session
    from midi.sinks import MemorySink

    config = heron_config(tmp_path, duration=20.0)
    inst = load_installation(config)
    log = EventLog(tmp_path / "events.jsonl")
    log.emit(0.0, "run", config=str(config))
    session = Session(inst, SimulatedClock(), log, MemorySink())
    tick, rate = inst.settings.tick, inst.settings.audio.sample_rate
    for step in range(1, int(20.0 / tick) + 1):
        session.clock.advance_to(step * tick)
        session.step(step * tick, int(tick * rate), None, audio=False)
    session.save_state(tmp_path / "state")
    log.close()
    assert main(["export-motion", str(tmp_path / "events.jsonl"), "--creature", "heron", str(tmp_path / "a.bvh")]) == 0
    assert main(["export-motion", str(tmp_path / "state"), "--creature", "heron", str(tmp_path / "b.bvh")]) == 0
    logged, kept = ((tmp_path / f"{x}.bvh").read_text().split("MOTION")[1].splitlines()[3:] for x in "ab")
    # the log notes the path every half second, so it ends up to one report short of the state's
    assert len(logged) > 300 and len(logged) <= len(kept) <= len(logged) + 16
    assert logged[:-2] == kept[:len(logged) - 2]
    saved = tmp_path / "state" / "heron.json"
    saved.write_text(saved.read_text().replace('"motion"', '"moved"'))
    assert main(["export-motion", str(tmp_path / "state"), "--creature", "heron", str(tmp_path / "c.bvh")]) == 2


def test_every_effector_strikes_a_note_it_passes(tmp_path: Path):
    """``effectors = ["head_end", "neck"]``: the beak goes to notes by A*, and a note where the
    neck is (far from the beak) is struck by the neck."""
    from creatures.clock import SimulatedClock
    from creatures.events import EventLog
    from creatures.runtime.session import Session
    from midi.sinks import MemorySink

    config = heron_config(tmp_path)
    config.write_text(config.read_text().replace('effectors = ["head_end"]', 'effectors = ["head_end", "neck"]'))
    inst = load_installation(config)
    inst.specs[0].space.strike_radius = 0.05  # a heron's beak and neck are 17 cm apart
    session = Session(inst, SimulatedClock(), EventLog(keep_in_memory=100), MemorySink())
    heron = session.creatures[0]
    assert heron.body.effector == "head_end"
    beak, neck = heron.body.strikers_in_place()
    assert np.linalg.norm(beak - neck) > 2 * heron.notes.spec.strike_radius
    obj = heron.notes.space.place(NoteEvent(0.0, 64, 90, 0, 0.5), neck.copy())
    heron.notes.strike_nearby(1.0)
    assert heron.notes._struck_at.get(id(obj)) == 1.0


def test_frames_asked_of_creatures_without_bodies_say_so_and_list_no_frames(tmp_path: Path):
    """`--frames`/`--video` on a piece none of whose creatures has a body: the run says there
    was nothing to draw, and lists no frames folder or video (it listed both, empty and absent)."""
    from creatures.authored.scaffold import new_installation
    from creatures.body.render import BodyRenderer, RenderUnavailable

    try:
        BodyRenderer(64, 48).close()
    except RenderUnavailable as exc:
        pytest.skip(f"no GL platform: {exc}")
    inst = load_installation(new_installation("plain", tmp_path))
    inst.settings.output.frames = inst.settings.output.video = True
    summary = run_offline(inst, tmp_path / "out", duration=2.0, progress=False)
    assert not {"frames", "video"} & set(summary.files)
    assert any("no creature of this installation has a body" in m for m in summary.messages)


def heron_with_layer(tmp_path: Path, action: str) -> tuple[Path, int]:
    """The authored heron with a second group running ``action`` as a layer, and that line."""
    config = heron_config(tmp_path, kind="authored")
    with config.open("a") as handle:
        handle.write(f"""
[creature.tuples.nod]
action = {action}
until = {{ seconds = 4.0 }}

[creature.groups.layer]
tuples = ["nod"]
alpha = 0.0
""")
    return config, config.read_text().splitlines().index(f"action = {action}") + 1


@pytest.mark.parametrize("action", [
    '{ type = "oscillate", variables = { "nek.x" = 20.0 }, period = 2.0 }',
    '{ type = "sweep", variables = { "nek.x" = [-20.0, 30.0] } }',
    '{ type = "look_at", joints = { nek = 40.0 } }',
    '{ type = "adverb", value = 0.0, examples = [{ at = 0.0, seconds = 1.0, keys = [{ "nek.x" = 20.0 }] }, '
    '{ at = 1.0, seconds = 2.0, keys = [{ "chest.x" = 10.0 }] }] }',
])
def test_a_layer_on_a_body_from_files_names_a_joint_it_lacks_at_load(tmp_path: Path, action: str):
    """A skill's joints are checked against a body of files as against a shipped figure: a typo is
    a config error at the action's line with the nearest joint (it was a traceback at build). An
    adverb leaves out only the stick figure's joints the body lacks (``chest`` here: a manner
    written for the stick figure); a typo'd one was left out too, so it ran without a word."""
    config, line = heron_with_layer(tmp_path, action)
    with pytest.raises(ConfigError, match=rf"heron.toml:{line}: creature\.0\.tuples\.nod\.action: "
                                          r"the body has no joint 'nek' \(did you mean 'neck'\?\)"):
        load_installation(config)


@pytest.mark.parametrize("action", [
    '{ type = "oscillate", variables = { "base.y" = 20.0 }, period = 2.0 }',
    '{ type = "look_at", joints = { neck = 30.0, base = 40.0 } }',
    '{ type = "adverb", value = 0.0, examples = [{ at = 0.0, seconds = 1.0, keys = [{ "base.y" = 0.0 }] }, '
    '{ at = 1.0, seconds = 2.0, keys = [{ "base.y" = 20.0 }] }] }',
])
def test_a_layer_on_a_joint_its_material_never_turns_is_refused_at_load(tmp_path: Path, action: str):
    """The heron's takes never turn its base from rest, and a body never turns a joint further
    than its material does: a layer on ``base`` ran and moved nothing (an adverb on it too, its
    ``motor`` events naming it as driving the base). Refused at the action's line, with the
    joints that do turn."""
    config, line = heron_with_layer(tmp_path, action)
    with pytest.raises(ConfigError) as caught:
        load_installation(config)
    assert str(caught.value) == (
        f"{config}:{line}: creature.0.tuples.nod.action: no frame of the body's material turns the joint 'base' "
        "from rest, and the body never turns a joint further than its material does, so no layer can move it "
        "(joints it turns: neck, head); give it a take or a rest_pose that turns it")


@pytest.mark.parametrize("still_head, action, said", [
    (False, '{ type = "oscillate", variables = { "neck.x" = 120.0 }, period = 2.0 }',
     "it turns neck 120° (takes: at most 68.8°)"),
    (False, '{ type = "sweep", variables = { "neck.x" = [-20.0, 30.0], "head.x" = [0.0, 90.0] } }',
     "it turns head 90° (takes: at most 70.0°)"),
    (True, '{ type = "adverb", value = 0.0, examples = [{ at = 0.0, seconds = 1.0, keys = [{ "head.x" = 20.0 }] }, '
           '{ at = 1.0, seconds = 2.0, keys = [{ "neck.x" = 10.0 }] }] }',
     "it turns head 20° (the takes never turn it)"),
    (False, '{ type = "oscillate", variables = { "neck.x" = 20.0, "voice.gain" = 0.5 }, period = 2.0 }', None),
])
def test_a_layer_asking_more_than_the_takes_turn_is_said_at_load_and_in_the_summary(tmp_path: Path, still_head: bool,
                                                                                    action: str, said: str | None):
    """A body never turns a joint further than its takes do, and a layer asking more (120° of
    a neck its takes and joint_limits hold to 68.8°; an adverb, a manner written for the stick
    figure, nodding a head these takes never turn) ran held there with nothing said. Not
    refused (the rest of the layer moves, and exchange's bored manner on the dog asks its
    chest): said once at load with the joints and ranges, as a ``config`` event and a line of
    the run's summary."""
    if still_head:
        rows = heron_frames()
        rows[:, 10] = 0.0  # the head's nod: now it never turns
        write_bvh(tmp_path / "heron.bvh", rows)
    config, line = heron_with_layer(tmp_path, action)
    inst = load_installation(config)
    assert inst.notes == ([] if said is None else [
        f"{config}:{line}: creature.0.tuples.nod.action: {said}: a body never turns a joint further than its "
        "takes do, so the layer is held there on those joints"])
    if said is not None:
        inst.settings.output.wav = inst.settings.output.report = False
        summary = run_offline(inst, tmp_path / "out", duration=1.0, progress=False)
        assert [m for m in summary.messages if "takes" in m] == inst.notes
        events = read_events(tmp_path / "out" / "events.jsonl")
        assert [e["note"] for e in events if e["kind"] == "config"] == inst.notes


@pytest.mark.parametrize("edits, key, message", [
    ('edits.blend = [{ nodes = "peck", file = "heron.bvh", frames = [0, 4], weight = 2.0 }]', "edits.blend.0.weight",
     "[[blend]] weight = 2.0 is not a weight in [0, 1]"),
    ('edits.blend = [{ nodes = "peck", file = "heron.bvh", frames = [0, 4], weight = 0.5 }, '
     '{ nodes = "heron@100..102", file = "heron.bvh", frames = [0, 2], weight = 0.5 }]', "edits.blend.1",
     "[[blend]] conflicts with edits.blend.0: both blend node heron@100"),
])
def test_an_edit_in_the_config_itself_is_said_at_its_key_not_as_a_file(tmp_path: Path, edits: str, key: str,
                                                                        message: str):
    """The config's own ``edits`` were named as a file that is not there, after the key that
    already names them (``…/[creature.body] edits: blend.0.weight: [[blend]] weight …``): the
    message is now the config's line and key, then what is wrong, and a conflict names the
    other edit by its key."""
    config = heron_config(tmp_path, extra=edits)
    line = config.read_text().splitlines().index(edits) + 1
    with pytest.raises(ConfigError) as caught:
        load_installation(config)
    assert str(caught.value) == f"{config}:{line}: creature.0.body.{key}: {message}"


@pytest.mark.parametrize("extra, key, message", [  # (the rest pose carries the first rest label)
    ('joint_limits = { nek = 1.0 }', "joint_limits.nek", "no joint 'nek' in the body (did you mean 'neck'?)"),
    ('effectors = ["hed_end"]', "effectors.hed_end", "no joint 'hed_end' in the body (did you mean 'head_end'?)"),
    ('rest_pose = { nek = [10.0, 0.0, 0.0] }', "rest_pose.nek", "no joint 'nek' in the body (did you mean 'neck'?)"),
    ('rest_labels = ["still", "pek"]', "rest_labels", "rest label 'pek' is on no frame of the animations (did you mean 'peck'?)"),
    ('edits.favour = [{ node = "pek", multiplier = 0.5 }]', "edits.favour.0.node",
     "no node carries that label (and it is not source@frame) (did you mean 'peck'?)"),
])
def test_a_name_the_body_lacks_is_an_error_with_the_nearest_one(tmp_path: Path, extra: str, key: str, message: str):
    """A typo'd joint or label in [creature.body] says what was meant, at the key's line."""
    config = heron_config(tmp_path)
    written = [row for row in config.read_text().splitlines() if not row.startswith(extra.split(" = ")[0] + " = ")]
    config.write_text("\n".join(written).replace("[creature.body]", f"[creature.body]\n{extra}") + "\n")
    line = config.read_text().splitlines().index(extra) + 1
    with pytest.raises(ConfigError) as caught:
        load_installation(config)
    assert str(caught.value).startswith(f"{config}:{line}: creature.0.body.{key}: ")
    assert str(caught.value).endswith(message)


@pytest.mark.parametrize("old, new, key, message", [
    ("joint_limits = { neck = 1.2, head = 1.3 }", "joint_limits = { neck = 1.2, head = 4.0 }", "joint_limits.head",
     "a limit is a turn from rest in (0, π] radians (got 4.0)"),
    ('file = "heron.bvh"', 'file = "heron.bvh"\nframes = [200, 100]', "animations.0.frames",
     "give [first, last] with first <= last (got [200, 100])"),
])
def test_a_value_out_of_range_is_named_at_its_own_key(tmp_path: Path, old: str, new: str, key: str, message: str):
    """An out-of-range limit or a reversed range is an error at its own key and line, not at the
    table's header with the whole table quoted."""
    config = heron_config(tmp_path)
    config.write_text(config.read_text().replace(old, new))
    line = config.read_text().splitlines().index(new.splitlines()[-1]) + 1
    with pytest.raises(ConfigError) as caught:
        load_installation(config)
    assert str(caught.value) == f"{config}:{line}: creature.0.body.{key}: {message}"


def test_a_take_in_rest_bvh_is_told_the_name_is_the_rest_poses(tmp_path: Path):
    """'rest' is the rest pose's source name, so a take of that stem must be renamed; it was told
    that two animations were named 'rest' when there was one."""
    config = heron_config(tmp_path)
    (tmp_path / "heron.bvh").rename(tmp_path / "rest.bvh")
    config.write_text(config.read_text().replace('file = "heron.bvh"', 'file = "rest.bvh"'))
    with pytest.raises(ConfigError, match=r"creature\.0\.body\.animations\.0\.name: 'rest' names the rest pose's "
                                          r"nodes .*give this take another 'name'"):
        load_installation(config)
    config.write_text(config.read_text().replace('file = "rest.bvh"', 'file = "rest.bvh"\nname = "heron"'))
    assert "heron" in load_installation(config).specs[0].body.material().graph.poses.sources
