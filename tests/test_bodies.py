"""The shipped bodies (issue 16): a dog and a bird generated as BVH by the project, read back as
motor graphs, walking with root motion without foot sliding, striking notes by A*, within
their joint limits and their source's top speed, and drawn."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from creatures.body.generate import BODIES as GENERATORS
from creatures.body.generate import generate
from creatures.kinds.figures import BODIES, figure_graph
from creatures.kinds.parts import Body
from creatures.motor import quaternion as quat
from creatures.motor.blend import Limits
from creatures.motor.material import MaterialError, read_clips
from creatures.motor.note_space import nearest_note
from creatures.motor.playback import Playback
from creatures.motor.programs import ProgramStack, parse_programs

FRAME = 1.0 / 15.0
"""Seconds between the frames a test looks at (the rendered frame rate of the shipped bodies)."""
CONTACT = 0.005
"""A paw within 5 mm of the ground in two frames running is in contact for both."""
SLIDE = 0.01
"""The issue's bound: a paw in contact moves at most 1 cm per frame."""
PAWS = {"dog": ("hind_paw_l", "hind_paw_r", "front_paw_l", "front_paw_r"), "bird": ("foot_l", "foot_r")}
WALKS = {
    "dog": 'walk: getTo "walk 1"; wait; getTo "walk 2"; wait; getTo "walk 3"; wait; getTo "walk 4"; wait; cycle 0',
    "bird": 'walk: getTo "hop 2"; wait; getTo "hop 3"; wait; getTo "hop 4"; wait; getTo "hop 1"; wait; cycle 0',
}


def test_shipped_files_are_what_the_generator_makes(tmp_path):
    written = generate(tmp_path)
    assert sorted(p.name for p in written) == sorted(
        [f"{name}{suffix}" for name in GENERATORS for suffix in (".bvh", ".labels.toml")] + ["line.svg"])
    for path in written:
        assert path.read_bytes() == (BODIES / path.name).read_bytes(), f"{path.name} differs: regenerate it"


def test_the_dog_has_its_tricks_and_the_bird_its_moves():
    dog, bird = figure_graph("dog").poses, figure_graph("bird").poses
    assert 25 <= dog.skeleton.joint_count <= 31
    for label in ("stand", "walk", "sit", "lie down", "beg", "roll over", "low energy"):
        assert len(dog.labelled(label)), label
    for label in ("perch", "peck", "flap", "hop", "hop 2", "low energy"):
        assert len(bird.labelled(label)), label
    nose = dog.skeleton.index("front_paw_l")
    heights = dog.positions[dog.labelled("beg"), nose, 1]
    assert heights.max() - heights.min() > 0.2  # begs from low to high: a height to shape
    assert dog.sources == ["stand", "walk", "sit", "lie down", "sit to lie down", "beg", "roll over"]


def contact_slides(paws: np.ndarray) -> np.ndarray:
    """Per-frame movement of every paw that is in contact in two frames running ``(T, P, 3)``."""
    planted = (paws[1:, :, 1] < CONTACT) & (paws[:-1, :, 1] < CONTACT)
    return np.linalg.norm(np.diff(paws, axis=0), axis=-1)[planted]


@pytest.mark.parametrize("figure,clip", [("dog", "walk"), ("bird", "hop")])
def test_generated_gait_does_not_slide(figure, clip):
    material = figure_graph(figure)
    poses = material.poses
    frames = np.flatnonzero(poses.source_ids == poses.sources.index(clip))
    travel = np.cumsum(np.concatenate((np.zeros((1, 3)), material.advances[frames][:-1])), axis=0)
    paws = poses.positions[frames][:, [poses.skeleton.index(p) for p in PAWS[figure]]] + travel[:, None]
    assert travel[-1, 2] > 0.1  # it goes somewhere
    slides = contact_slides(paws)
    assert len(slides) >= len(frames)  # paws are planted much of the time
    assert slides.max() <= SLIDE


def walk(figure: str, seconds: float) -> tuple[Body, np.ndarray, list]:
    """A body on ``figure`` walking by motor program; its paws and poses every frame."""
    body = Body(np.random.default_rng(4), figure=figure)
    stack = ProgramStack(body.motor, parse_programs(WALKS[figure])["walk"])
    stack.start(0.0)
    paws, poses = [], []
    index = [body.skeleton.index(p) for p in PAWS[figure]]
    for i in range(int(seconds / FRAME)):
        t = i * FRAME
        stack.update(t)
        pose = body.update(t)
        paws.append(pose.positions[index])
        poses.append(pose)
    return body, np.array(paws), poses


