"""A room in a run (issue 21): notes crossing it late and softer, masking, crowds from one
table, zones, visitors from the input map's sensors, speaker layouts in out.wav, and the
shipped flock piece."""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np
import pytest
import soundfile

import installations
from creatures.clock import SimulatedClock
from creatures.config import ConfigError
from creatures.events import EventLog, read_events
from creatures.room.hearing import SPEED_OF_SOUND, db_velocity, velocity_db
from creatures.room.vehicle import norms
from creatures.runtime.offline import run_offline
from creatures.runtime.schema import load_installation
from creatures.runtime.session import Session
from midi.notes import NoteEvent
from midi.sinks import MemorySink

TICK = 0.02

HEADER = """
title = "room"
seed = 3
tick = 0.02
[output]
report = false
[room]
width = 10.0
depth = 10.0
listener = [5.0, 5.0]
{room}
"""

SINGER = """
[[creature]]
name = "{name}"
kind = "authored"
{extra}
[creature.vehicle]
at = [{x}, {y}]
{vehicle}
[creature.percepts.heard]
type = "heard"
window = 0.2
[creature.tuples.listen]
action = "rest"
until = {{ seconds = 1.0 }}
[creature.tuples.echo]
trigger = "heard"
action = {{ type = "echo", count = 1, mutation = 0.0, velocity = 80 }}
until = {{ done = true, seconds = 2.0 }}
value = {echo}
[creature.groups.main]
tuples = ["listen", "echo"]
alpha = 0.0
"""


TRACKER = "".join(f'[[input]]\nosc = "/v"\nto = "sensor"\nname = "v{axis}"\nvalue = {{ arg = {i} }}\n'
                  for i, axis in enumerate("xy"))
"""A visitor tracker: OSC `/v x y` into the sensors vx and vy."""


def singer(name: str, x: float, y: float, *, vehicle: str = "", extra: str = "", echo: float = 0.0) -> str:
    return SINGER.format(name=name, x=x, y=y, vehicle=vehicle, extra=extra, echo=echo)


def caller(name: str, x: float, y: float, vehicle: str = "") -> str:
    """A singer that also calls a phrase of its own, over and over (for what the speakers carry)."""
    return singer(name, x, y, vehicle=vehicle).replace("[creature.tuples.listen]", (
        "[creature.tuples.call]\naction = { type = \"play_phrase\", pitches = [60, 64, 67], durations = 0.4 }\n"
        "until = { done = true }\nvalue = 5.0\n[creature.tuples.listen]")).replace(
        'tuples = ["listen", "echo"]', 'tuples = ["call", "listen", "echo"]')


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "room.toml"
    path.write_text(textwrap.dedent(text))
    return path


def session(tmp_path: Path, room: str, *creatures: str) -> tuple[Session, SimulatedClock]:
    inst = load_installation(write(tmp_path, HEADER.format(room=room) + "".join(creatures)))
    clock = SimulatedClock()
    return Session(inst, clock, EventLog(), MemorySink()), clock


def run(s: Session, clock: SimulatedClock, until: float, tick: float = TICK) -> None:
    while clock.now() < until - 1e-9:
        t = clock.advance(tick)
        s.step(t, 0, None, audio=False)


def test_a_note_four_metres_away_arrives_late_and_softer(tmp_path):
    s, clock = session(tmp_path, "", singer("a", 2.0, 5.0), singer("b", 6.0, 5.0))
    a, b = s.creatures
    run(s, clock, 0.98)
    s.world.play(a, NoteEvent(1.0, 60, 100, 0, 0.5))
    run(s, clock, 1.0)
    assert b.ear.last(1) == []  # it has started at a; it has not crossed the room yet
    run(s, clock, 1.02)
    (heard,) = b.ear.last(1)
    assert heard.time == pytest.approx(1.0 + 4.0 / SPEED_OF_SOUND, abs=1e-6)
    assert heard.velocity == round(db_velocity(velocity_db(100) - 20 * np.log10(4.0)))  # inverse law, 1 m ref
    assert b.ear.heard_at == pytest.approx(1.02)  # heard at the tick after it arrived


def test_a_loud_near_note_masks_a_quiet_far_one(tmp_path):
    room = "hearing = { margin = 20.0, band = 12.0, threshold = -90.0 }"
    s, clock = session(tmp_path, room, singer("ear", 5.0, 5.0), singer("loud", 5.5, 5.0), singer("quiet", 9.5, 9.5))
    ear, loud, quiet = s.creatures
    run(s, clock, 0.98)
    s.world.play(loud, NoteEvent(1.0, 60, 120, 0, 1.0))
    s.world.play(quiet, NoteEvent(1.05, 62, 60, 0, 0.3))  # −13 dB at the source and 6.4 m away
    run(s, clock, 1.5)
    assert [n.pitch for n in ear.ear.last(4)] == [60]
    assert s.stage.masked >= 1
    run(s, clock, 2.98)
    s.world.play(quiet, NoteEvent(3.0, 62, 60, 0, 0.3))  # the loud one is over: now it is heard
    run(s, clock, 3.2)
    assert [n.pitch for n in ear.ear.last(4)] == [60, 62]


def test_a_phrase_passes_along_a_line_of_singers_hop_by_hop(tmp_path):
    """Each singer hears only its neighbours 1.5 m away (velocity 80 is −8 dB; at 1.5 m −17.5
    dB, at 3 m −23.6 dB, under the −20 dB threshold), and echoes what it hears at its own
    level: the phrase reaches the far end of the line through every singer in turn."""
    room = "hearing = { reference = 0.5, threshold = -20.0 }"
    line = [singer(f"s{i}", 1.0 + 1.5 * i, 5.0, echo=50.0) for i in range(5)]
    s, clock = session(tmp_path, room, *line)
    run(s, clock, 0.5)
    s.world.play(s.creatures[0], NoteEvent(0.52, 72, 80, 0, 0.3))
    run(s, clock, 6.0)
    first: dict[str, float] = {}
    for n in s.log.records:
        if n["kind"] == "note":
            first.setdefault(n["creature"], n["time"])
    times = [first.get(f"s{i}") for i in range(5)]
    assert None not in times, first
    assert times == sorted(times) and len(set(times)) == 5  # hop by hop down the line
    heard_far = [n for n in s.creatures[2].ear.last(8) if n.time < times[1]]
    assert heard_far == []  # s2 heard nothing of s0's own note: only s1's echo reached it


def test_count_and_vary_make_a_seeded_crowd(tmp_path):
    crowd = singer("bird", 5.0, 5.0).replace('name = "bird"', 'name = "bird"\ncount = 6\n'
                                             'vary = { "vehicle.max_speed" = [0.5, 1.5], "channel" = [0, 3] }')
    crowd = crowd.replace("at = [5.0, 5.0]", "")
    inst = load_installation(write(tmp_path, HEADER.format(room="") + crowd))
    assert [s.name for s in inst.specs] == [f"bird-{i}" for i in range(6)]
    speeds = [s.vehicle.max_speed for s in inst.specs]
    assert all(0.5 <= v <= 1.5 for v in speeds) and len(set(speeds)) == 6
    assert {s.channel for s in inst.specs} <= {0, 1, 2, 3}
    again = load_installation(write(tmp_path, HEADER.format(room="") + crowd))
    assert [s.vehicle.max_speed for s in again.specs] == speeds
    s = Session(inst, SimulatedClock(), EventLog(), MemorySink())
    pos = s.stage.v.pos
    assert len({tuple(p) for p in pos.round(6)}) == 6  # each placed apart, at seeded random


@pytest.mark.parametrize("old, new, key, message", [
    ('count = 6', 'count = 0', "count", "count must be a whole number"),
    ('"vehicle.max_speed" = [0.5, 1.5]', '"vehicle.max_speed" = [1.5, 0.5]', "vary", "is not a range"),
])
def test_bad_crowds_are_errors_at_the_table(tmp_path, old, new, key, message):
    crowd = singer("bird", 5.0, 5.0).replace('name = "bird"', 'name = "bird"\ncount = 6\n'
                                             'vary = { "vehicle.max_speed" = [0.5, 1.5] }').replace(old, new)
    with pytest.raises(ConfigError, match=message) as info:
        load_installation(write(tmp_path, HEADER.format(room="") + crowd))
    assert info.value.line is not None


