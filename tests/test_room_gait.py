"""Walking bodies in the room (issue 21, creatures/room/gait.py): the dog's walk played by the
distance its vehicle covers, so a paw on the floor stays put, where the clip played at its own
pace slides; clones start at different phases; frames, the live view, pose events and the body
stream draw each body where its vehicle is."""

from __future__ import annotations

import numpy as np
import pytest
from test_room_stage import run, session, write

from creatures.config import ConfigError
from creatures.kinds.figures import figure_graph
from creatures.room.gait import Walk, in_room
from creatures.runtime.bodies import gather
from creatures.runtime.body_stream import snapshot
from creatures.view.snapshot import bodies, frame, pose_event
from creatures.runtime.schema import load_installation

DOG = """
[[creature]]
name = "{name}"
kind = "authored"
{extra}
[creature.body]
figure = "dog"
[creature.vehicle]
at = [{x}, 5.0]
max_speed = 0.9
max_turn = 90.0
gait = "{gait}"
steer = [{{ behaviour = "wander", weight = 1.0 }}, {{ behaviour = "wall_avoidance", weight = 3.0 }}]
[creature.tuples.idle]
action = "rest"
until = {{ seconds = 1.0 }}
[creature.groups.main]
tuples = ["idle"]
alpha = 0.0
"""

PAWS = ("front_paw_l_end", "front_paw_r_end", "hind_paw_l_end", "hind_paw_r_end")


def dog(name: str = "rex", x: float = 5.0, *, gait: str = "walk", extra: str = "") -> str:
    return DOG.format(name=name, x=x, gait=gait, extra=extra)


def test_a_walk_is_one_travelling_clip_by_distance():
    walk = Walk.of(figure_graph("dog"), "walk")
    assert walk.stride == pytest.approx(0.8)  # the generated walk: two 0.4 m cycles at 0.5 m/s
    assert np.allclose(walk.pose(0.0), walk.pose(walk.stride), atol=1e-6)  # the seam joins
    assert not np.allclose(walk.pose(0.0), walk.pose(0.2))
    # Facing +z with its left at +x, turned to a heading along +x (room east) and put at (3, 4):
    # its nose east of it, its left hand north (room y is the world's −z).
    nose, left = np.array([[0.0, 0.5, 1.0]]), np.array([[1.0, 0.5, 0.0]])
    at, east = np.array([3.0, 4.0]), np.array([1.0, 0.0])
    assert np.allclose(in_room(nose, at, east), [[4.0, 0.5, -4.0]])
    assert np.allclose(in_room(left, at, east), [[3.0, 0.5, -5.0]])


def slide(track: list[tuple[np.ndarray, float]], dt: float) -> float:
    """Median horizontal speed of a paw while it is on the floor (within 5 mm of its lowest)."""
    paws = np.array([p for p, _ in track])  # (T, 4, 3)
    floor = paws[:, :, 1].min(axis=0)
    down = paws[:, :, 1] < floor + 0.005
    both = down[1:] & down[:-1]
    step = np.linalg.norm(np.diff(paws[:, :, [0, 2]], axis=0), axis=-1) / dt
    return float(np.median(step[both]))


def test_a_walking_dog_keeps_its_paws_planted_where_played_by_time_they_slide(tmp_path):
    s, clock = session(tmp_path, "", dog())
    stage, rex = s.stage, s.creatures[0]
    paws = [rex.body.skeleton.index(name) for name in PAWS]
    walk = stage.gaits.walks[0]
    dt, by_distance, by_time, speeds = 0.02, [], [], []
    phase = stage.gaits.phase[0]
    while clock.now() < 20.0:
        run(s, clock, clock.now() + dt)
        pos, heading = stage.v.pos[0], stage.v.heading[0]
        speeds.append(float(np.hypot(*stage.v.vel[0])))
        by_distance.append((stage.figure(rex, rex.figure()[0])[paws], speeds[-1]))
        phase += 0.5 * dt  # the clip at its own pace (0.5 m/s), whatever the vehicle does
        by_time.append((in_room(walk.pose(phase), pos, heading)[paws], speeds[-1]))
    speed = float(np.median(speeds))
    assert speed > 0.6  # it walks, faster than the clip was recorded
    # Measured: 0.055 m/s at a median 0.83 m/s, all of it from turning about the pelvis (a
    # straight walk slides 1e-8 m/s: the next test); by time, the difference in pace: 0.35 m/s.
    assert slide(by_distance[50:], dt) < 0.1 * speed
    assert slide(by_time[50:], dt) > 0.25 * speed


def test_a_straight_walk_by_distance_does_not_slide_at_any_speed():
    graph = figure_graph("dog")
    walk, paws = Walk.of(graph, "walk"), [graph.skeleton.index(name) for name in PAWS]
    heading = np.array([0.6, 0.8])
    for speed in (0.3, 0.8, 1.5):
        track = [(in_room(walk.pose(speed * 0.02 * k), heading * speed * 0.02 * k, heading)[paws], speed)
                 for k in range(300)]
        assert slide(track, 0.02) < 1e-6


def test_clones_step_out_of_phase_and_each_is_drawn_where_it_stands(tmp_path):
    s, clock = session(tmp_path, "", dog(extra="count = 6"))
    phases = s.stage.gaits.phase
    stride = s.stage.gaits.walks[0].stride
    assert len(set(np.round(phases, 6))) == 6 and np.ptp(phases) > stride / 3
    run(s, clock, 2.0)
    positions, _, _ = gather(s.creatures)
    joints = len(s.creatures[0].body.skeleton.names)
    roots = positions.reshape(6, joints, 3)[:, 0]
    assert np.allclose(roots[:, [0, 2]] * [1.0, -1.0], s.stage.v.pos, atol=0.15)  # the pelvis over the vehicle
    assert np.all(roots[:, 1] > 0.2)  # standing, not under the floor
    # Every picture agrees: the live view's frame, the pose events and the body stream show
    # the same joints, at the origin's place.
    rex = s.creatures[0]
    assert np.allclose(frame(2.0, s.creatures)["bodies"][rex.name], positions[:joints])
    assert np.allclose(pose_event(rex)["joints"], positions[:joints], atol=1e-3)
    streamed = snapshot(rex)
    assert np.allclose(streamed.positions, positions[:joints])
    assert streamed.rotations is None  # turned and walking: its local rotations would not rebuild it
    assert all(b.place == (0.0, 0.0, 0.0) for b in bodies(s.creatures))


@pytest.mark.parametrize("gait, extra, message", [
    ("wlak", "", "not a clip of the body \\(did you mean 'walk'\\?\\)"),
    ("sit", "", "gait 'sit' does not walk"),
])
def test_a_gait_that_cannot_walk_is_a_config_error(tmp_path, gait, extra, message):
    from test_room_stage import HEADER

    with pytest.raises(ConfigError, match=message) as info:
        load_installation(write(tmp_path, HEADER.format(room="") + dog(gait=gait, extra=extra)))
    assert info.value.line is not None


def test_a_gait_needs_a_body(tmp_path):
    from test_room_stage import HEADER

    text = HEADER.format(room="") + dog().replace('[creature.body]\nfigure = "dog"\n', "")
    with pytest.raises(ConfigError, match="needs a body that walks"):
        load_installation(write(tmp_path, text))