@pytest.mark.parametrize("figure,speed", [("dog", 0.25), ("bird", 0.04)])
def test_a_walking_body_travels_and_its_planted_paws_stay_put(figure, speed):
    body, paws, _ = walk(figure, 30.0)
    assert body.travelled[2] > speed * 25.0  # most of the source's speed, from wherever it started
    slides = contact_slides(paws[int(5.0 / FRAME):])  # once it has got into its gait
    assert len(slides) > 100
    assert slides.max() <= SLIDE


@pytest.mark.parametrize("figure", ["dog", "bird"])
def test_strikes_notes_by_a_star_within_limits_and_top_speed(figure, clock):
    body = Body(np.random.default_rng(2), figure=figure)
    graph = body.graph
    rng = np.random.default_rng(5)
    reach = body.reach()

    class Note:
        def __init__(self, position: np.ndarray) -> None:
            self.position = position

    limits = Limits.of(graph.poses, graph.timing.max_speed)
    for trial in range(6):
        notes = [Note(reach[i] + rng.normal(0.0, 0.01, 3)) for i in rng.choice(len(reach), 3, replace=False)]
        note, path = nearest_note(body.finder, body.motor.position(clock.now()), body.effector, notes, tolerance=0.05)
        body.motor.set_course(clock.now(), path)
        previous = None
        while not body.motor.arrived(clock.now()):
            clock.advance(1.0 / 60.0)
            pose = body.update(clock.now())
            angles = quat.angle_between(pose.rotations, quat.identity(pose.rotations.shape[:1]))
            assert np.all(angles <= limits.range + 1e-6), "a joint left the range its source material shows"
            if previous is not None:
                turn = quat.angle_between(pose.rotations, previous.rotations) / (pose.time - previous.time)
                assert turn.max() <= limits.max_speed + 1e-6, "a joint outran the source's fastest joint"
            previous = pose
        clock.advance(0.1)
        body.update(clock.now())
        assert np.linalg.norm(body.strikers_in_place()[0] - note.position) < 0.08


@pytest.mark.gl
def test_each_body_is_drawn():
    from creatures.body.render import BodyRenderer, RenderUnavailable

    try:
        renderer = BodyRenderer(160, 120, joint_radius=0.015)
    except RenderUnavailable as exc:
        pytest.skip(f"no GL platform: {exc}")
    with renderer:
        for figure in ("dog", "bird"):
            body = Body(np.random.default_rng(0), figure=figure)
            positions = body.update(0.0).positions
            renderer.frame_camera(positions)
            _, depth = renderer.render_with_depth(positions, body.skeleton.parents)
            assert 0.005 < (depth > 0).mean() < 0.6, figure


@pytest.mark.gl
def test_the_camera_follows_a_walking_dog():
    """Rendered frames of a dog walking 30 s (about 8 m): a camera that stays where it framed
    the first frame loses it; the following camera (``[output] follow``, the default) keeps it
    in the middle of the picture."""
    from creatures.body.render import BodyRenderer, RenderUnavailable

    _, _, poses = walk("dog", 30.0)
    first, last = poses[0].positions, poses[-1].positions
    parents = Body(np.random.default_rng(0), figure="dog").skeleton.parents
    assert np.linalg.norm(last[0, [0, 2]] - first[0, [0, 2]]) > 4.0
    seen = {}
    for follow in (False, True):
        try:
            renderer = BodyRenderer(160, 120, joint_radius=0.015, follow=follow)
        except RenderUnavailable as exc:
            pytest.skip(f"no GL platform: {exc}")
        with renderer:
            _, depth = renderer.render_with_depth(first, parents)
            assert (depth > 0).mean() > 0.01
            _, depth = renderer.render_with_depth(last, parents)
            rows, cols = np.nonzero(depth > 0)
            seen[follow] = ((depth > 0).mean(), cols.mean() / 160 if len(cols) else None)
    assert seen[False][0] < 0.002, "without following, the dog has walked out of the picture"
    coverage, middle = seen[True]
    assert coverage > 0.01 and 0.3 < middle < 0.7, seen