@pytest.mark.parametrize("steer, message", [
    ('steer = [{ behaviour = "seek", target = "nobody" }]', "no creature named 'nobody'"),
    ('steer = [{ behaviour = "seak" }]', "did you mean 'seek'"),
    ('steer = [{ behaviour = "path_following", path = "aisle" }]', "path_following needs path"),
    # the table a field is named in is [[room.flows]]: the message said [[room.fields]], which is no key
    ('steer = [{ behaviour = "flow_following", field = "rond" }]',
     "flow_following needs field = one of the room's \\[\\[room.flows\\]\\] names, got 'rond' "
     "\\(\\[\\[room.flows\\]\\]: none\\)"),
    ('steer = [{ behaviour = "seek", when = "hungry" }]', "no percept 'hungry'"),
    # a slip is said with the nearest name, as everywhere else in a config
    ('steer = [{ behaviour = "seek", target = "visiter" }]', "no creature named 'visiter' .*did you mean 'visitor'"),
    ('steer = [{ behaviour = "seek", target = "b" }]', "no creature named 'b' to steer by \\(targets: .*centre.*\\[x, y\\]\\)"),
    ('steer = [{ behaviour = "seek", when = "heardd" }]', "no percept 'heardd' \\(did you mean 'heard'"),
])
def test_steering_that_names_what_is_not_there_is_a_config_error(tmp_path, steer, message):
    path = write(tmp_path, HEADER.format(room="") + singer("a", 1.0, 1.0, vehicle=steer))
    with pytest.raises(ConfigError, match=message) as info:
        load_installation(path)
    assert info.value.line is not None


@pytest.mark.parametrize("steer, message", [
    # loaded, then the first sub-step raised "seek() got an unexpected keyword argument 'panic'"
    ('{ behaviour = "seek", target = "centre", panic = 2.0 }',
     "panic is a key of flee and evasion, not of seek \\(seek takes: target, weight, probability, when\\)"),
    ('{ behaviour = "separation", target = "centre" }', "target is a key of seek, flee, .*, not of separation"),
    ('{ behaviour = "wander", path = "aisle" }', "path is a key of path_following, not of wander "
                                                 "\\(wander takes: rate, weight, probability, when\\)"),
])
def test_a_steering_key_its_behaviour_does_not_take_is_a_config_error(tmp_path, steer, message):
    path = write(tmp_path, HEADER.format(room="") + singer("a", 1.0, 1.0, vehicle=f"steer = [{steer}]"))
    with pytest.raises(ConfigError, match=message) as info:
        load_installation(path)
    assert info.value.line is not None and "vehicle.steer.0" in str(info.value)


@pytest.mark.parametrize("vehicle, percept, key, message", [
    ('steer = [{ behaviour = "seek" }]', "", "vehicle.steer.0.target",
     "seek steers to the nearest tracked visitor \\(its target when none is given\\), and the room tracks none"),
    ('steer = [{ behaviour = "wander" }, { behaviour = "flee", target = "visitor" }]', "", "vehicle.steer.1.target",
     "flee steers to the nearest tracked visitor, and the room tracks none"),
    ("", 'type = "proximity"', "percepts.near.of",
     "proximity of the nearest tracked visitor \\(its 'of' when none is given\\), and the room tracks none"),
    ("", 'type = "sees"\nof = "visitor"', "percepts.near.of", "sees of the nearest tracked visitor, and the room"),
])
def test_a_visitor_in_a_room_that_tracks_none_is_a_config_error(tmp_path, vehicle, percept, key, message):
    """Without [[room.visitors]] there is never a visitor: a creature seeking one stood still and
    a percept of one read 0 for the whole run, nothing said."""
    creature = singer("a", 1.0, 1.0, vehicle=vehicle)
    if percept:
        creature = creature.replace("[creature.percepts.heard]", f"[creature.percepts.near]\n{percept}\n"
                                                                 "[creature.percepts.heard]")
    with pytest.raises(ConfigError, match=message) as info:
        load_installation(write(tmp_path, HEADER.format(room="") + creature))
    assert info.value.line is not None and key in str(info.value) and "[[room.visitors]]" in str(info.value)
    tracked = HEADER.format(room='visitors = [{ x = "vx", y = "vy" }]') + TRACKER + creature
    assert load_installation(write(tmp_path, tracked)).specs[0].name == "a"  # with a tracked visitor it loads


def test_room_percepts_need_a_room(tmp_path):
    text = HEADER.format(room="").replace("[room]\nwidth = 10.0\ndepth = 10.0\nlistener = [5.0, 5.0]\n", "")
    text += singer("a", 1.0, 1.0).replace("[creature.percepts.heard]", "[creature.percepts.near]\ntype = "
                                          "\"proximity\"\n[creature.percepts.heard]")
    with pytest.raises(ConfigError, match="needs a \\[room\\]"):
        load_installation(write(tmp_path, text))


@pytest.mark.parametrize("vehicle", ['steer = [{ behaviour = "wander" }]', "max_speed = 0.5"])
def test_a_vehicle_without_a_room_is_a_config_error(tmp_path, vehicle):
    """A [creature.vehicle] (a place, steering) in an installation with no [room] loaded and ran
    as if it were not there: the creature never moved, nothing said (copying a crowd's creature
    into a piece without its [room] table, say)."""
    text = HEADER.format(room="").replace("[room]\nwidth = 10.0\ndepth = 10.0\nlistener = [5.0, 5.0]\n", "")
    text += singer("a", 1.0, 1.0, vehicle=vehicle)
    with pytest.raises(ConfigError, match="there is no \\[room\\]") as info:
        load_installation(write(tmp_path, text))
    assert info.value.line == text.splitlines().index("[creature.vehicle]") + 1
    assert "creature.0.vehicle" in str(info.value)


def test_a_proximity_whose_near_is_beyond_its_far_is_a_config_error(tmp_path):
    """``near = 5.0, far = 1.0`` (the two swapped) loaded and read 1 with no one within 5 m and 0
    with someone beside it: the percept meant "someone is near" said "no one is", all run.
    ``near = far`` (a step at that distance) still loads."""
    percept = '[creature.percepts.near]\ntype = "proximity"\nof = "creature"\nnear = {near}\nfar = 1.0\n'

    def text(near: float) -> str:
        return HEADER.format(room="") + singer("a", 1.0, 1.0).replace(
            "[creature.percepts.heard]", percept.format(near=near) + "[creature.percepts.heard]")

    with pytest.raises(ConfigError, match="near = 5 m is beyond far = 1 m") as info:
        load_installation(write(tmp_path, text(5.0)))
    assert info.value.line == text(5.0).splitlines().index("far = 1.0") + 1
    assert load_installation(write(tmp_path, text(1.0))).specs[0].name == "a"


def test_a_zone_changes_a_creature_inside_and_puts_it_back_when_it_leaves(tmp_path):
    room = """[[room.zones]]
name = "slow"
low = [4.5, 0.0]
high = [5.5, 10.0]
drives = { calm = 0.9 }
spec = { max_speed = 0.25 }
disable = ["echo"]
"""
    walker = singer("w", 1.0, 5.0, vehicle='steer = [{ behaviour = "seek", target = [9.5, 5.0] }]',
                    extra="[creature.drives.calm]\nlevel = 0.1")
    s, clock = session(tmp_path, room, walker)
    w = s.creatures[0]
    speeds, calm, disabled = [], [], []
    while clock.now() < 12.0:
        run(s, clock, clock.now() + 0.2)
        x = s.stage.v.pos[0, 0]
        speeds.append((x, s.stage.v.speed()[0]))
        calm.append((x, w.motivation.level("calm", clock.now())))
        disabled.append((x, "echo" in w.groups["main"].disabled))
    inside = [v for x, v in speeds if 4.8 < x < 5.4]
    after = [v for x, v in speeds if x > 7.5]
    assert inside and max(inside) <= 0.25 + 1e-9
    assert after and max(after) > 0.9  # its own max_speed back
    assert all(c == pytest.approx(0.9, abs=0.05) for x, c in calm if 4.8 < x < 5.4)
    assert all(c == pytest.approx(0.1, abs=0.05) for x, c in calm if x > 7.5)
    assert all(d for x, d in disabled if 4.8 < x < 5.4) and not any(d for x, d in disabled if x > 7.5)
    kinds = [(e["zone"], e["inside"]) for e in s.log.records if e["kind"] == "zone"]
    assert kinds == [("slow", True), ("slow", False)]


