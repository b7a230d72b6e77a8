"""Skills over named parameters (issue 17): look-at, servos with patience, WavesWorld's
current→min→max→current sweep, adverbs played by creatures, and simple shaping."""

from __future__ import annotations

import math
import re

import textwrap
from pathlib import Path

import numpy as np
import pytest

from creatures.clock import SimulatedClock
from creatures.config import ConfigError
from creatures.events import EventLog
from creatures.motor import quaternion as quat
from creatures.motor.skills import Servo, Sweep, look_turns, paired_stages, shortest
from creatures.runtime.schema import load_installation
from creatures.runtime.session import Session
from midi.notes import NoteEvent
from midi.sinks import MemorySink

TICK = 0.02


# -- the skills alone ----------------------------------------------------------------------
def test_look_turns_take_eyes_then_head_then_body_the_short_way_within_limits():
    limits = [20.0, 60.0, 45.0, 90.0]  # eyes, head, neck, body
    turns = look_turns(50.0, limits)
    assert turns.tolist() == [20.0, 30.0, 0.0, 0.0]  # the eyes first, the head the rest
    turns = look_turns(200.0, limits)  # 200° to the left is 160° to the right
    assert turns.sum() == pytest.approx(-160.0) and (turns <= 0).all()
    assert (np.abs(turns) <= limits).all() and turns.tolist()[:3] == [-20.0, -60.0, -45.0]
    assert look_turns(-359.0, limits).tolist() == [1.0, 0.0, 0.0, 0.0]
    assert look_turns(300.0, [10.0, 10.0]).tolist() == [-10.0, -10.0]  # beyond every limit: as far as they go


def test_both_eyes_turn_together_and_take_their_share_of_a_look_once():
    names = ["eye_l", "eye_r", "head", "chest"]
    stages = paired_stages(names)
    assert stages == [0, 0, 2, 3]
    turns = look_turns(50.0, [30.0, 20.0, 70.0, 35.0], stages)
    assert turns.tolist() == [20.0, 20.0, 30.0, 0.0]  # the eyes within the tighter limit, both alike
    assert shortest(180.0) == -180.0 and shortest(-181.0) == 179.0


def test_a_servo_follows_at_its_rate_and_gives_up_when_its_patience_runs_out():
    servo = Servo(2, rate=10.0, tolerance=0.1, patience=2.0)
    servo.step(0.0)
    servo.aim(np.array([5.0, -20.0]), 0.0)
    assert servo.step(1.0).tolist() == [5.0, -10.0]  # at most 10 per second each
    assert servo.step(1.5).tolist() == [5.0, -15.0] and not servo.gave_up
    assert servo.eta(1.5) == pytest.approx(2.0)
    assert servo.step(2.0).tolist() == [5.0, -20.0] and servo.reached and not servo.gave_up
    # A target running away faster than the servo can follow: it gives up after 2 s.
    for k in range(1, 60):
        t = 2.0 + 0.1 * k
        servo.aim(np.array([5.0, -20.0 - 30.0 * 0.1 * k]), t)
        servo.step(t)
        if servo.gave_up:
            break
    assert servo.gave_up and 4.0 < t <= 4.3  # off target from 2.1 s, for 2 s on end
    frozen = servo.value.copy()
    assert servo.step(t + 1.0).tolist() == frozen.tolist()  # given up: it stops


def test_sweep_goes_current_min_max_current_at_constant_velocity_over_a_list():
    sweep = Sweep([-10.0, 0.0, -1.0], [30.0, 4.0, 1.0], duration=4.0)
    sweep.start(np.array([0.0, 4.0, 0.0]), 10.0)
    times = 10.0 + np.linspace(0.0, 4.0, 4001)
    values = np.array([sweep.value(t) for t in times])
    first = values[:, 0]
    assert first.min() == pytest.approx(-10.0) and first.max() == pytest.approx(30.0)
    assert np.argmin(first) < np.argmax(first)  # down to the min first, then up to the max
    speed = np.abs(np.diff(first)) / np.diff(times)
    assert speed.max() == pytest.approx(speed[speed > 0].min(), rel=1e-3)  # constant velocity: 80 units over 4 s
    assert speed.max() == pytest.approx((10 + 40 + 30) / 4.0, rel=1e-3)
    assert values[:, 1].min() == pytest.approx(0.0) and values[:, 2].max() == pytest.approx(1.0)
    assert sweep.value(14.0).tolist() == [0.0, 4.0, 0.0] and sweep.done(14.0)  # back exactly, all together
    assert not sweep.done(13.9)
    with pytest.raises(ValueError, match="list length mismatch"):
        Sweep([0.0], [1.0, 2.0], 1.0)


# -- on a creature ---------------------------------------------------------------------------
LISTENER = """
title = "look"
tick = {tick}
duration = 20.0

[[creature]]
name = "caller"
kind = "authored"
pan = -0.8

[creature.tuples.rest]
action = "rest"
until = {{ seconds = 5.0 }}

[creature.groups.main]
tuples = ["rest"]
alpha = 0.0

[[creature]]
name = "bird"
kind = "authored"
pan = 0.8
{keys}

[creature.body]
figure = "bird"

[creature.percepts.heard]
type = "heard"
window = 0.5

[creature.tuples.rest]
action = "rest"
until = {{ seconds = 5.0 }}

[creature.tuples.look]
trigger = "heard"
action = {{ type = "look_at", speed = 90.0 }}
until = {{ seconds = 1.0, done = true }}
value = 2.0

[creature.groups.main]
tuples = ["rest"]
alpha = 0.0

[creature.groups.attention]
tuples = ["look"]
alpha = 0.0
{extra}
"""