@pytest.mark.parametrize("edit,message", [
    (("frames = [0, 30]", "frames = [0, 31]", 1), "clip 'walk' starts at frame 31, the clips before it end at 31"),
    (("frames = [0, 30]", "frames = [0, 9999]", 1), "not within dog.bvh's 271 frames"),
    (('name = "stand"', "name = 3", 1), "needs a string 'name'"),
    (("[[clip]]", "[[clip]", 1), "cannot read clips file"),
    (('bvh = "dog.bvh"', "bvh = 3", 1), "a clips file names its BVH"),
])
def test_a_labels_file_that_does_not_fit_is_an_error_naming_its_line(tmp_path, edit, message):
    text = (BODIES / "dog.labels.toml").read_text(encoding="utf-8")
    old, new, count = edit
    bad = tmp_path / "dog.labels.toml"
    bad.write_text(text.replace(old, new, count), encoding="utf-8")
    (tmp_path / "dog.bvh").write_bytes((BODIES / "dog.bvh").read_bytes())
    with pytest.raises(MaterialError, match=message) as caught:
        read_clips(bad)
    assert str(caught.value).startswith(f"{bad}:")
    line = int(str(caught.value).split(":")[1])
    assert line >= 1


def test_playback_of_a_walk_path_keeps_source_timing(clock):
    """The walk plays at its source's pace: one gait quarter per 0.2 s (3 frames at 15 fps)."""
    body = Body(np.random.default_rng(0), figure="dog")
    poses = body.graph.poses
    first = int(poses.labelled("walk 1")[0])
    path = body.finder.path(first, list(poses.labelled("walk 2")))
    assert path.nodes == (first, first + 1, first + 2, first + 3)
    playback = Playback(body.graph, path, 0.0)
    assert playback.end_time == pytest.approx(0.2, abs=0.02)


@pytest.mark.parametrize("name,figure,travel", [("wren", "bird", 0.5), ("fetch", "dog", 1.0)])
def test_a_shipped_body_strikes_the_notes_it_hears_and_walks_without_sliding(name, figure, travel):
    """The shipped installation on each new body, run as ``creatures offline`` runs it: its
    effector (the wren's beak, the dog's nose) strikes heard notes placed in space (A* in note
    space), it walks about by root motion (the figure the run shows travels), no planted foot
    of the shown figure moves more than 1 cm between two ticks of the run while it walks (two
    ticks on steps of its gait), nor at any other time (between tricks, off the gait: playback
    paces a move so no planted paw slides faster than ``metric.CONTACT_SPEED``, and the dog's
    generated clips step their paws to new places), and no joint leaves the range of its source
    or turns faster than the source's fastest joint."""
    from creatures.clock import SimulatedClock
    from creatures.events import EventLog
    from creatures.runtime.inputs import phrase_notes
    from creatures.runtime.schema import load_installation
    from creatures.runtime.session import Session
    from midi.sinks import MemorySink

    import installations

    inst = load_installation(installations.path(name))
    clock = SimulatedClock()
    log = EventLog(keep_in_memory=100_000)
    session = Session(inst, clock, log, MemorySink())
    for note in phrase_notes(rng=session.input_rng):
        session.world.inject(note)
    creature = session.creatures[0]
    assert creature.body.figure == figure
    feet = [creature.body.skeleton.index(foot) for foot in PAWS[figure]]
    limits = Limits.of(creature.body.graph.poses, creature.body.graph.timing.max_speed)
    graph = creature.body.graph
    gait = graph.advances.any(axis=1)  # nodes whose next source frame carries the body on
    tick, shown, turns, stepping = inst.settings.tick, [], [], []
    for step in range(1, int(60.0 / tick)):
        t = step * tick
        clock.advance_to(t)
        session.step(t, int(tick * inst.settings.audio.sample_rate), None, audio=False)
        shown.append(creature.figure()[0])
        turns.append(creature.body.pose.rotations)
        stepping.append(on_gait_step(creature.body.motor.playback, t, gait, graph.timing.next_frame))
    shown, turns = np.array(shown), np.array(turns)
    angles = quat.angle_between(turns, quat.identity(turns.shape[:2]))
    assert np.all(angles <= limits.range + 1e-6), "a joint left the range its source material shows"
    speeds = quat.angle_between(turns[1:], turns[:-1]) / tick
    assert speeds.max() <= limits.max_speed + 1e-6, "a joint outran the source's fastest joint"
    played = [e for e in log.records if e["kind"] == "note" and e["creature"] == creature.name]
    roots = shown[:, creature.body.skeleton.parents < 0][:, 0]
    stepping = np.array(stepping)
    walking = stepping[1:] & stepping[:-1]  # two ticks running in the gait
    slides = np.concatenate([contact_slides(shown[[i, i + 1]][:, feet]) for i in np.flatnonzero(walking)] + [[]])
    anywhere = contact_slides(shown[:, feet])
    print(f"{name}: {len(played)} notes, travelled {np.linalg.norm(roots[-1] - roots[0]):.2f} m, "
          f"{walking.sum()} of {len(walking)} ticks on gait steps; planted feet moved at most "
          f"{slides.max(initial=0) * 1e3:.1f} mm a tick there ({len(slides)} contacts), "
          f"{anywhere.max() * 1e3:.1f} mm at any time ({len(anywhere)} contacts)")
    assert len(played) >= 10  # the effector strikes notes
    assert np.linalg.norm((roots[:, [0, 2]] - roots[0, [0, 2]]), axis=1).max() > travel  # the shown body walked
    assert walking.sum() >= 60  # enough steps on the gait for the slide measure below to mean something
    if figure == "dog":  # the bird's hop lifts its feet: its contacts are all between hops
        assert len(slides) > 100 and slides.max() <= SLIDE
    assert len(anywhere) > 500 and anywhere.max() <= SLIDE