def test_a_zone_s_gain_makes_a_creature_quieter_inside_and_its_own_gain_returns(tmp_path):
    """A caller walks through a zone with spec { gain = 0.1 } (its own is 0.8): while inside,
    its share of the mix is 1/8 of the same walk's without the zone, and once out it is the
    same again (the spec key set and put back as the console's set would)."""
    hush = """[[room.zones]]
name = "hush"
low = [4.0, 0.0]
high = [6.0, 10.0]
spec = { gain = 0.1 }
"""
    seek = 'steer = [{ behaviour = "seek", target = [9.5, 5.0] }]'

    def walk(room: str) -> tuple[list[float], list[float], list[float]]:
        s, clock = session(tmp_path, room, caller("c", 1.0, 5.0, seek))
        frames = round(TICK * s.sample_rate)
        xs, rms, gain = [], [], []
        while clock.now() < 10.0 - 1e-9:
            t = clock.advance(TICK)
            mix = s.step(t, frames, None)
            xs.append(float(s.stage.v.pos[0, 0]))
            rms.append(float(np.sqrt((mix ** 2).mean())))
            gain.append(s.creatures[0].spec.gain)
        return xs, rms, gain

    xs, quiet, gain = walk(hush)
    _, loud, _ = walk("")
    inside = [q / lo for x, q, lo in zip(xs, quiet, loud) if 4.3 < x < 5.7 and lo > 1e-4]
    after = [(q, lo) for x, q, lo in zip(xs, quiet, loud) if x > 6.5]
    assert len(inside) > 10 and all(r == pytest.approx(0.1 / 0.8, rel=0.02) for r in inside)
    assert after and all(q == pytest.approx(lo, rel=1e-6) for q, lo in after) and max(lo for _, lo in after) > 1e-3
    assert {g for x, g in zip(xs, gain) if 4.3 < x < 5.7} == {0.1} and gain[-1] == 0.8


def test_a_zone_sets_a_key_of_a_creature_with_a_figure_body(tmp_path):
    """A dog (``body = { figure = "dog" }``) walks into a zone with spec { gain = 0.1 }: the
    key is set as for any creature (the spec once re-validated with every default as if
    written, and a figure body with files beside it was refused)."""
    hush = "[[room.zones]]\nname = \"hush\"\nlow = [4.0, 0.0]\nhigh = [6.0, 10.0]\nspec = { gain = 0.1 }\n"
    dog = caller("d", 1.0, 5.0, 'steer = [{ behaviour = "seek", target = [9.5, 5.0] }]').replace(
        'kind = "authored"', 'kind = "authored"\nbody = { figure = "dog" }', 1)
    s, clock = session(tmp_path, hush, dog)
    gains = []
    while clock.now() < 10.0 - 1e-9:
        s.step(clock.advance(TICK), round(TICK * s.sample_rate), None, audio=False)
        gains.append((float(s.stage.v.pos[0, 0]), s.creatures[0].spec.gain))
    assert {g for x, g in gains if 4.3 < x < 5.7} == {0.1} and gains[-1][1] == 0.8
    assert s.creatures[0].spec.body.figure == "dog"


def test_a_zone_with_hears_input_false_shuts_out_the_input_inside_only(tmp_path):
    """spec { hears_input = false } inside a zone: a walker crossing it hears the player's
    notes (input, ten a second) before and after the zone and none inside, while it still
    hears another creature's notes there."""
    deaf = """input_at = [5.0, 9.0]
[[room.zones]]
name = "deaf"
low = [4.0, 0.0]
high = [6.0, 10.0]
spec = { hears_input = false }
"""
    walker = singer("w", 1.0, 5.0, vehicle='steer = [{ behaviour = "seek", target = [9.5, 5.0] }]')
    s, clock = session(tmp_path, deaf, walker, singer("other", 5.0, 3.0, vehicle="max_speed = 0.01"))
    w, other = s.creatures
    heard: list[tuple[float, str]] = []
    hear = w.hear
    w.hear = lambda note, source: (heard.append((float(s.stage.v.pos[0, 0]), source)), hear(note, source))
    k = 0
    while clock.now() < 10.0 - 1e-9:
        t = clock.advance(TICK)
        if k % 5 == 0:
            s.world.inject(NoteEvent(round(t, 6), 60 + k % 12, 100, 0, 0.05))
            s.world.play(other, NoteEvent(round(t, 6), 48, 100, 0, 0.05))
        s.step(t, 0, None, audio=False)
        k += 1
    def sources(lo: float, hi: float) -> set[str]:
        return {source for x, source in heard if lo < x < hi}
    assert sources(0.0, 3.9) == {"input", "other"}
    assert sources(4.1, 5.9) == {"other"}  # inside: the other creature, not the player
    assert sources(6.1, 10.0) == {"input", "other"}
    assert w.spec.hears_input


def test_overlapping_zones_give_the_latest_zone_s_values_and_the_own_back_after_the_last(tmp_path):
    """Zones "wide" (3–5 m) and "slow" (4–6 m) overlap: the walker entering wide then slow
    keeps slow's speed and calm after leaving wide, and its own once out of slow; a tuple both
    enable stays on across the overlap. (Each zone's own undo once put its own speed back at 5 m.)"""
    room = """[[room.zones]]
name = "wide"
low = [3.0, 0.0]
high = [5.0, 10.0]
drives = { calm = 0.5 }
spec = { max_speed = 0.5 }
enable = ["echo"]

[[room.zones]]
name = "slow"
low = [4.0, 0.0]
high = [6.0, 10.0]
drives = { calm = 0.9 }
spec = { max_speed = 0.25 }
enable = ["echo"]
"""
    walker = singer("w", 1.0, 5.0, vehicle='steer = [{ behaviour = "seek", target = [9.5, 5.0] }]',
                    extra="[creature.drives.calm]\nlevel = 0.1")
    s, clock = session(tmp_path, room, walker)
    w = s.creatures[0]
    track = []
    while clock.now() < 20.0:
        run(s, clock, clock.now() + 0.2)
        track.append((s.stage.v.pos[0, 0], s.stage.v.speed()[0], w.motivation.level("calm", clock.now()),
                      "echo" not in w.groups["main"].disabled))
    def where(lo, hi):
        return [(speed, calm, echo) for x, speed, calm, echo in track if lo < x < hi]
    assert where(3.2, 3.8) and all(sp <= 0.5 + 1e-9 and c == pytest.approx(0.5, abs=0.05) and e
                                   for sp, c, e in where(3.2, 3.8))
    assert where(5.2, 5.8) and all(sp <= 0.25 + 1e-9 and c == pytest.approx(0.9, abs=0.05) and e
                                   for sp, c, e in where(5.2, 5.8))  # out of wide, still in slow
    after = where(7.5, 10.0)
    assert after and max(sp for sp, _, _ in after) > 0.9
    assert all(c == pytest.approx(0.1, abs=0.05) and not e for _, c, e in after)
    assert not any(e for _, _, e in where(0.0, 2.8))  # enabled only inside its zones