def session_of(tmp_path: Path, extra: str = "", *, keep: int = 0, keys: str = "") -> Session:
    tmp_path.mkdir(parents=True, exist_ok=True)
    path = tmp_path / "look.toml"
    path.write_text(textwrap.dedent(LISTENER.format(tick=TICK, extra=extra, keys=keys)))
    return Session(load_installation(path), SimulatedClock(), EventLog(keep_in_memory=keep), MemorySink())


def run(session: Session, until: float, start: float = 0.0, each=None) -> None:
    for step in range(int(round(start / TICK)) + 1, int(round(until / TICK)) + 1):
        t = step * TICK
        session.clock.advance_to(t)
        session.step(t, 1, None, audio=False)
        if each is not None:
            each(t)


def head_yaw(body) -> float:
    """Degrees the head faces left of +z, from the shown pose's joint rotations."""
    names, parents = body.skeleton.names, body.skeleton.parents
    j, chain = names.index("head"), []
    while j >= 0:
        chain.append(j)
        j = parents[j]
    world = quat.identity()
    for j in reversed(chain):
        world = quat.multiply(world, body.pose.rotations[j])
    forward = quat.rotate(world, np.array([0.0, 0.0, 1.0]))
    return float(np.degrees(np.arctan2(forward[0], forward[2])))


def test_a_creature_turns_its_head_to_whoever_it_hears_within_limits_and_back(tmp_path):
    session = session_of(tmp_path, keep=100_000, keys="report_every = 0.25")
    bird = session.creatures[1]
    body = bird.body
    run(session, 1.0)
    rest_yaw, rest = head_yaw(body), body.pose.rotations.copy()
    assert body.layers is None or "look" not in body.layers.blend  # no look until it hears someone
    # The caller, at the audience's left (the bird's right, on the line across the stage), plays.
    for k in range(6):
        session.world.inject(NoteEvent(1.0 + 0.3 * k, 60 + k, 90, 0, 0.2), source="caller")
    look = bird.tuples["look"].action
    limits = look.limits
    shown = []
    run(session, 3.0, 1.0, each=lambda t: shown.append((t, head_yaw(body), look.offsets.degrees.copy())))
    _, yaw, turns = shown[-1]
    assert turns.sum() == pytest.approx(-90.0, abs=0.5)  # straight to its right: the short way, not 270° left
    assert (np.abs(turns) <= limits + 1e-9).all() and abs(turns[0]) == pytest.approx(limits[0])  # the head first
    assert yaw - rest_yaw < -45.0  # the head faces round to the right
    speeds = np.abs(np.diff([s[2] for s in shown], axis=0)).max(axis=0) / TICK
    assert speeds.max() <= 90.0 + 1e-6  # its servo's rate
    frames = np.array([s[1] for s in shown])
    assert np.all(np.diff(frames) <= 1e-6)  # it turns one way, steadily
    # The caller stops: the look ends, turns back and leaves the blend; the pose is rest again.
    run(session, 8.0, 3.0)
    assert "look" not in body.layers.blend
    assert np.allclose(body.pose.rotations, rest, atol=1e-12)
    assert head_yaw(body) == pytest.approx(rest_yaw, abs=1e-9)
    # The events log names who drove each joint, at the creature's report_every.
    motor = [e for e in session.world.log.records if e["kind"] == "motor" and e["creature"] == "bird"]
    looking = [e for e in motor if 2.0 <= e["t"] <= 3.0]
    gaps = np.diff([e["t"] for e in motor])
    assert np.all((gaps >= 0.25 - 1e-9) & (gaps <= 0.25 + TICK + 1e-9))  # every 0.25 s (on the tick)
    assert all(e["joints"]["head"] == {"course": 1.0, "look": 1.0} for e in looking)
    assert set(looking[0]["joints"]) == {"head", "neck", "pelvis"}  # the look's joints (the bird's chest is held)
    assert motor[-1]["joints"] == {} and motor[-1]["layers"] == {"course": 1.0}


def eyed_hierarchy() -> str:
    """The heron of tests/body_fixtures.py with two eyes on its head instead of a beak tip."""
    from body_fixtures import HIERARCHY

    tip = "      End Site\n      {\n        OFFSET 0 0 30\n      }\n"
    eye = ("      JOINT {name}\n      {{\n        OFFSET {x} 2 5\n        CHANNELS 3 Zrotation Xrotation Yrotation\n"
           "        End Site\n        {{\n          OFFSET 0 0 1\n        }}\n      }}\n")
    assert tip in HIERARCHY
    return HIERARCHY.replace(tip, eye.format(name="eye_l", x=3) + eye.format(name="eye_r", x=-3))