def on_gait_step(playback: Playback | None, t: float, gait: np.ndarray, following: np.ndarray) -> bool:
    """Whether the course at ``t`` is on a step of the gait itself: between two keys that are
    successive source frames of a node that carries the body on."""
    if playback is None:
        return False
    segment = int(np.searchsorted(playback.key_times, t, side="left"))
    if not 1 <= segment < len(playback.key_times):
        return False
    to = int(playback.key_nodes[segment - 1])
    start = playback.path.start
    before = (start.node if start.next is None else -1) if segment == 1 else int(playback.key_nodes[segment - 2])
    return before >= 0 and bool(gait[before]) and int(following[before]) == to


def test_an_authored_body_table_checks_labels_against_its_figure(tmp_path):
    from creatures.config import ConfigError
    from creatures.runtime.schema import load_installation

    import installations

    text = installations.path("wren").read_text(encoding="utf-8").replace('labels = ["flap"]', 'labels = ["sway left"]')
    (tmp_path / "wren.toml").write_text(text, encoding="utf-8")
    with pytest.raises(ConfigError, match="the body has no motor label 'sway left'"):
        load_installation(tmp_path / "wren.toml")
    text = text.replace('figure = "bird"', 'figure = "cat"')
    (tmp_path / "wren.toml").write_text(text, encoding="utf-8")
    with pytest.raises(ConfigError, match="figure"):
        load_installation(tmp_path / "wren.toml")


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.lists(st.sampled_from([
    "[[clip]]", "[[label]]", 'name = "walk"', "name = 3", "frames = [0, 30]", "frames = [31, 260]",
    "frames = [5, 2]", "frames = [0.5, 3]", "frames = 7", "frames = [-1, 4]", "root_motion = true",
    'root_motion = "yes"', "clip = 3", "label = [1, 2]", "[clip]", "x = [", '"', "bvh = 1", ""]), max_size=14))
def test_fuzzed_labels_files_are_read_or_refused_with_their_line(tmp_path, lines):
    bad = tmp_path / "fuzz.labels.toml"
    bad.write_text("\n".join(['bvh = "dog.bvh"', *lines]), encoding="utf-8")
    if not (tmp_path / "dog.bvh").exists():
        (tmp_path / "dog.bvh").write_bytes((BODIES / "dog.bvh").read_bytes())
    try:
        clips = read_clips(bad)
    except MaterialError as exc:
        assert str(exc).startswith(f"{bad}:") and str(exc).split(":")[1].isdigit()
    else:
        assert sum(c.frames[1] - c.frames[0] + 1 for c in clips) == 271
        assert all(c.frames[0] <= a <= b <= c.frames[1] for c in clips for spans in c.labels.values() for a, b in spans)