def test_a_visitor_from_the_tracker_is_sought_and_fled(tmp_path):
    room = 'visitors = [{ x = "vx", y = "vy" }]'
    maps = TRACKER
    near = singer("near", 2.0, 2.0, vehicle='steer = [{ behaviour = "arrival", target = "visitor", slowing = 1.0 }]')
    shy = singer("shy", 7.0, 7.0, vehicle='steer = [{ behaviour = "flee", target = "visitor", panic = 4.0 }]')
    inst = load_installation(write(tmp_path, HEADER.format(room=room) + maps + near + shy))
    clock = SimulatedClock()
    s = Session(inst, clock, EventLog(), MemorySink())
    for k in range(int(10.0 / TICK)):
        t = clock.advance(TICK)
        if k % 5 == 0:  # a tracker at 10 Hz
            s.inputs.osc("/v", [6.0, 6.0], t)
        s.step(t, 0, None, audio=False)
    assert np.linalg.norm(s.stage.v.pos[0] - [6.0, 6.0]) < 0.1
    assert np.linalg.norm(s.stage.v.pos[1] - [6.0, 6.0]) > 3.9


def test_a_visitor_the_tracker_gives_one_coordinate_of_is_said_once(tmp_path):
    """A tracker sending x alone (or a map reading the wrong argument) left the visitor never
    shown and nothing said: it is a ``room visitor half`` event once its timeout has passed,
    once, and not while the visitor is seen whole."""
    room = 'visitors = [{ x = "vx", y = "vy", timeout = 1.0 }]'
    log = EventLog()
    inst = load_installation(write(tmp_path, HEADER.format(room=room) + TRACKER.replace('"/v"', '"/vx"', 1)
                                   + singer("a", 2.0, 2.0)))
    clock = SimulatedClock()
    s = Session(inst, clock, log, MemorySink())
    for k in range(int(6.0 / TICK)):
        t = clock.advance(TICK)
        if k % 5 == 0:
            s.inputs.osc("/vx", [6.0], t)  # x alone, for 3 s; then both
            if t > 3.0:
                s.inputs.osc("/v", [0.0, 6.0], t)
        s.step(t, 0, None, audio=False)
    half = [e for e in log.records if e["kind"] == "room visitor half"]
    assert [(e["visitor"], e["heard"], e["missing"]) for e in half] == [(0, "vx", "vy")]
    assert 1.0 <= half[0]["t"] <= 1.2
    assert len(s.stage.crowd.around.visitors) == 1  # seen whole at the end


def test_a_ring_of_speakers_writes_one_channel_each_panned_by_place(tmp_path):
    room = 'speakers = "ring"\nchannels = 4'
    inst = load_installation(write(tmp_path, HEADER.format(room=room) + caller("east", 9.0, 5.0)))
    run_offline(inst, tmp_path / "out", duration=3.0)
    wav, _ = soundfile.read(tmp_path / "out" / "out.wav")
    assert wav.shape[1] == 4
    rms = np.sqrt((wav ** 2).mean(0))
    assert rms[0] > 0.001  # speaker 0 at azimuth 0 (+x, east of the listener) carries it
    assert rms[0] > 20 * max(rms[1:])


def test_a_dome_writes_one_channel_per_speaker_near_overhead_far_at_ear_height(tmp_path):
    """speakers = "dome": the floor is projected onto the dome, so a caller 0.5 m from the
    listener sounds mostly from the top speaker and one 4 m off (dome_reach) from the ring."""
    room = 'speakers = "dome"\ndome_reach = 4.0'
    rms = {}
    for where, (x, y) in {"near": (5.5, 5.0), "far": (9.0, 5.0)}.items():
        inst = load_installation(write(tmp_path, HEADER.format(room=room) + caller("east", x, y, "max_speed = 0.01")))
        run_offline(inst, tmp_path / where, duration=3.0)
        wav, _ = soundfile.read(tmp_path / where / "out.wav")
        assert wav.shape[1] == 13
        rms[where] = np.sqrt((wav ** 2).mean(0))
    near, far = rms["near"], rms["far"]
    assert near[12] > 0.001 and near[12] > 2 * max(near[:12])  # overhead: 83° up
    assert far[0] > 0.001 and far[0] > 20 * max(np.delete(far, 0))  # east, at ear height: speaker 0 alone


@pytest.mark.parametrize("room, message", [
    ('speakers = "dome"\nchannels = 8', "a dome has one channel per speaker"),
    ('dome = [[0.0, 0.0], [120.0, 0.0], [240.0, 0.0]]', "for speakers = \"dome\""),
    ('speakers = "dome"\ndome = [[0.0, 100.0], [120.0, 0.0], [240.0, 0.0]]', "less than or equal to 90"),
    ('speakers = "dome"\ndome = [[0.0, 0.0], [90.0, 0.0], [180.0, 0.0], [270.0, 0.0]]', "above ear height"),
    ('speakers = "dome"\ndome = [[0.0, 0.0], [0.0, 0.0], [0.0, 0.0]]', "span no solid|above ear height"),
])
def test_a_dome_that_cannot_be_is_a_config_error(tmp_path, room, message):
    with pytest.raises(ConfigError, match=message):
        load_installation(write(tmp_path, HEADER.format(room=room) + singer("a", 1.0, 1.0)))


@pytest.mark.slow
def test_the_flock_gathers_round_whoever_plays_scatters_at_a_loud_chord_and_passes_phrases_along(tmp_path):
    inst = load_installation(installations.path("flock"))
    inst.settings.output.report = False
    run_offline(inst, tmp_path, duration=60.0)
    events = read_events(tmp_path / "events.jsonl")
    rooms = {round(e["t"]): e for e in events if e["kind"] == "room"}
    first, second = np.array([11.0, 3.0]), np.array([3.5, 7.5])  # flock-rehearsal.csv's visitor: 8-30 s, 34-60 s

    def spread(t: int, visitor: np.ndarray) -> float:
        return float(np.linalg.norm(np.array(rooms[t]["pos"]) - visitor, axis=1).mean())

    assert spread(0, first) > 4.0
    assert spread(26, first) < 2.5  # gathered round the player
    assert spread(34, second) > 4.0 and spread(56, second) < 2.5  # and followed them across the room
    gap = min(np.linalg.norm(np.array(rooms[t]["pos"]) - first, axis=1).min() for t in range(16, 30))
    assert gap > 0.6  # leaving them their own space (flee within 0.8 m)
    singers = {e["creature"] for e in events if e["kind"] == "note" and e["t"] > 10}
    assert len(singers) == 15  # every singer took part

    def nearest(t: int) -> float:
        return float(np.linalg.norm(np.array(rooms[t]["pos"]) - second, axis=1).min())

    # The loud chord at 50 s (velocity 124, where the visitor stands) scatters the flock for a
    # moment (flee from loud within 4 m), and it gathers again.
    assert spread(51, second) > spread(49, second) + 0.4 and nearest(51) > nearest(49) + 0.25
    assert spread(53, second) < spread(51, second)
    # Phrases pass along the flock with no one playing: before the visitor comes in (8 s) the
    # only notes are the singers' own, and many of them pass on what they heard of another.
    passed = [e for e in events if e["kind"] == "selection" and e["tuple"] == "pass it on" and e["t"] < 8.0]
    assert not [e for e in events if e["kind"] == "heard" and e["time"] < 8.0]
    assert len({e["creature"] for e in passed}) >= 8


def test_a_pitch_above_nyquist_sounds_octaves_down_instead_of_crashing():
    """A phrase passed along a flock with mutations can drift to MIDI 127 (12.5 kHz), above
    the 11.025 kHz Nyquist of a 22050 Hz run: the voice sounds it octaves down."""
    from audio.voices import VoicePool

    pool = VoicePool(1, sample_rate=22050.0, block_size=256)
    i = pool.note_on(127, 1.0)
    assert pool.voices[i].frequency == pytest.approx(12543.85 / 2, rel=1e-3)