def test_a_body_with_eyes_turns_both_together_when_it_looks(tmp_path):
    """A body from files with two eyes (the heron's, given eyes that glance 25° and 18° in its
    material): looking at a caller on its right, both eyes turn by the same angle, within the
    tighter of their ranges, and the head and neck take the rest."""
    from body_fixtures import heron_frames, write_bvh

    rows = heron_frames()
    eyes = np.zeros((len(rows), 6))
    glance = np.sin(np.linspace(0.0, 6.0 * np.pi, len(rows)))
    eyes[:, 2], eyes[:, 5] = 25.0 * glance, 18.0 * glance  # each eye's Y yaw
    tmp_path.mkdir(parents=True, exist_ok=True)
    write_bvh(tmp_path / "eyed.bvh", np.concatenate((rows, eyes), axis=1), hierarchy=eyed_hierarchy())
    text = textwrap.dedent(LISTENER.format(tick=TICK, extra="", keys="")).replace(
        '[creature.body]\nfigure = "bird"\n',
        '[creature.body]\neffectors = ["head"]\nscale = 0.01\nrest_pose = { neck = [20.0, 0.0, 0.0] }\n\n'
        '[[creature.body.animations]]\nfile = "eyed.bvh"\n', 1)
    (tmp_path / "look.toml").write_text(text)
    session = Session(load_installation(tmp_path / "look.toml"), SimulatedClock(), EventLog(keep_in_memory=0),
                      MemorySink())
    bird = session.creatures[1]
    for k in range(6):
        session.world.inject(NoteEvent(0.5 + 0.3 * k, 60 + k, 90, 0, 0.2), source="caller")
    look = bird.tuples["look"].action
    names = [bird.body.skeleton.names[j] for j in look.offsets.joints]
    assert names[:2] == ["eye_l", "eye_r"]
    run(session, 3.0)
    turns = look.offsets.degrees
    assert turns[0] == turns[1] != 0.0  # together
    assert abs(turns[0]) == pytest.approx(min(look.limits[:2]), abs=1e-6)  # as far as the tighter eye goes
    assert turns[0] + turns[2:].sum() == pytest.approx(-90.0, abs=0.5)  # the pair's share once, the rest by head and neck


def test_the_heard_direction_is_the_room_bearing_or_the_stage_line(tmp_path):
    from creatures.authored.skills import heard_bearing

    session = session_of(tmp_path)
    bird = session.creatures[1]
    assert heard_bearing(bird) is None
    bird.ear.heard_from = "caller"
    assert heard_bearing(bird) == pytest.approx(-90.0)
    bird.ear.heard_from = "input"  # an outside player stands in front of the middle of the stage
    assert heard_bearing(bird) == pytest.approx(np.degrees(np.arctan2(-1.6, 2.0)))
    session.creatures[0].ear.heard_from = "bird"
    assert heard_bearing(session.creatures[0]) == pytest.approx(90.0)


def test_a_sweep_tuple_moves_named_joints_current_min_max_current(tmp_path):
    extra = """
[creature.tuples.nod]
action = { type = "sweep", variables = { "neck.x" = [-20.0, 30.0], "head.x" = [-10.0, 10.0] }, duration = 2.0 }
until = { done = true, seconds = 5.0 }

[creature.groups.nodding]
tuples = ["nod"]
max_active = 1
alpha = 0.0
"""
    session = session_of(tmp_path, extra)
    bird = session.creatures[1]
    nod = bird.tuples["nod"]
    seen = []
    run(session, 1.9, each=lambda t: seen.append(bird.body.pose.rotations[bird.body.skeleton.index("neck")].copy()))
    assert nod.active and "nod" in bird.body.layers.blend
    angles = quat.angle_between(np.array(seen), np.array(seen[:1]))
    assert np.degrees(angles.max()) > 20.0  # the neck swept
    run(session, 2.2, 1.9)
    assert not nod.active or nod.started_at > 2.0  # done when back, at 2 s


NOD = """
[creature.tuples.nod]
action = { type = "sweep", variables = { "nekc.x" = [-20.0, 30.0] } }
until = { done = true }

[creature.groups.nodding]
tuples = ["nod"]
alpha = 0.0
"""
"""A second group sweeping a joint variable (a typo'd neck: each test puts its own in its place)."""


@pytest.mark.parametrize("written, meant", [("neck.w", "(did you mean 'neck.x', 'neck.y' or 'neck.z'?)"),
                                            ("neck.xx", "(did you mean 'neck.x', 'neck.y' or 'neck.z'?)"),
                                            ("neck.rotation", "(joint variables: neck.x, neck.y, neck.z)")])
def test_a_bad_axis_is_named_with_the_variables_it_could_mean_not_the_action_table(tmp_path, written, meant):
    """``"neck.w"`` in a sweep was refused as ``a joint variable is 'joint.x', 'joint.y' or
    'joint.z'`` followed by the action's whole table (``(got {'variables': {...}, ...})``, cut
    at 120 characters), which named neither the axis that was wrong nor the variable meant."""
    with pytest.raises(ConfigError) as bad:
        session_of(tmp_path, NOD.replace("nekc.x", written))
    axis = written.split(".")[1]
    assert str(bad.value).endswith(f"creature.1.tuples.nod.action: {written!r}: no axis {axis!r} {meant}")


def test_a_joint_near_no_name_of_the_body_is_told_a_short_list(tmp_path):
    """A joint no name of the body is near listed every joint of the body (a body from files
    may have 60): at most twelve now, and how many more."""
    with pytest.raises(ConfigError) as bad:
        session_of(tmp_path, NOD.replace("nekc.x", "qqqq.x"))
    assert re.search(r"no joint 'qqqq' \(joints: (\w+, ){11}\w+ and \d+ more\)$", str(bad.value)), str(bad.value)