def test_a_path_a_percept_gated_weight_and_level_of_detail_from_the_config(tmp_path):
    room = """lod = { near = 3.0, levels = 2, budget = 2 }
[[room.paths]]
name = "aisle"
points = [[1.0, 2.0], [9.0, 2.0]]
radius = 0.3
"""
    follower = singer("f", 1.0, 2.5, vehicle='steer = [{ behaviour = "path_following", path = "aisle" }]')
    # It seeks the room's corner only while its "heard" percept is salient: nothing is heard.
    gated = singer("g", 5.0, 8.0, vehicle='steer = [{ behaviour = "seek", target = [9.5, 9.5], when = "heard" }]')
    s, clock = session(tmp_path, room, follower, gated)
    joined, worst = None, 0.0
    while clock.now() < 8.0 - 1e-9:
        run(s, clock, clock.now() + TICK)
        off = abs(s.stage.v.pos[0, 1] - 2.0) if 1.0 <= s.stage.v.pos[0, 0] <= 9.0 else np.inf
        joined = clock.now() if joined is None and off <= 0.3 else joined
        worst = max(worst, off) if joined is not None else worst
    f, g = s.stage.v.pos
    assert f[0] > 7.0 and joined is not None and worst <= 0.3  # on the aisle from when it joined it
    assert np.allclose(g, [5.0, 8.0])  # its weight is 0 while it hears nothing
    assert s.stage.crowd.gain[1, 0] == 0.0
    assert s.stage.crowd.steered <= 2 * s.stage.crowd.steps  # the budget: two steerings per sub-step


def test_room_percepts_read_distance_bearing_crowding_and_sight(tmp_path):
    room = 'visitors = [{ x = "vx", y = "vy" }]\nobstacles = [{ at = [5.0, 8.0], radius = 0.5 }]'
    maps = TRACKER
    percepts = """
[creature.percepts]
close = { type = "proximity", near = 1.0, far = 5.0 }
ahead = { type = "bearing", width = 90.0 }
crowded = { type = "crowding", radius = 1.5, full = 2 }
seen = { type = "sees" }
[creature.percepts.heard]"""
    me = singer("me", 2.0, 5.0, vehicle="heading = 0.0\nfov = 120.0").replace("[creature.percepts.heard]", percepts)
    others = [singer("n1", 2.0, 6.0), singer("n2", 3.0, 8.0), singer("far", 8.0, 8.0)]
    inst = load_installation(write(tmp_path, HEADER.format(room=room) + maps + me + "".join(others)))
    clock = SimulatedClock()
    s = Session(inst, clock, EventLog(), MemorySink())
    t = clock.advance(TICK)
    s.inputs.osc("/v", [5.0, 5.0], t)  # 3 m straight ahead
    s.step(t, 0, None, audio=False)
    c = s.creatures[0]

    def value(name: str) -> float:
        return c.percept(name).evaluate(t)

    assert value("close") == pytest.approx(0.5)  # 3 m on the ramp from 5 m (0) to 1 m (1)
    assert value("ahead") == pytest.approx(1.0)
    assert value("crowded") == pytest.approx(0.5)  # n1 within 1.5 m; n2 and far are not
    assert value("seen") == 1.0
    t = clock.advance(TICK)
    s.inputs.osc("/v", [2.0, 2.0], t)  # now 3 m to its right: 90° off its heading, outside the cone
    s.step(t, 0, None, audio=False)
    assert value("ahead") == 0.0 and value("seen") == 0.0 and value("close") == pytest.approx(0.5)
    assert s.stage.sees("me", "creature") == 1  # 'far' (27° off); n1 (90°) and n2 (72°) are outside the cone


def test_a_creature_behind_an_obstacle_is_not_seen_by_the_stage(tmp_path):
    room = 'obstacles = [{ at = [5.0, 5.0], radius = 0.5 }]'
    s, _ = session(tmp_path, room, singer("eye", 2.0, 5.0, vehicle="heading = 0.0"),
                   singer("hidden", 8.0, 5.0), singer("open", 8.0, 6.5))
    assert s.stage.sees("eye", "creature") == 1  # 'open' only


@pytest.mark.parametrize("room, creature, message", [
    ("", 'at = [12.0, 5.0]', "outside the 10 x 10 m room"),
    ('input_at = [5.0, 11.0]', "", "input_at \\[5.0, 11.0\\] is outside"),
    ("", 'at = [1.0, 1.0]\nradius = 6.0', "a body of radius 6 m does not fit in the 10 x 10 m room"),
    ('obstacles = [{ at = [1.5, 1.0], radius = 0.8 }]', "", "start \\[1.0, 1.0\\] is inside obstacle 0"),
    ('obstacles = [{ at = [11.0, 5.0], radius = 0.8 }]', "", "obstacle \\[11.0, 5.0\\] of radius 0.8 m lies outside"),
    ("", 'at = [1.0, 1.0]\nsteer = [{ behaviour = "seek", target = [5.0, 12.0] }]',
     "target \\[5.0, 12.0\\] is outside the 10 x 10 m room"),
    # aimed into a pillar, or a note object laid within one: pressed against it all run, never struck
    ('obstacles = [{ at = [5.0, 5.0], radius = 1.0 }]', 'at = [1.0, 1.0]\nsteer = [{ behaviour = "seek", target = [5.2, 5.0] }]',
     "target \\[5.2, 5.0\\] is inside obstacle 0 \\(at \\[5.0, 5.0\\], radius 1 m\\): the creature would press"),
    ('obstacles = [{ at = [5.0, 5.0], radius = 1.0 }]\n[[room.notes]]\nat = [5.5, 5.0]\npitch = 60', "",
     "note object \\[5.5, 5.0\\] \\(radius 0.3 m\\) lies inside obstacle 0 .*: no creature could step onto it"),
    ('[[room.paths]]\nname = "p"\npoints = [[1.0, 1.0], [11.0, 1.0]]', "", "path 'p': point \\[11.0, 1.0\\] is outside"),
    # a path drawn through a pillar: followers pressed against it (one of four stood there 10 s of 20)
    ('obstacles = [{ at = [5.0, 5.0], radius = 1.0 }]\n[[room.paths]]\nname = "p"\npoints = [[1.0, 5.5], [9.0, 5.5]]',
     "", "path 'p': from \\[1.0, 5.5\\] to \\[9.0, 5.5\\] it passes through obstacle 0 \\(at \\[5.0, 5.0\\], radius 1 m\\)"),
    ('[[room.zones]]\nname = "z"\nlow = [11.0, 0.0]\nhigh = [12.0, 4.0]', "", "zone 'z' .* lies outside the 10 x 10"),
    ('[[room.zones]]\nname = "z"\nlow = [3.0, 0.0]\nhigh = [3.0, 4.0]', "", "zone 'z' .* has no area"),
    ("", 'at = [1.0, 1.0]\nmass = 1e-310', "vehicle.mass: Input should be greater than or equal to 0.001"),
    ('[[room.zones]]\nname = "z"\nlow = [3.0, 0.0]\nhigh = [4.0, 4.0]\nspec = { max_speed = 500.0 }', "",
     "zone 'z': spec\\['max_speed'\\] = 500.0: Input should be less than or equal to 100"),
    ('[[room.zones]]\nname = "z"\nlow = [3.0, 0.0]\nhigh = [4.0, 4.0]\nspec = { mass = 1e-310 }', "",
     "zone 'z': spec\\['mass'\\] = 1e-310: Input should be greater than or equal to 0.001"),
    ('[[room.zones]]\nname = "z"\nlow = [3.0, 0.0]\nhigh = [4.0, 4.0]\nspec = { radius = 5.5 }', "",
     "zone 'z': a body of radius 5.5 m does not fit"),
    ('[[room.flows]]\nname = "f"\n[[room.flows]]\nname = "f"\nshape = "uniform"', "", "two \\[\\[room.flows\\]\\] are named 'f'"),
    ('[[room.zones]]\nname = "z"\nlow = [0.0, 0.0]\nhigh = [1.0, 1.0]\ndrives = { hungre = 1.0 }', "",
     "no creature has a drive 'hungre'"),
    ('[[room.zones]]\nname = "z"\nlow = [0.0, 0.0]\nhigh = [1.0, 1.0]\nenable = ["dance"]', "",
     "no creature has a tuple 'dance'"),
    ('[[room.zones]]\nname = "z"\nlow = [0.0, 0.0]\nhigh = [1.0, 1.0]\nenable = ["ech"]', "",
     "no creature has a tuple 'ech' \\(did you mean 'echo'"),
    ('[[room.zones]]\nname = "z"\nlow = [0.0, 0.0]\nhigh = [1.0, 1.0]\nspec = { gian = 0.5 }', "",
     "spec key 'gian' is neither a vehicle key .* nor any creature's spec key \\(did you mean 'gain'\\?\\)"),
    ('[[room.zones]]\nname = "z"\nlow = [0.0, 0.0]\nhigh = [1.0, 1.0]\nspec = { gain = 9.0 }', "",
     "creature 'a': gain: Input should be less than or equal to 4"),
    ('[[room.zones]]\nname = "z"\nlow = [0.0, 0.0]\nhigh = [1.0, 1.0]\nspec = { name = "b" }', "",
     "name cannot change while the creature runs"),
    ('[[room.zones]]\nname = "z"\nlow = [0.0, 0.0]\nhigh = [1.0, 1.0]\nspec = { "vehicle.max_speed" = 0.5 }', "",
     "set by their own names"),
    ('visitors = [{ x = "vxx", y = "vy" }]\n' + TRACKER, "", "no input map writes a sensor 'vxx' \\(did you mean 'vx'"),
    ('visitors = [{ x = "vx", y = "vy" }]', "", "no input map writes a sensor 'vx' \\(no \\[\\[input\\]\\] map"),
    # a visitor table copied unchanged counted one person twice; y = x walked them on the diagonal
    ('visitors = [{ x = "vx", y = "vy" }, { x = "vx", y = "vy" }]\n' + TRACKER, "",
     "sensor 'vx' is read by visitor 0's x already"),
    ('visitors = [{ x = "vx", y = "vx" }]\n' + TRACKER, "", "sensor 'vx' is read by visitor 0's x already"),
])
def test_places_and_zones_that_cannot_be_are_config_errors(tmp_path, room, creature, message):
    text = HEADER.format(room=room) + singer("a", 1.0, 1.0).replace("at = [1.0, 1.0]", creature or "at = [1.0, 1.0]")
    with pytest.raises(ConfigError, match=message) as info:
        load_installation(write(tmp_path, text))
    assert info.value.line is not None
    assert info.value.file.name == "room.toml"


def quadrants(radius: float) -> str:
    """Four pillars, one in each quarter of the 10 m room: of radius 3.4 m, with a 0.25 m body's
    reach they cover the floor; of 3.2 m they leave a diamond round the middle."""
    return "obstacles = [" + ", ".join(f"{{ at = [{x}, {y}], radius = {radius} }}" for x in (2.5, 7.5)
                                       for y in (2.5, 7.5)) + "]"


@pytest.mark.parametrize("obstacles, key", [
    ("obstacles = [{ at = [5.0, 5.0], radius = 100.0 }]", "room.obstacles.0.radius"),  # 100 for 1.0
    (quadrants(3.4), "room.obstacles:"),
])
def test_obstacles_that_leave_no_floor_to_start_on_are_a_config_error(tmp_path, obstacles, key):
    """A creature with no ``at`` starts at a seeded free place; obstacles over the whole floor
    left none, so it started inside one (the last of 100 draws) and the walls and the obstacle
    between them held it in a corner for the whole run, nothing said."""
    unplaced = singer("a", 1.0, 1.0).replace("at = [1.0, 1.0]\n", "")
    with pytest.raises(ConfigError, match="covers? the whole floor .* no place where 'a' \\(radius 0.25 m\\)") as info:
        load_installation(write(tmp_path, HEADER.format(room=obstacles) + unplaced))
    assert info.value.line is not None and key in str(info.value)
    s, clock = session(tmp_path, quadrants(3.2), unplaced)  # a gap of a few cm a side is enough
    run(s, clock, 0.1)
    assert np.hypot(*(s.stage.v.pos[0] - 5.0)) < 0.2


def test_a_flow_field_of_more_cells_than_a_painted_one_may_have_is_a_config_error(tmp_path):
    """0.02 m cells over a 1000 m square room: 2.5e9 cells, 40 GB asked for as the run began."""
    text = (HEADER.format(room='[[room.flows]]\nname = "f"\ncell = 0.02').replace("= 10.0", "= 1000.0")
            + singer("a", 1.0, 1.0))
    with pytest.raises(ConfigError, match="flow 'f': cells of 0.02 m make 2.5e\\+09 over the 1000 x 1000 m room, "
                                          "more than 1e\\+06 \\(at least 1 m\\)") as info:
        load_installation(write(tmp_path, text))
    assert info.value.line is not None


def test_far_creatures_decide_less_often_within_a_budget_and_still_hear(tmp_path):
    """[room.lod] with decide: a creature 8 m from the listener (level 3) runs its behaviour one
    tick in eight; two near ones sharing a budget of one decider a tick take turns (neither
    starves); the far one still hears every note when it starts."""
    room = "lod = { near = 2.0, levels = 3, decide_budget = 2 }"
    s, clock = session(tmp_path, room, singer("a", 5.0, 5.0), singer("b", 5.5, 5.0), singer("c", 5.0, 5.5),
                       singer("far", 9.9, 9.9))
    ticks, when = {c.name: 0 for c in s.creatures}, {}
    chosen = s.stage.deciding

    def counted(tick: int, dt: float) -> np.ndarray:
        due = chosen(tick, dt)
        for i in due:
            ticks[s.creatures[i].name] += 1
            when[s.creatures[i].name] = clock.now()
        return due

    s.stage.deciding = counted  # the session ticks whom the stage chose (a crowd of them together)
    run(s, clock, 2.0)  # 100 ticks
    assert all(c.group.last_tick == when[c.name] for c in s.creatures)  # each decided when chosen, no later
    assert 10 <= ticks["far"] <= 13  # one tick in eight, or a tick later when the budget is full
    assert sum(ticks.values()) == 200 and min(ticks[n] for n in "abc") >= 55  # two a tick, shared
    s.world.play(s.creatures[0], NoteEvent(2.0, 60, 127, 0, 0.5))
    run(s, clock, 2.1)
    assert s.creatures[3].ear.last(1)  # heard on the tick it arrived, deciding or not


def test_with_level_of_detail_a_run_ticked_at_0_02_s_and_one_at_0_04_s_walk_the_same_paths(tmp_path):
    """Eight wandering singers, [room.lod] near 2 m, three levels, deciding by level: every
    0.04 s for 10 s, the two runs' creatures stand within 1e-9 m of each other (the levels are
    planned on the sub-step grid; planned each tick, they ended up to 9.2 m apart)."""
    rng = np.random.default_rng(5)
    wander = 'steer = [{ behaviour = "wander" }, { behaviour = "wall_avoidance", weight = 2.0 }]'
    singers = [singer(f"s{i}", *rng.uniform(1, 9, 2).round(2), vehicle=wander) for i in range(8)]

    def trace(tick: float) -> tuple[np.ndarray, float]:
        s, clock = session(tmp_path, "lod = { near = 2.0, levels = 3 }", *singers)
        where = []
        for k in range(250):
            run(s, clock, 0.04 * (k + 1), tick)
            where.append(s.stage.v.pos.copy())
        return np.array(where), s.stage.crowd.steered / (8 * s.stage.crowd.steps)

    (fine, steered), (coarse, _) = trace(0.02), trace(0.04)
    assert np.abs(fine - coarse).max() < 1e-9
    assert norms(fine[-1] - fine[0]).min() > 1.0  # every one wandered
    assert steered < 0.8  # far ones steered less often: the levels did act