def test_sweep_names_must_be_joint_variables(tmp_path):
    extra = NOD
    with pytest.raises(ConfigError, match=r"look.toml:\d+: .*no joint 'nekc' \(did you mean 'neck'\?\)"):
        session_of(tmp_path, extra)
    with pytest.raises(ConfigError, match="a joint variable is 'joint.x'"):
        session_of(tmp_path, extra.replace("nekc.x", "neck"))
    with pytest.raises(ConfigError, match=r"look.toml:\d+: .*'voice.pann' is no voice parameter \(did you mean "
                                          r"'voice.pan'\?\)"):
        session_of(tmp_path, extra.replace("nekc.x", "voice.pann"))
    # voice.cutoff is a low-pass's: a creature that sings through strings without bright_hz has none
    with pytest.raises(ConfigError, match=r"look.toml:\d+: .*voice.cutoff, a low-pass: the creature needs one, "
                                          r"a mouth's \(\[creature.hearing\].*\[creature.voice\] bright_hz"):
        session_of(tmp_path, extra.replace('"nekc.x" = [-20.0, 30.0]', '"voice.cutoff" = [-0.5, 0.0]'))


@pytest.mark.parametrize("action", ['{ type = "oscillate", variables = { "neck.x" = 1e300 } }',
                                    '{ type = "sweep", variables = { "neck.x" = [-20.0, 1e300] } }',
                                    '{ type = "servo", percept = "heard", variables = { "neck.x" = [0.0, -1e300] } }'])
def test_a_skills_depth_beyond_a_million_is_refused_at_its_line(tmp_path, action):
    """An oscillator of ``"chest.y" = 1e300`` loaded (noted as turning the chest ``inf°``, to be
    held within its takes' 40°) and then never moved the chest at all, while 1e6 swung it to
    its limit: each depth is now held to the bounds of every other rate (±1e6)."""
    extra = NOD.replace('{ type = "sweep", variables = { "nekc.x" = [-20.0, 30.0] } }', action).replace(
        "until = { done = true }", "until = { seconds = 2.0 }")
    with pytest.raises(ConfigError, match=r"look.toml:\d+: creature\.1\.tuples\.nod\.action\.variables\.neck\.x.*"
                                          r"(less|greater) than or equal to -?1000000"):
        session_of(tmp_path, extra)
    session_of(tmp_path / "ok", extra.replace("e300", "e6"))


def test_a_layer_on_a_joint_the_figure_never_turns_is_refused_at_its_line(tmp_path):
    """The bird's material never turns its beak from rest, and a body never turns a joint
    further than its material does (blend.Limits): a sweep of ``beak.x`` moved nothing while
    the ``motor`` events named it as driving the beak. It is refused at load instead."""
    extra = NOD.replace("nekc.x", "beak.x")
    with pytest.raises(ConfigError, match=r"look.toml:\d+: creature\.1\.tuples\.nod\.action: no frame of the "
                                          r"body's material turns the joint 'beak' from rest"):
        session_of(tmp_path, extra)
    session_of(tmp_path / "neck", extra.replace("beak.x", "neck.x"))  # a joint it turns


def test_voice_cutoff_darkens_what_a_mouth_sings():
    """``voice.cutoff`` scales the mouth's low-pass over what the body sets: a fifth of it
    leaves a tenth as much of a bright sound above 4 kHz."""
    from audio.self_hearing import SingingState
    from audio.utterance import Utterance
    from creatures.kinds.hearing_parts import Mouth, MouthSpec

    sr = 22050
    noise = np.random.default_rng(3).normal(0.0, 0.2, sr).astype(np.float32)
    highs = []
    for cutoff in (1.0, 0.2):
        mouth = Mouth(MouthSpec(), SingingState())
        mouth.sing(0.0, Utterance(noise, sr, np.zeros((1, 13)), 0.0))
        out = np.zeros(8192)
        mouth.render(out, sr, None, cutoff=cutoff)
        spectrum = np.abs(np.fft.rfft(out)) ** 2
        highs.append(spectrum[np.fft.rfftfreq(len(out), 1.0 / sr) > 4000.0].sum() / spectrum.sum())
    assert highs[1] < 0.1 * highs[0]


# -- adverbs ---------------------------------------------------------------------------------
ADVERB = """
[creature.drives.boredom]
level = {level}

[creature.tuples.manner]
until = {{ seconds = 30.0 }}

[creature.tuples.manner.action]
type = "adverb"
{source}
examples = [
    {{ at = 0.0, seconds = 2.0, keys = [{{ "neck.x" = 0.0 }}, {{ "neck.x" = 5.0 }}] }},
    {{ at = 1.0, seconds = 4.0, keys = [{{ "neck.x" = 20.0 }}, {{ "neck.x" = 40.0 }}] }},
]

[creature.groups.manners]
tuples = ["manner"]
alpha = 0.0
"""


def neck_track(tmp_path: Path, level: float, source: str = 'drive = "boredom"') -> np.ndarray:
    session = session_of(tmp_path, ADVERB.format(level=level, source=source))
    bird = session.creatures[1]
    neck = bird.body.skeleton.index("neck")
    out = []
    run(session, 12.0, each=lambda t: out.append(bird.body.pose.rotations[neck].copy()))
    return np.degrees(quat.angle_between(np.array(out), np.array(out[:1])))