def test_an_unheard_creature_decides_less_often_than_a_sounding_one_beside_it(tmp_path):
    """[room.lod] unheard = 2: two creatures 1 m from the listener (level 0 by distance), one
    calling phrases, one silent. The silent one is never heard, so it stays at level 2 and
    decides one tick in four; the caller is at level 0 while a note of it sounds (and 2 between
    phrases), so it decides more often; without unheard both decide every tick."""
    def decisions(room: str) -> tuple[dict[str, int], set[tuple[int, int]]]:
        s, clock = session(tmp_path, room, caller("loud", 5.0, 4.0, "max_speed = 0.01"),
                           singer("quiet", 5.0, 6.0, vehicle="max_speed = 0.01"))
        ticks = {c.name: 0 for c in s.creatures}
        chosen = s.stage.deciding
        if chosen is not None:
            def counted(tick: int, dt: float) -> np.ndarray:
                due = chosen(tick, dt)
                for i in range(len(s.creatures)) if due is None else due:
                    ticks[s.creatures[i].name] += 1
                return due

            s.stage.deciding = counted  # the session ticks whom the stage chose (a crowd together)
        levels = set()
        while clock.now() < 4.0 - 1e-9:  # 200 ticks
            run(s, clock, clock.now() + TICK)
            levels.add(tuple(int(x) for x in s.stage.crowd.level))
        return ticks, levels

    ticks, levels = decisions("lod = { near = 3.0, levels = 3, unheard = 2 }")
    assert 48 <= ticks["quiet"] <= 52
    assert ticks["loud"] >= ticks["quiet"] + 15
    assert levels == {(0, 2), (2, 2)}
    assert decisions("lod = { near = 3.0, levels = 3 }")[0] == {"loud": 200, "quiet": 200}


def test_a_creature_steers_to_a_note_object_and_strikes_it_once_per_stepping_on(tmp_path):
    """[[room.notes]]: a note object on the floor. `target = "note"` brings the seeker to the
    nearest one (the far one is never reached), it plays that note as its own on stepping
    on, once while it stands there, and the frames draw the objects on the floor."""
    room = ('[[room.notes]]\nat = [7.0, 5.0]\npitch = 67\n'
            '[[room.notes]]\nat = [1.0, 9.0]\npitch = 48\n')
    seeker = singer("s", 3.0, 5.0, vehicle='steer = [{ behaviour = "arrival", target = "note", slowing = 1.0 }]')
    s, clock = session(tmp_path, room, seeker)
    run(s, clock, 10.0)
    assert np.hypot(*(s.stage.v.pos[0] - [7.0, 5.0])) < 0.1  # come to rest on it
    struck = [e for e in s.log.records if e["kind"] == "struck"]
    assert [(e["note"], e["pitch"]) for e in struck] == [(0, 67)]  # once, though it stands there
    played = [e for e in s.log.records if e["kind"] == "note" and e["creature"] == "s"]
    assert [e["pitch"] for e in played if e["pitch"] in (67, 48)][:1] == [67]
    assert abs(next(e for e in played if e["pitch"] == 67)["t"] - struck[0]["t"]) < 1e-9
    from creatures.runtime.bodies import gather

    positions, parents, marks = gather(s.creatures)  # no body here: the seeker is drawn as a marker
    assert parents.tolist() == [-1, 0, 1] and np.allclose(positions[0], [7.0, 0.0, -5.0], atol=0.1)  # on the object
    assert marks == s.stage.note_marks() == [((7.0, 0.0, -5.0), 67), ((1.0, 0.0, -9.0), 48)]


@pytest.mark.parametrize("room, vehicle, message", [
    ('[[room.notes]]\nat = [12.0, 5.0]\npitch = 60', "", "note object \\[12.0, 5.0\\] is outside"),
    ("", 'steer = [{ behaviour = "seek", target = "note" }]', "the room has none"),
])
def test_a_note_object_off_the_floor_or_none_to_seek_is_a_config_error(tmp_path, room, vehicle, message):
    text = HEADER.format(room=room) + singer("a", 1.0, 1.0, vehicle=vehicle)
    with pytest.raises(ConfigError, match=message) as info:
        load_installation(write(tmp_path, text))
    assert info.value.line is not None


def test_a_creature_put_on_a_note_object_strikes_it_only_by_stepping_on(tmp_path):
    """Placed on a note object at the start (or put back there by its saved place), a creature
    strikes nothing; it strikes when it steps off and on again."""
    room = '[[room.notes]]\nat = [5.0, 5.0]\npitch = 67\nradius = 0.5'
    s, clock = session(tmp_path, room, singer("a", 5.0, 5.0, vehicle="max_speed = 0.001"))
    run(s, clock, 1.0)
    assert not [e for e in s.log.records if e["kind"] == "struck"]
    s.stage.put("a", {"at": [8.0, 8.0], "velocity": [0.0, 0.0], "heading": [1.0, 0.0]})
    run(s, clock, 1.5)
    s.stage.put("a", {"at": [5.0, 5.0], "velocity": [0.0, 0.0], "heading": [1.0, 0.0]})
    run(s, clock, 2.0)
    assert not [e for e in s.log.records if e["kind"] == "struck"]  # a place taken back is no step
    s.stage.v.pos[0] = [8.0, 8.0]
    run(s, clock, 2.5)
    s.stage.v.pos[0] = [5.1, 5.0]  # walked back onto it (moved by hand, as steering would)
    run(s, clock, 3.0)
    assert [e["pitch"] for e in s.log.records if e["kind"] == "struck"] == [67]
    s.stage.v.pos[0] = [5.0, 2.0]  # off it, then across it and beyond within one tick
    run(s, clock, 3.5)
    s.stage.v.pos[0] = [5.0, 8.0]
    run(s, clock, 3.52)
    assert [e["pitch"] for e in s.log.records if e["kind"] == "struck"] == [67, 67]  # struck in passing


def test_a_lone_caller_s_notes_are_not_kept_for_ears_that_are_not_there(tmp_path):
    """A room of one: its notes reach no other ear, so none is kept for an arrival that will
    never land (they were, one per note, for the whole run). With a second creature every
    note is kept only while in flight, and heard."""
    s, clock = session(tmp_path, "", caller("loud", 5.0, 5.0))
    run(s, clock, 10.0)
    played = sum(e["kind"] == "note" for e in s.log.records)
    assert played > 5 and not s.stage._sounds
    s, clock = session(tmp_path, "", caller("loud", 5.0, 5.0), singer("ear", 6.0, 5.0))
    run(s, clock, 10.0)
    assert s.stage.masked + sum(1 for _ in s.creatures[1].ear.last(1000)) > 5
    assert all(k in set(s.stage._flying["note"].tolist()) for k in s.stage._sounds)


PAINTED = """[[room.flows]]
name = "round"
shape = "painted"
rows = [">>>>v",
        "^...v",
        "^...v",
        "^...v",
        "^<<<<"]
[[room.flows]]
name = "mill"
shape = "vortex"
cell = 0.5
"""
"""A director's painted field (the room from above, the back wall first): round the walls
clockwise; and a vortex, anticlockwise round the centre."""


def test_flow_fields_from_the_config_steer_the_crowd(tmp_path):
    """A painted field carries a creature round the room's edge, side by side in the order its
    arrows say (west along the front, up the west side, east along the back, down the east),
    and a vortex carries another round the centre anticlockwise, both from [[room.flows]]."""
    follow = 'steer = [{ behaviour = "flow_following", field = "%s" }]'
    s, clock = session(tmp_path, PAINTED, singer("edge", 7.0, 1.0, vehicle=follow % "round"),
                       singer("mill", 8.0, 5.0, vehicle=follow % "mill"))
    sides, turned = [], 0.0
    while clock.now() < 40.0 - 1e-9:
        before = np.arctan2(*(s.stage.v.pos[1] - 5.0)[::-1])
        run(s, clock, clock.now() + 0.1)
        turned += (np.arctan2(*(s.stage.v.pos[1] - 5.0)[::-1]) - before + np.pi) % (2 * np.pi) - np.pi
        x, y = s.stage.v.pos[0]
        side = "front" if y < 2 else "west" if x < 2 else "back" if y > 8 else "east" if x > 8 else None
        if side is not None and (not sides or sides[-1] != side):
            sides.append(side)
    assert sides[:5] == ["front", "west", "back", "east", "front"]
    assert turned > 2 * np.pi  # the vortex's creature went all the way round the centre, anticlockwise


@pytest.mark.parametrize("flow, message", [
    ('[[room.flows]]\nname = "f"\nshape = "painted"\nrows = [">>", ">>>"]', "as long as the first"),
    ('[[room.flows]]\nname = "f"\nshape = "painted"\nrows = [">x"]', "rows"),
    ('[[room.flows]]\nname = "f"\nshape = "painted"', "needs rows"),
    ('[[room.flows]]\nname = "f"\nrows = [">"]', "shape = 'painted'"),
])
def test_a_badly_painted_field_is_a_config_error(tmp_path, flow, message):
    with pytest.raises(ConfigError, match=message) as info:
        load_installation(write(tmp_path, HEADER.format(room=flow) + singer("a", 1.0, 1.0)))
    assert info.value.line is not None


def test_a_crowd_following_a_tracked_visitor_ticked_at_0_02_and_0_04_s_agrees_within_its_travel(tmp_path):
    """What a tick samples moves a crowd too (the visitor's place, read once a tick): a singer
    arriving on a visitor who walks a 2 m circle at 0.5 m/s, tracked at 50 Hz, and another
    pursuing it, ticked at 0.02 s and at 0.04 s. The stated tolerance: the two runs' creatures
    stay within the visitor's travel in one 0.04 s tick (0.02 m) of each other, since the
    coarser run reads where the visitor was up to one tick late; steering alone agrees within
    1e-9 m (tests above). Measured: 4.9 mm (arrival) and 5.6 mm (pursuit, which also reads the
    visitor's velocity) at most over 20 s."""
    room = 'visitors = [{ x = "vx", y = "vy" }]'
    near = singer("near", 2.0, 2.0, vehicle='steer = [{ behaviour = "arrival", target = "visitor", slowing = 1.0 }]')
    chase = singer("chase", 8.0, 2.0, vehicle='steer = [{ behaviour = "pursuit", target = "visitor" }]')

    def trace(tick: float) -> np.ndarray:
        inst = load_installation(write(tmp_path, HEADER.format(room=room) + TRACKER + near + chase))
        clock = SimulatedClock()
        s = Session(inst, clock, EventLog(keep_in_memory=0), MemorySink())
        every, where = int(round(tick / 0.02)), []
        for k in range(int(20.0 / 0.02)):
            at = 0.02 * (k + 1)
            angle = 0.25 * at  # 0.5 m/s round a circle of 2 m
            s.inputs.osc("/v", [5.0 + 2.0 * np.cos(angle), 5.0 + 2.0 * np.sin(angle)], round(0.02 * k, 6))
            if (k + 1) % every == 0:
                s.step(clock.advance(tick), 0, None, audio=False)
                if (k + 1) % 2 == 0:
                    where.append(s.stage.v.pos.copy())
        return np.array(where)

    fine, coarse = trace(0.02), trace(0.04)
    apart = norms(fine - coarse).max()
    assert apart <= 0.5 * 0.04  # the visitor's travel in one coarse tick
    assert norms(fine[-1] - fine[0]).min() > 2.0  # both followed the walking visitor a long way
    assert apart > 1e-6  # the sampling does show: this is not the 1e-9 of steering alone


@pytest.mark.parametrize("vary, message", [
    # a slip in the last part: said at the vary key's own line, not the vehicle table's
    ('vary = { "vehicle.max_sped" = [0.5, 1.5] }', r"vary\.vehicle\.max_sped: unknown key \(did you mean 'max_speed'\?\)"),
    # a slip in a table written above: the nearest written name, not a new tuple that lacks its keys
    ('vary = { "tuples.ecco.action.count" = [2, 4] }', r"no 'ecco' under 'tuples' in the table \(did you mean 'echo'\?\)"),
    ('cycle = { chanel = [0, 1] }', r"cycle\.chanel: unknown key \(did you mean 'channel'\?\)"),
])
def test_a_slip_in_a_crowds_vary_or_cycle_is_said_at_its_line(tmp_path, vary, message):
    crowd = singer("bird", 5.0, 5.0).replace('name = "bird"', f'name = "bird"\ncount = 3\n{vary}')
    crowd = crowd.replace("at = [5.0, 5.0]", "")
    text = HEADER.format(room="") + crowd
    with pytest.raises(ConfigError, match=message) as info:
        load_installation(write(tmp_path, text))
    assert info.value.line == text.splitlines().index(vary) + 1


WANDERING = ('max_speed = 1.0\nmax_turn = 90.0\n'
             'steer = [{ behaviour = "wander", weight = 1.0 }, { behaviour = "wall_avoidance", weight = 3.0 }]')


def test_a_creature_without_a_body_is_drawn_as_a_marker_where_its_vehicle_stands(tmp_path):
    """A crowd of singers without bodies (the flock) was drawn nowhere: no frames, no poses,
    nothing in the live view or the body stream. In a room each is a post where its vehicle
    stands with an arm pointing its heading, in every picture alike."""
    from creatures.room.stage import MARKER_JOINTS
    from creatures.runtime.bodies import gather
    from creatures.runtime.body_stream import hello_of, snapshot
    from creatures.view.snapshot import bodies, frame, pose_event

    s, clock = session(tmp_path, "", singer("a", 2.0, 5.0, vehicle=WANDERING), singer("b", 7.0, 3.0, vehicle=WANDERING))
    start = s.stage.v.pos.copy()
    run(s, clock, 3.0)
    assert np.linalg.norm(s.stage.v.pos - start, axis=1).min() > 0.5  # both wandered off
    positions, parents, _ = gather(s.creatures)
    assert parents.tolist() == [-1, 0, 1, -1, 3, 4]
    for i, creature in enumerate(s.creatures):
        joints = positions[3 * i:3 * i + 3]
        (x, y), (hx, hy) = s.stage.v.pos[i], s.stage.v.heading[i]
        assert np.allclose(joints[0], [x, 0.0, -y]) and np.allclose(joints[1], [x, 0.6, -y])
        assert np.allclose(joints[2] - joints[1], [0.25 * hx, 0.0, -0.25 * hy])  # room (x, y) is (x, −z)
        # The live view's frame, the pose events and the body stream show the same joints.
        assert np.allclose(frame(3.0, s.creatures)["bodies"][creature.name], joints)
        assert np.allclose(pose_event(creature)["joints"], joints, atol=1e-5)
        assert np.allclose(snapshot(creature).positions, joints)
        assert hello_of(creature, i).joints == MARKER_JOINTS
    assert [b.parents for b in bodies(s.creatures)] == [[-1, 0, 1]] * 2
    # The crowd's markers are placed once a tick: they follow it on, and a place taken back.
    run(s, clock, 3.5)
    assert np.allclose(s.creatures[1].shown()[0][0], [s.stage.v.pos[1][0], 0.0, -s.stage.v.pos[1][1]])
    s.stage.put("a", {"at": [9.0, 1.0], "velocity": [0.0, 0.0], "heading": [0.0, 1.0]})
    assert np.allclose(s.creatures[0].shown()[0], [[9.0, 0.0, -1.0], [9.0, 0.6, -1.0], [9.0, 0.6, -1.25]])


def test_an_offline_room_without_bodies_logs_its_markers_for_the_replay(tmp_path):
    from creatures.view.snapshot import replay

    inst = load_installation(write(tmp_path, HEADER.format(room="") + singer("a", 2.0, 5.0, vehicle=WANDERING)))
    run_offline(inst, tmp_path / "out", duration=2.0)
    events = read_events(tmp_path / "out" / "events.jsonl")
    (skeleton,) = [e for e in events if e["kind"] == "skeleton"]
    assert skeleton["parents"] == [-1, 0, 1]
    rooms = {round(e["t"], 3): e["pos"][0] for e in events if e["kind"] == "room"}
    poses = [e for e in events if e["kind"] == "pose"]
    assert len(poses) >= 15  # [view] log_fps 10 over 2 s
    matched = [(p["joints"][0], rooms[round(p["t"], 3)]) for p in poses if round(p["t"], 3) in rooms]
    assert matched and all(np.allclose([x, -z], at, atol=1e-3) for (x, _, z), at in matched)
    shown = replay(events)
    assert shown.hello["creatures"][0]["parents"] == [-1, 0, 1]
    floors = np.array([f["bodies"]["a"][0] for f in shown.frames])
    assert np.ptp(floors[:, [0, 2]], axis=0).max() > 0.5  # it moves in the replay