def test_an_adverb_set_by_a_drive_plays_over_the_body_in_neutral_time(tmp_path):
    alert, bored, half = neck_track(tmp_path, 0.0), neck_track(tmp_path, 1.0), neck_track(tmp_path, 0.5)
    settled = slice(int(2.0 / TICK), None)  # after the layer's fade-in

    def period(track: np.ndarray) -> float:
        """The lag (s) of the highest autocorrelation peak past a second."""
        x = track[settled] - track[settled].mean()
        lags = np.arange(int(1.0 / TICK), len(x) // 2 + int(1.0 / TICK))
        r = [x[:-k] @ x[k:] / (len(x) - k) for k in lags]
        return float(lags[int(np.argmax(r))] * TICK)

    assert np.ptp(bored[settled]) > 3 * np.ptp(alert[settled]) > 0  # the bored example sways further
    assert period(alert) == pytest.approx(2.0, rel=0.15) and period(bored) == pytest.approx(4.0, rel=0.15)
    assert period(half) == pytest.approx(3.0, rel=0.15)  # 50:50 lasts the mean of 2 s and 4 s


def test_an_adverb_takes_exactly_one_source(tmp_path):
    with pytest.raises(ConfigError, match="exactly one of drive, percept or value"):
        session_of(tmp_path, ADVERB.format(level=0.0, source='drive = "boredom"\nvalue = 0.5'))
    with pytest.raises(ConfigError, match="'adverb_model' percept"):
        session_of(tmp_path, ADVERB.format(level=0.0, source='percept = "heard"'))


def test_an_adverb_whose_levels_are_one_level_is_refused_at_its_line(tmp_path):
    """``levels = [1, 1]`` read every level of the drive as the first example's place (a zero
    span taken as 0), so however bored the creature grew its manner never changed, without a
    word. Reversed levels still map the other way round."""
    with pytest.raises(ConfigError, match=r"look.toml:\d+: creature\.1\.tuples\.manner\.action: levels \[1, 1\] map "
                                          r"every level of drive 'boredom' to one place"):
        session_of(tmp_path, ADVERB.format(level=5.0, source='drive = "boredom"\nlevels = [1.0, 1.0]'))
    session_of(tmp_path / "reversed", ADVERB.format(level=5.0, source='drive = "boredom"\nlevels = [1.0, 0.0]'))


def test_an_adverb_value_beyond_its_examples_is_refused_at_its_line(tmp_path):
    # at 3 over examples at 0 and 1 the RBF weights were −2 and 3: the neck turned 67°, past
    # any example's 40°, and at −3 the cycle lasted 1 µs, replayed every tick
    for value in (3.0, -3.0):
        with pytest.raises(ConfigError, match=rf"look.toml:\d+: .*value {value:g} lies outside the examples' "
                                              r"places \[0, 1\]"):
            session_of(tmp_path, ADVERB.format(level=0.0, source=f"value = {value}"))
    assert session_of(tmp_path, ADVERB.format(level=0.0, source="value = 1.0"))  # an example's own place


def test_an_adverb_sampled_beyond_its_examples_is_clamped_to_them_and_said(tmp_path):
    # the model's range reaches to 3, the examples to 1: a sample of 3 plays the last example
    extra = ADVERB.format(level=0.0, source='percept = "manner model"') + """
[creature.percepts."manner model"]
type = "adverb_model"
prior_mean = 3.0
prior_std = 0.01
range = [2.5, 3.0]
"""
    session = session_of(tmp_path, extra, keep=10_000)
    bird = session.creatures[1]
    run(session, 1.0)
    action = bird.tuples["manner"].action
    assert action.sampled > 2.5 and action.adverb == 1.0 and action._length == pytest.approx(4.0)
    said = [r for r in session.log.records if r["kind"] == "adverb"]
    assert said and said[0]["adverb"] == 1.0 and said[0]["sampled"] == action.sampled


# -- simple shaping ----------------------------------------------------------------------------
SHAPED = """
[creature.drives.boredom]
level = 0.0

[creature.percepts."beg height"]
type = "adverb_model"
prior_mean = 0.1

[creature.tuples.beg]
until = { seconds = 1.0 }

[creature.tuples.beg.action]
type = "adverb"
percept = "beg height"
fade = 0.2
examples = [
    { at = 0.0, seconds = 1.0, keys = [{ "neck.x" = 0.0 }] },
    { at = 1.0, seconds = 1.0, keys = [{ "neck.x" = 40.0 }] },
]

[creature.tuples.sit]
action = "rest"
until = { seconds = 0.5 }
value = 0.01

[creature.groups.training]
tuples = ["beg", "sit"]
alpha = 0.0
"""


def test_rewarding_high_begs_shapes_the_adverb_higher_within_40_rewards(tmp_path):
    session = session_of(tmp_path, SHAPED)
    bird = session.creatures[1]
    beg, model = bird.tuples["beg"], bird.percepts["beg height"]
    start_mean, rewards, t, judged = model.model.mean, 0, 0.0, None
    low, high = model.low, model.high
    neck = bird.body.skeleton.index("neck")
    heights = []  # (sampled ĥ, how far the neck rose)
    while rewards < 40 and t < 400.0:
        run(session, t + 0.5, t)
        t += 0.5
        if beg.active and beg.started_at != judged:
            judged = beg.started_at
            heights.append((beg.action.sampled, quat.angle_between(bird.body.pose.rotations[neck], quat.identity())))
            if beg.action.sampled > model.model.mean:  # the trainer clicks for a beg above its usual
                bird.reward(1.0, t, 0.5, 0.1)
                rewards += 1
    assert rewards <= 40
    assert model.model.mean - start_mean >= 0.5 * (high - low)
    sampled, raised = np.array(heights).T
    # the body shows what was sampled: higher ĥ, higher beg (r > 0.9 before the bird was held to
    # its source material's joint range, which now caps the highest begs: 0.66 measured)
    assert np.corrcoef(sampled, raised)[0, 1] > 0.6
    # The model survives a save and reload.
    state = bird.state()
    again = session_of(tmp_path / "again", SHAPED).creatures[1]
    again.restore(state)
    assert again.percepts["beg height"].model.mean == model.model.mean


# -- oscillators and servos over joints and voice parameters -------------------------------
RISING = """
[creature.drives.rising]
growth = {growth}

[creature.percepts.rising]
type = "drive"
drive = "rising"
scale = "level"
"""
"""A drive rising at ``growth`` a second, and a percept of its level for a servo to follow."""


def test_an_oscillator_swings_the_voice_gain_and_a_servo_follows_a_percept_until_it_gives_up(tmp_path):
    extra = RISING + """
[creature.tuples.swell]
action = {{ type = "oscillate", variables = {{ "voice.gain" = 0.5 }}, period = 1.0, fade = 0.0 }}
until = {{ seconds = 30.0 }}

[creature.tuples.follow]
until = {{ seconds = 30.0, done = true }}

[creature.tuples.follow.action]
type = "servo"
variables = {{ "neck.x" = [0.0, 40.0] }}
percept = "rising"
speed = 20.0
tolerance = 1.0
patience = 1.0

[creature.groups.skills]
tuples = ["swell", "follow"]
max_active = 2
alpha = 0.0
"""
    session = session_of(tmp_path, extra.format(growth=0.1))  # 4° a second: the servo keeps up
    bird = session.creatures[1]
    gains = []
    run(session, 6.0, each=lambda t: gains.append((t, bird.voice_parameters().resolve(t)[0])))
    times, gain = np.array(gains).T
    started = bird.tuples["swell"].started_at
    assert np.allclose(gain[times > started], 1.0 + 0.5 * np.sin(2 * np.pi * (times[times > started] - started)))
    assert bird.tuples["follow"].active and "follow" in bird.body.layers.blend
    neck = bird.body.layers.blend.channel_contributors(6.0)[bird.body.skeleton.index("neck")]
    assert neck == {"course": 1.0, "follow": 1.0}
    # The voice really is scaled: each block sounds at voice.gain, ramped from the last block's.
    bird.voice = type("Steady", (), {"render": lambda self, o, t, cutoff=1.0, gain=None: o.fill(1.0), "retune": lambda self, *knobs: None})()
    out = np.zeros(100)
    bird.sound(out, 22050)
    now = bird.voice_parameters().resolve(session.clock.now())[0]
    assert out[-1] == pytest.approx(now) and now != pytest.approx(1.0, abs=0.05)
    bird.sound(out, 22050)
    assert np.allclose(out, now)  # the same time again: a steady block
    # A drive rising at 1 a second asks 40° a second of a servo of 20°: it lags, and after 1 s gives up.
    session = session_of(tmp_path / "fast", extra.format(growth=1.0))
    bird = session.creatures[1]
    follow = bird.tuples["follow"]
    starts = []
    run(session, 3.0, each=lambda t: starts.append(follow.started_at) if follow.started_at not in starts else None)
    assert 1.0 < starts[1] < 1.5  # off target for its patience (1 s) on end: done (and the group starts it again)


def test_a_servo_whose_percept_reads_nan_keeps_its_last_target_and_says_so(tmp_path):
    extra = RISING.format(growth=0.1) + """
[creature.tuples.follow]
until = { seconds = 30.0 }

[creature.tuples.follow.action]
type = "servo"
variables = { "neck.x" = [0.0, 40.0], "voice.gain" = [0.0, 0.5] }
percept = "rising"

[creature.groups.skills]
tuples = ["follow"]
alpha = 0.0
"""
    session = session_of(tmp_path, extra, keep=10_000)
    run(session, 1.0)
    bird = session.creatures[1]
    bird.percepts["rising"].evaluate = lambda t: math.nan  # a percept gone wrong
    run(session, 2.0, 1.0)
    neck = bird.body.pose.rotations[bird.body.skeleton.index("neck")]
    # NaN passed min(max(u, 0), 1): the gain went NaN (the creature's sound with it) and the neck
    # snapped back to rest
    assert np.isfinite(bird.voice_parameters().resolve(2.0)).all()
    assert np.degrees(quat.angle_between(neck, quat.identity())) > 5.0  # held where it went by 1 s (10.9°), not at rest
    said = [r for r in session.log.records if r["kind"] == "servo percept not finite"]
    assert len(said) == 1 and said[0]["percept"] == "rising"


@pytest.mark.parametrize("policy,weight", [("exclusive", 1.0), ("mean", 3.0), ("add", 1.0)])
def test_a_layers_policy_weight_and_priority_come_from_the_config(tmp_path, policy, weight):
    """``blend = {policy, weight, priority}`` on a skill: ``exclusive`` holds the neck at the
    layer's own turn over the course, ``mean`` weights it 3 : 1 against the course (the weighted
    slerp), ``add`` composes it over the course; the voice parameters it drives (pan, push) are
    blended alike, move the creature in the mix and are logged with who drives them."""
    extra = f"""
[creature.tuples.hold]
action = {{ type = "oscillate", variables = {{ "neck.x" = 10.0, "voice.pan" = -0.5, "voice.push" = 1.0 }}, period = 4.0, fade = 0.0, blend = {{ policy = "{policy}", weight = {weight}, priority = 2.0 }} }}
until = {{ seconds = 30.0 }}

[creature.groups.skills]
tuples = ["hold"]
alpha = 0.0
"""
    session = session_of(tmp_path, extra, keep=10_000)
    bird = session.creatures[1]
    run(session, 2.0)
    t = session.clock.now()
    hold = bird.tuples["hold"]
    assert hold.active
    swing = math.sin(2 * math.pi * (t - hold.started_at) / 4.0)
    neck = bird.body.skeleton.index("neck")
    layer = quat.from_axis_angle(np.array([1.0, 0.0, 0.0]), math.radians(10.0 * swing))
    course = bird.body.layers._course[neck]
    expected = {"exclusive": layer, "mean": quat.slerp(course, layer, 0.75),
                "add": quat.multiply(course, layer)}[policy]
    shown = bird.body.pose.rotations[neck]
    assert quat.angle_between(shown, expected) < 1e-9
    assert quat.angle_between(course, layer) > 0.01  # the course and the layer differ: the policy chose
    # The voice: pan and push are offsets over their rest (0 and 1) in add; in mean and exclusive
    # the layer gives rest + offset as the value, and it is the only one driving them.
    values = bird.voice_parameters().resolve(t)
    assert values[1] == pytest.approx(-0.5 * swing, abs=1e-9)
    assert values[2] == pytest.approx(1.0 + swing, abs=1e-9)
    assert bird.pan() == pytest.approx(0.8 + values[1])
    session.step(t, 64, None, audio=True)  # a block sounded: the mix has moved it
    assert session.mixer.pans[1] == pytest.approx(bird.pan())
    logged = [e for e in session.world.log.records if e["kind"] == "voice parameters" and e["creature"] == "bird"]
    assert logged and logged[-1]["contributors"]["voice.pan"] == {"hold": weight}


def test_a_budget_layer_is_truncated_to_the_bodys_budget(tmp_path):
    """``blend.policy = "budget"`` within ``[creature.body] budget`` degrees: a 10° swing over a
    4° budget turns the neck 4° over the course at most (IViHumans' truncated running sum)."""
    extra = """
[creature.tuples.hold]
action = { type = "oscillate", variables = { "neck.x" = 10.0 }, period = 4.0, fade = 0.0, blend = { policy = "budget" } }
until = { seconds = 30.0 }

[creature.groups.skills]
tuples = ["hold"]
alpha = 0.0
"""
    path = tmp_path / "look.toml"
    path.write_text(textwrap.dedent(LISTENER.format(tick=TICK, extra=extra, keys="")).replace(
        'figure = "bird"', 'figure = "bird"\nbudget = 4.0', 1))
    session = Session(load_installation(path), SimulatedClock(), EventLog(keep_in_memory=0), MemorySink())
    bird = session.creatures[1]
    neck = bird.body.skeleton.index("neck")
    turns = []
    for step in range(1, int(round(3.0 / TICK)) + 1):
        t = step * TICK
        session.clock.advance_to(t)
        session.step(t, 1, None, audio=False)
        course = bird.body.layers._course[neck]
        turns.append(math.degrees(quat.angle_between(bird.body.pose.rotations[neck], course)))
    assert max(turns) == pytest.approx(4.0, abs=1e-6)  # the swing reached 10°: held to the budget


TWO_LAYERS = """
[creature.tuples.high]
action = {{ type = "oscillate", variables = {{ "neck.x" = {high} }}, period = 4.0, fade = 0.0, blend = {{ policy = "{policy}", priority = 2.0 }} }}
until = {{ seconds = 30.0 }}

[creature.tuples.low]
action = {{ type = "oscillate", variables = {{ "neck.x" = {low} }}, period = 4.0, fade = 0.0, blend = {{ policy = "{policy}", priority = 1.0 }} }}
until = {{ seconds = 30.0 }}

[creature.groups.skills]
tuples = ["high", "low"]
max_active = 2
alpha = 0.0
"""


def two_layer_session(tmp_path: Path, policy: str, high: float, low: float, body: str = "") -> Session:
    tmp_path.mkdir(parents=True, exist_ok=True)
    path = tmp_path / "look.toml"
    path.write_text(textwrap.dedent(LISTENER.format(tick=TICK, extra=TWO_LAYERS.format(policy=policy, high=high, low=low),
                                                    keys="")).replace('figure = "bird"', f'figure = "bird"\n{body}', 1))
    return Session(load_installation(path), SimulatedClock(), EventLog(keep_in_memory=0), MemorySink())


def test_two_layers_from_the_config_resolve_by_priority(tmp_path):
    """Two ``exclusive`` layers on the neck: the higher priority holds it outright; two
    ``budget`` layers within a 4° budget: the higher priority takes what it needs first, the
    lower what is left."""
    session = two_layer_session(tmp_path / "exclusive", "exclusive", 10.0, -10.0)
    bird = session.creatures[1]
    run(session, 1.0)
    t, neck = session.clock.now(), bird.body.skeleton.index("neck")
    high = bird.tuples["high"]
    assert high.active and bird.tuples["low"].active
    swing = math.sin(2 * math.pi * (t - high.started_at) / 4.0)
    layer = quat.from_axis_angle(np.array([1.0, 0.0, 0.0]), math.radians(10.0 * swing))
    assert quat.angle_between(bird.body.pose.rotations[neck], layer) < 1e-9
    session = two_layer_session(tmp_path / "budget", "budget", 3.0, 3.0, "budget = 4.0")
    bird = session.creatures[1]
    run(session, 1.0)
    blend, t = bird.body.layers.blend, session.clock.now()
    swing = math.sin(2 * math.pi * (t - bird.tuples["high"].started_at) / 4.0)
    turned = math.degrees(quat.angle_between(bird.body.pose.rotations[neck], bird.body.layers._course[neck]))
    assert abs(3.0 * swing) > 2.0  # both want more than half the budget: the second is cut short
    assert turned == pytest.approx(min(2 * abs(3.0 * swing), 4.0), abs=1e-6)
    assert blend.contributors(t) == {"course": 1.0, "high": 1.0, "low": 1.0}


def test_a_budget_layer_needs_a_budget_and_voice_parameters_have_none(tmp_path):
    with pytest.raises(ConfigError, match=r"look.toml:\d+: .*'budget' shares each joint's budget: set \[creature.body\] budget"):
        two_layer_session(tmp_path / "none", "budget", 3.0, 3.0)
    extra = TWO_LAYERS.format(policy="budget", high=3.0, low=3.0)
    extra = extra.replace('"neck.x" = 3.0 }, period = 4.0, fade = 0.0, blend = { policy = "budget", priority = 1.0',
                          '"voice.gain" = 0.3 }, period = 4.0, fade = 0.0, blend = { policy = "budget", priority = 1.0')
    assert '"voice.gain"' in extra
    path = tmp_path / "look.toml"
    path.write_text(textwrap.dedent(LISTENER.format(tick=TICK, extra=extra, keys="")).replace(
        'figure = "bird"', 'figure = "bird"\nbudget = 4.0', 1))
    with pytest.raises(ConfigError, match="voice parameters have none"):
        load_installation(path)


def test_voice_tension_and_damping_retune_the_scanned_strings(tmp_path):
    """``voice.tension`` and ``voice.damping`` from the config scale the strings' stiffness and
    damping each block the creature sounds, and the strings return to the config's when the
    layer goes; a creature that sings through a mouth is refused them, naming the line."""
    extra = """
[creature.tuples.tune]
action = { type = "oscillate", variables = { "voice.tension" = -0.6, "voice.damping" = 1.0 }, period = 8.0, fade = 0.0 }
until = { seconds = 30.0 }

[creature.groups.tuning]
tuples = ["tune"]
alpha = 0.0
"""
    session = session_of(tmp_path, extra)
    bird = session.creatures[1]
    run(session, 2.0)
    t = session.clock.now()
    swing = math.sin(2 * math.pi * (t - bird.tuples["tune"].started_at) / 8.0)
    base = bird.spec.voice.parameters()
    out = np.zeros(2048)
    bird.sound(out, 22050)
    strings = bird.voice.pool.bank.parameters
    assert strings.stiffness == pytest.approx(base.stiffness * (1.0 - 0.6 * swing))
    assert strings.damping == pytest.approx(base.damping * (1.0 + swing))
    bird.voice_parameters().stop("tune", t)  # the layer gone (no fade): the strings as configured
    session.clock.advance_to(t + 1e-3)
    bird.sound(out, 22050)
    assert bird.voice.pool.bank.parameters == base
    with pytest.raises(ConfigError, match=r"look.toml:\d+: .*voice.tension, a scanned string's: this creature sings "
                                          r"through a mouth"):
        session_of(tmp_path / "mouth", extra, keys="[creature.hearing]")


def test_retuned_strings_sing_differently():
    """A fifth of the tension changes what a plucked scanned string sings (its shape, which is
    its timbre, moves slower), by more than a tenth of its level."""
    from creatures.kinds.parts import Voice, VoiceSpec

    sung = []
    for tension in (1.0, 0.2):
        voice = Voice(VoiceSpec(), 22050)
        voice.retune(tension, 1.0)
        voice.play(60, 100, 10.0)
        out = np.zeros(22050)
        voice.render(out, 0.5)
        sung.append(out)
    level = np.sqrt(np.mean(sung[0] ** 2))
    assert level > 1e-3 and np.sqrt(np.mean((sung[0] - sung[1]) ** 2)) > 0.1 * level


# -- the shipped piece -------------------------------------------------------------------------
def test_the_shipped_exchange_looks_at_whom_it_hears_and_wanders_in_a_bored_manner():
    import installations
    from creatures.authored.skills import heard_bearing

    inst = load_installation(installations.path("exchange"))
    session = Session(inst, SimulatedClock(), EventLog(keep_in_memory=0), MemorySink())
    for k in range(8):
        session.world.inject(NoteEvent(0.5 + 0.4 * k, 60 + 2 * k, 90, 0, 0.3))  # a player, heard by ada
    creatures = {c.name: c for c in session.creatures}
    looked, manners = {name: [] for name in creatures}, {name: [] for name in creatures}
    tick = inst.settings.tick

    def each(t: float) -> None:
        for name, c in creatures.items():
            look = c.tuples["look"]
            if look.active and look.action.servo.reached:  # settled on its source
                looked[name].append((np.sign(heard_bearing(c)), np.sign(look.action.offsets.degrees.sum())))
            if c.tuples["bored manner"].active and c.tuples["wander"].active:
                manners[name].append(c.tuples["bored manner"].action.adverb)

    for step in range(1, int(30.0 / tick) + 1):
        t = step * tick
        session.clock.advance_to(t)
        session.step(t, 1, None, audio=False)
        each(t)
    for name in creatures:
        assert looked[name], f"{name} never looked at anyone"
        assert all(want == turned != 0 for want, turned in looked[name])  # toward whom it heard
        assert manners[name]  # the bored manner layered over the wander
    assert {s for s, _ in looked["bo"]} == {-1.0, 1.0}  # bo, in the middle, turns to ada and to cy
