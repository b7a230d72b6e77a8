"""The open input map (``[[input]]``): every kind of mapping, config errors that name the key
and line, serial devices on a pseudo-terminal, and the clicker's late reward."""

from __future__ import annotations

import os
import pty
import select
import textwrap

import mido
import numpy as np
import pytest

from input_fixtures import COLONY

from creatures.behaviour.action_group import ActionGroup
from creatures.behaviour.action_tuple import Action, ActionTuple, DoUntil
from creatures.behaviour.percept import FunctionPercept
from creatures.cli import main
from creatures.clock import SimulatedClock
from creatures.config import ConfigError
from creatures.events import EventLog
from creatures.kinds import load_all
from creatures.runtime.input_map import Unreadable, as_pitch
from creatures.runtime.input_routes import address_pattern
from creatures.runtime.input_sources import RETRY, SerialSource, line_message, value_of
from creatures.runtime.schema import load_installation
from creatures.runtime.session import Session
from midi.sinks import MemorySink

MAPS = """
[[input]]
osc = "/note"
to = "note"
pitch = {arg = 0}
velocity = {arg = 1, default = 100}
duration = {arg = 2, default = 0.25}

[[input]]
osc = "/light/{left,right}/[0-9]*"
to = "sensor"
name = "light"

[[input]]
osc = "/lux"
to = "sensor"
name = "lux"

[[input]]
osc = "/any"
to = "sensor"
name = "count"
value = {arg = 3, default = -1}

[[input]]
midi = "cc"
control = 7
to = "sensor"
name = "fader"
range = [-1.0, 1.0]

[[input]]
midi = "note"
channel = 9
note = 36
to = "reward"
creatures = ["bo"]
amount = 2.0

[[input]]
osc = "/reward"
to = "reward"
creatures = {arg = 0}
amount = {arg = 1, default = 1.0}

[[input]]
osc = "/bored"
to = "drive"
drive = "boredom"
amount = {arg = 0}

[[input]]
osc = "/calm"
to = "drive"
drive = "boredom"
creatures = ["bo"]
set = 0.0
"""


def colony(tmp_path, maps: str = MAPS, extra: str = ""):
    path = tmp_path / "colony.toml"
    path.write_text(COLONY + extra + maps)
    inst = load_installation(path)
    clock = SimulatedClock()
    return Session(inst, clock, EventLog(), MemorySink()), clock


def events(session: Session, kind: str) -> list[dict]:
    return [e for e in session.log.records if e["kind"] == kind]


@pytest.mark.parametrize("pattern,address,matches", [
    ("/a/b", "/a/b", True),
    ("/a/*", "/a/anything", True),
    ("/a/*", "/a/b/c", False),  # no wildcard crosses a '/'
    ("/a/?x", "/a/yx", True),
    ("/a/?x", "/a/x", False),
    ("/ch/[0-9]", "/ch/7", True),
    ("/ch/[!0-9]", "/ch/7", False),
    ("/ch/[!0-9]", "/ch/a", True),
    ("/ch/[abc]d", "/ch/bd", True),
    ("/{foo,bar}/x", "/bar/x", True),
    ("/{foo,bar}/x", "/baz/x", False),
    ("/a.b", "/aXb", False),  # '.' is a plain character
    ("/a-b", "/a-b", True),
])
def test_osc_1_0_address_patterns(pattern, address, matches):
    assert (address_pattern(pattern).fullmatch(address) is not None) is matches


@pytest.mark.parametrize("pattern", ["no/slash", "/a/[bc", "/a/{x,y", "/a b", "/a/]", "/a/[]", "/{a,*}"])
def test_bad_patterns_are_refused(pattern):
    with pytest.raises(ValueError):
        address_pattern(pattern)


def test_osc_int_float_string_and_two_argument_notes_are_heard_by_those_that_hear_input(tmp_path):
    session, clock = colony(tmp_path)
    router = session.inputs
    clock.advance_to(1.0)
    assert router.osc("/note", [60, 90, 0.5], 1.0) == 1  # ints, and a float duration
    assert router.osc("/note", [62.0, 80.0], 1.0) == 1  # floats, two arguments: the duration's default
    assert router.osc("/note", ["C#4"], 1.0) == 1  # a string: a note name; velocity's default
    assert router.osc("/note", ["64", True], 1.0) == 1  # a numeric string, a bool (velocity 1)
    assert not events(session, "heard")  # logged as the creatures hear them, when they start
    session.world.deliver(1.0)
    heard = [(e["pitch"], e["velocity"], e["duration"], e["source"]) for e in events(session, "heard")]
    assert heard == [(60, 90, 0.5, "osc"), (62, 80, 0.25, "osc"), (61, 100, 0.25, "osc"), (64, 1, 0.25, "osc")]
    placed = {(e["creature"], e["source"]) for e in session.log.records if e["kind"] == "placed"}
    assert placed == {("bo", "input")}  # `deaf` (hears_input = false) hears none of them
    assert router.counts["mapped"] == 4 and router.counts["malformed"] == 0


def test_unreadable_and_unmapped_messages_are_counted_and_logged_once_per_cause(tmp_path):
    session, clock = colony(tmp_path)
    router = session.inputs
    said: list[str] = []
    router.say = said.append
    for t in (1.0, 2.0, 3.0):
        router.osc("/note", [], t)  # no pitch
        router.osc("/note", ["sixty"], t)  # not a pitch
        router.osc("/note", [60, 0], t)  # velocity 0 is no note
        router.osc("/synth/freq", [440.0], t)
    assert router.counts["malformed"] == 9 and router.counts["unmapped"] == 3
    assert router.counts["malformed osc"] == 9 and router.counts["mapped"] == 0
    logged = [(e["kind"], e["address"], e["count"]) for e in session.log.records if e["kind"] in ("unmapped", "malformed")]
    assert logged == [("malformed", "/note", 1), ("unmapped", "/synth/freq", 1)]  # rate limited per cause
    assert len(said) == 2 and "/synth/freq" in said[1]
    router.osc("/synth/freq", [1.0], 70.0)  # a minute later: logged again, with the count since
    assert [e["count"] for e in events(session, "unmapped")] == [1, 3]
    session.close()
    assert events(session, "inputs")[-1]["unmapped"] == 4


def test_two_thousand_distinct_unmapped_addresses_are_one_cause_logged_at_most_every_ten_seconds(tmp_path):
    """One line per distinct address (up to 1,024) made 1,023 lines in under a second for
    2,000 ``/probe/<i>``: unmapped is one cause, whatever the address."""
    session, clock = colony(tmp_path)
    router = session.inputs
    said: list[str] = []
    router.say = said.append
    for i in range(2000):
        router.osc(f"/probe/{i}", [i], 1.0 + i / 2000)
    assert len(said) == 1 and "/probe/0" in said[0] and router.counts["unmapped osc"] == 2000
    router.osc("/probe/again", [], 11.5)  # 10 s on: one line with the count since and a few addresses
    assert len(said) == 2 and "2000 messages" in said[1] and "'/probe/1', '/probe/2', '/probe/3'" in said[1]
    assert [(e["count"], e["examples"]) for e in events(session, "unmapped")] == [
        (1, ["/probe/0"]), (2000, ["/probe/1", "/probe/2", "/probe/3"])]
    session.close()
    assert events(session, "inputs")[-1]["unmapped"] == 2001


def test_what_was_counted_since_the_last_line_is_said_when_the_run_ends(tmp_path):
    """Messages of a cause after its line and within 10 s of it were counted and then never
    said: a run that ended before the next such message lost their addresses and why (a live
    run sent 9 malformed OSC messages and logged the first alone)."""
    session, clock = colony(tmp_path)
    router = session.inputs
    said: list[str] = []
    router.say = said.append
    router.osc("/note", ["sixty"], 1.0)  # said at once
    router.osc("/note", [200], 2.0)  # pitch out of range: counted, held for the next line
    router.osc("/lux", ["bright"], 2.5)  # not a reading
    router.osc("/note", [], 3.0)  # no pitch
    router.osc("/synth/freq", [440.0], 3.5)  # unmapped, said at once: nothing held
    session.close()
    assert [(e["count"], e["address"], e["why"], e["examples"]) for e in events(session, "malformed")] == [
        (1, "/note", "pitch: 'sixty' is not a number", ["/note"]),
        (3, "/note", "no argument 0 (the message has 0)", ["/note", "/lux"])]  # the latest's address and why
    assert [e["count"] for e in events(session, "unmapped")] == [1]
    assert len(said) == 3 and "3 messages" in said[2] and "no argument 0" in said[2]
    assert events(session, "inputs")[-1]["malformed"] == 4


def test_wildcard_any_arity_and_bool_readings_reach_named_sensors(tmp_path):
    session, clock = colony(tmp_path)
    router = session.inputs
    router.osc("/light/left/3", [0.25], 1.0)
    router.osc("/light/right/12", [True], 1.5)
    router.osc("/light/up/3", [0.9], 1.6)  # not {left,right}
    for n, t in ((0, 2.0), (4, 2.5), (7, 3.0)):  # any arity: argument 3 or its default
        router.osc("/any", list(range(10, 10 + n)), t)
    light = session.world.sensor("light")
    assert light.data == [0.25, 1.0] and light.times == [1.0, 1.5]
    assert session.world.sensor("count").data == [-1.0, 13.0, 13.0]
    assert light.saliency_at(1.2) == pytest.approx(0.25)  # a StateObject: saliency and history
    assert router.counts["unmapped"] == 1
    with pytest.raises(KeyError, match="sensors: \\['count', 'fader', 'light', 'lux'\\]"):
        session.world.sensor("dark")


def test_midi_cc_is_scaled_into_a_sensor_and_other_controllers_are_unmapped(tmp_path):
    session, clock = colony(tmp_path)
    router = session.inputs
    for value, t in ((0, 1.0), (127, 1.1), (64, 1.2)):
        router.midi(mido.Message("control_change", control=7, value=value, channel=3), t)
    router.midi(mido.Message("control_change", control=8, value=1), 1.3)
    router.midi(mido.Message("program_change", program=5), 1.4)
    assert session.world.sensor("fader").data == pytest.approx([-1.0, 1.0, 64 / 127 * 2 - 1])
    assert router.counts["unmapped midi"] == 2


PRESSURE_MAPS = """
[[input]]
midi = "program"
channel = 2
to = "sensor"
name = "scene"
range = [0.0, 127.0]

[[input]]
midi = "aftertouch"
to = "sensor"
name = "press"
range = [0.0, 1.0]

[[input]]
midi = "polytouch"
note = 60
to = "sensor"
name = "key60"
value = {arg = 0}
"""


def test_program_change_aftertouch_and_polytouch_reach_sensors_and_filters_hold(tmp_path):
    """Every MIDI message kind the map names reaches its sensor, by its own argument order
    (program: program, channel; aftertouch: pressure, channel; polytouch: pressure, note,
    channel), and the channel and note filters send the rest to the unmapped count."""
    session, clock = colony(tmp_path, PRESSURE_MAPS)
    router = session.inputs
    router.midi(mido.Message("program_change", program=7, channel=2), 1.0)
    router.midi(mido.Message("program_change", program=9, channel=3), 1.1)  # another channel
    router.midi(mido.Message("aftertouch", value=127, channel=5), 1.2)
    router.midi(mido.Message("aftertouch", value=0, channel=0), 1.3)
    router.midi(mido.Message("polytouch", note=60, value=90), 1.4)
    router.midi(mido.Message("polytouch", note=61, value=90), 1.5)  # another key
    assert session.world.sensor("scene").data == pytest.approx([7.0])
    assert session.world.sensor("press").data == pytest.approx([1.0, 0.0])  # 0-127 onto [0, 1]
    assert session.world.sensor("key60").data == pytest.approx([90.0])  # no range: the raw reading
    assert router.counts["mapped midi"] == 4 and router.counts["unmapped midi"] == 2


def test_the_configured_window_decides_which_tuples_a_late_click_reaches(tmp_path):
    """``window`` in the config reaches the reward: the same late click credits the tuple that
    just ended with a wide window and only the active one with a narrow one."""
    credited = {}
    for window in (0.05, 3.0):
        table = f'[[input]]\nosc = "/click"\nto = "reward"\ncreatures = ["bo"]\nwindow = {window}\n'
        session, clock = colony(tmp_path, table)
        bo = session.world.creatures[0]
        names: list[str] = []
        step = 0
        while len(set(names)) < 2 and step < 3000:  # until bo has begun a second tuple
            step += 1
            clock.advance_to(step * 0.02)
            session.step(step * 0.02, 441, None, audio=False)
            names += [t.name for t in bo.group.active]
        t = clock.now()
        session.inputs.osc("/click", [], t)
        (event,) = events(session, "reward")
        credited[window] = event["credited"]
    assert len(credited[3.0]) > len(credited[0.05]) >= 1, credited


def test_midi_note_rewards_the_tuple_that_was_active_and_a_string_names_the_creature(tmp_path):
    session, clock = colony(tmp_path)
    bo = session.world.creatures[0]
    for step in range(1, 51):  # one simulated second: bo selects something
        clock.advance_to(step * 0.02)
        session.step(step * 0.02, 441, None, audio=False)
    running = {tp.name: tp for group in bo.reward_groups() for tp in group.active}  # its layers' groups too
    before = {name: tp.value.to_float() for name, tp in running.items()}
    t = clock.now()
    router = session.inputs
    router.midi(mido.Message("note_on", note=36, velocity=100, channel=9), t)
    router.midi(mido.Message("note_on", note=36, velocity=100, channel=0), t)  # another channel: a heard note
    reward = events(session, "reward")
    assert len(reward) == 1 and (reward[0]["creature"], reward[0]["amount"]) == ("bo", 2.0)
    active = running[reward[0]["tuple"]]  # a tuple that was running when the click came
    before = before[active.name]
    assert active.value.to_float() == pytest.approx(before + 0.2 * 1.0 * 2.0)  # V + rate·Tr·amount (Tr: whatever)
    router.osc("/reward", ["deaf", 0.5], t)
    router.osc("/reward", ["nobody"], t)  # names no creature: malformed, not a crash
    assert [e["creature"] for e in events(session, "reward")] == ["bo", "deaf"]
    assert router.counts["malformed osc"] == 1
    session.world.deliver(t)
    assert [e["pitch"] for e in events(session, "heard")] == [36]


def test_a_flood_of_clicks_is_throttled_and_counted_not_a_retraining(tmp_path):
    """10,000 ``/reward`` messages in 10 s (a bouncing switch, a stuck sender) once took an
    audited colony's values from about 2 to 370. A reward map takes 10 a second unless its
    ``limit`` says otherwise (a burst of 10, then 10 a second); the rest are counted as
    throttled and logged as one cause."""
    session, clock = colony(tmp_path, MAPS + '[[input]]\nosc = "/lux/fast"\nto = "sensor"\nname = "fast"\nlimit = 2\n')
    bo = session.world.creatures[0]
    for step in range(1, 51):  # bo selects something to credit
        clock.advance_to(step * 0.02)
        session.step(step * 0.02, 441, None, audio=False)
    running = {tp.name: tp for group in bo.reward_groups() for tp in group.active}
    before = {name: tp.value.to_float() for name, tp in running.items()}
    said: list[str] = []
    session.inputs.say = said.append
    t0 = clock.now()
    for k in range(1000):  # 1,000 a second for a second
        session.inputs.osc("/reward", ["bo", 1.0], t0 + k / 1000)
        session.inputs.osc("/lux/fast", [0.5], t0 + k / 1000)  # a sensor held to 2 a second
        session.inputs.osc("/lux", [0.5], t0 + k / 1000)  # no limit: every reading taken
    counts = session.inputs.counts
    taken = len(events(session, "reward"))
    assert taken == 10 + 10 - 1  # the burst, then one every 0.1 s of the second (the last one at 1.0 s is not in it)
    assert len(session.world.sensors["fast"]) == 2 + 2 - 1 and len(session.world.sensors["lux"]) == 1000
    assert counts["throttled osc"] == (1000 - taken) + (1000 - 3)
    assert counts["mapped osc"] == taken + 3 + 1000
    gained = max(running[name].value.to_float() - before[name] for name in before)
    assert 0 < gained <= taken * 0.2 * 1.0 + 1e-9  # at most rate·amount a click taken: not 1,000 clicks' worth
    throttled = [line for line in said if "throttled" in line]
    assert throttled == ["osc input '/lux/fast' throttled (over its map's limit of 2 a second); counted, logged at "
                         "most every 10 s"]  # one cause: the first throttled message's line, then a count


def test_each_session_has_its_own_allowance_of_clicks(tmp_path):
    """The routes are the installation's, shared by every session built from it (a rehearsal,
    the check's passes, the run): a session's clicks at 300 s must not empty the allowance of
    the next, whose clock starts at 0."""
    first, _ = colony(tmp_path)
    for k in range(20):
        first.inputs.osc("/reward", ["bo", 1.0], 300.0)
    assert first.inputs.counts["throttled osc"] == 10
    second = Session(first.inst, SimulatedClock(), EventLog(), MemorySink())
    second.inputs.osc("/reward", ["bo", 1.0], 0.0)
    assert second.inputs.counts["mapped osc"] == 1 and second.inputs.counts["throttled osc"] == 0


def test_drive_perturbation_adds_or_sets_a_drive(tmp_path):
    session, clock = colony(tmp_path)
    bo, deaf = session.world.creatures
    clock.advance_to(1.0)
    levels = [c.motivation.level("boredom", 1.0) for c in (bo, deaf)]
    session.inputs.osc("/bored", [0.5], 1.0)  # every creature with a boredom drive
    assert [c.motivation.level("boredom") for c in (bo, deaf)] == pytest.approx([x + 0.5 for x in levels])
    session.inputs.osc("/calm", [], 1.0)
    assert bo.motivation.level("boredom") == 0.0 and deaf.motivation.level("boredom") > 0.5
    assert [(e["creature"], e["drive"]) for e in events(session, "drive")] == [("bo", "boredom"), ("deaf", "boredom"),
                                                                                 ("bo", "boredom")]


BOUND_MAPS = MAPS + """
[[input]]
osc = "/wide"
to = "sensor"
name = "wide"
range = [-1e6, 1e6]
input_range = [0.0, 1e-300]
"""


def test_numbers_beyond_their_bounds_are_malformed_and_never_reach_a_value(tmp_path):
    """``/reward bo 1e308`` once crashed a live run. Every number read from a message meets
    its bound (readings and drives ±1e6, rewards ±1e3, a reading after its range scaling
    finite, a note's duration an hour): beyond, the message is counted malformed, no value moves, and the colony
    still ticks and saves."""
    session, clock = colony(tmp_path, BOUND_MAPS)
    bo = session.world.creatures[0]
    for step in range(1, 51):  # bo has an active tuple for a reward to reach
        clock.advance_to(step * 0.02)
        session.step(step * 0.02, 441, None, audio=False)
    values = [tuple_.value.to_float() for tuple_ in bo.group.tuples]
    boredom = bo.motivation.level("boredom")
    router, t = session.inputs, clock.now()
    for address, args in (("/reward", ["bo", 1e308]), ("/reward", ["bo", "-1e308"]), ("/reward", ["bo", 2e3]),
                          ("/reward", ["bo", 10**400]), ("/lux", [1e308]), ("/lux", [-2e6]), ("/bored", [1e308]),
                          ("/calm", []), ("/wide", [1.0]), ("/note", [60, 100, 1e5])):
        router.osc(address, args, t)
    assert router.counts["malformed osc"] == 9 and router.counts["mapped osc"] == 1  # /calm: a constant level
    assert not events(session, "reward") and not events(session, "heard") and len(session.world.sensor("lux")) == 0
    assert len(session.world.sensor("wide")) == 0
    assert [tuple_.value.to_float() for tuple_ in bo.group.tuples] == values
    assert bo.motivation.level("boredom") == 0.0 != boredom  # only /calm's constant reached it
    router.osc("/reward", ["bo", 1e3], t)  # at the bound: taken
    router.osc("/lux", [1e6], t)
    assert len(events(session, "reward")) == 1 and session.world.sensor("lux").data == [1e6]
    for step in range(51, 101):
        clock.advance_to(step * 0.02)
        session.step(step * 0.02, 441, None, audio=False)
    session.save_state(tmp_path / "state")
    assert (tmp_path / "state" / "bo.json").is_file()


# -- the clicker's window -------------------------------------------------------------------------
def test_a_late_click_credits_the_tuple_that_just_ended_and_not_one_long_gone():
    rng = np.random.default_rng(3)
    show = {"sit": 1.0, "roll": 0.0}
    tuples = [ActionTuple(name, FunctionPercept(name, lambda t, n=name: show[n]), Action(name), DoUntil(1.0), 5.0)
              for name in show]
    group = ActionGroup("dog", tuples, rng=rng, alpha=0.5, grounded_by="the clicks this test gives")
    group.tick(0.0)
    assert group.active[0].name == "sit"
    show.update(sit=0.0, roll=1.0)
    group.tick(1.0)  # sit is done; roll starts
    assert group.active[0].name == "roll"
    before = {name: group.find(name).value.to_float() for name in show}
    credited, moved = group.reward(2.0, 1.4, window=0.6)  # the visitor meant the sit, 0.4 s late
    assert credited == ["sit", "roll"]
    for name in show:  # each was triggered (Tr = 1) when it began: V += α·Tr·amount
        assert group.find(name).value.to_float() == pytest.approx(before[name] + 0.5 * 1.0 * 2.0)
    credited, moved = group.reward(2.0, 1.9, window=0.6)  # sit ended 0.9 s before: outside the window
    assert credited == ["roll"] and "sit" not in moved


def test_a_note_map_takes_a_note_name_for_its_constant_pitch(tmp_path):
    """``pitch = "F#3"``, as docs/config.md offers ("MIDI pitch, or a note name such as 'C4'"),
    was refused as "not a valid number"; it is the note's number."""
    session, clock = colony(tmp_path, '[[input]]\nosc = "/bell"\nto = "note"\npitch = "F#3"\nvelocity = 90\n')
    clock.advance_to(1.0)
    assert session.inputs.osc("/bell", [], 1.0) == 1
    session.world.deliver(1.0)
    assert [(e["pitch"], e["velocity"]) for e in events(session, "heard")] == [(54, 90)]


# -- config errors -----------------------------------------------------------------------------
@pytest.mark.parametrize("table,key,message", [
    ('osc = "/a/[bc"\nto = "note"', "input.0.osc", "bad OSC address pattern"),
    ('osc = "/a"\nargs = 2\nto = "note"\npitch = {arg = 2}', "input.0.pitch", "beyond the 2 argument(s)"),
    ('midi = "program"\nto = "sensor"\nname = "p"\nvalue = {arg = 2}', "input.0.value", "beyond the 2 argument(s)"),
    ('osc = "/a"\nto = "nite"', "input.0.to", "did you mean 'note'"),
    ('osc = "/a"\nto = "reward"\ncreatures = ["boo"]', "input.0.creatures", "did you mean 'bo'"),
    ('osc = "/a"\nto = "drive"\ndrive = "bordom"\namount = 1', "input.0.drive", "did you mean 'boredom'"),
    ('osc = "/a"\nto = "drive"\ndrive = "boredom"', "input.0.amount", "amount (added) or set"),
    ('midi = "ccc"\nto = "note"', "input.0.midi", "did you mean 'cc'"),
    ('osc = "/a"\nmidi = "cc"\nto = "note"', "input.0.midi", "hears one of"),
    ('osc = "/a"\nto = "note"\nname = "x"', "input.0.name", "not a key of to = 'note'"),
    ('osc = "/a"\ncontrol = 7\nto = "note"', "input.0.control", "only for midi = 'cc'"),
    ('serial = "/dev/ttyUSB0"\nto = "note"', "input.0.to", "a serial table is a source"),
    ('file = "r.csv"\nchannel = 2', "input.0.channel", "a file table is a source"),
    # a URL was opened on the creatures' thread (rfc2217:// waited 3 s a retry); '' looked for all night
    ('serial = "rfc2217://192.168.1.50:2217"', "input.0.serial", "is a URL"),
    ('serial = ""', "input.0.serial", "names no device"),
    ('osc = "/a"\nto = "note"\nbaud = 9600', "input.0.baud", "only with serial"),
    ('file = "missing.csv"', "input.0.file", "cannot read rehearsal file"),
    ('osc = "/a"\nto = "note"\npitchh = 3', "input.0.pitchh", "did you mean 'pitch'"),
    # a constant no note can have made every note the map heard malformed, and the config loaded
    ('osc = "/a"\nto = "note"\npitch = 200', "input.0.pitch", "a pitch is a MIDI number 0-127"),
    ('osc = "/a"\nto = "note"\nvelocity = 0', "input.0.velocity", "a velocity is a MIDI number 1-127"),
    # a key of {arg = N} mistyped was a bare 'unknown key': a number or a table, the table meant
    ('osc = "/a"\nto = "note"\n[input.pitch]\nar = 0', "input.0.pitch.ar", "unknown key (did you mean 'arg'?)"),
    # a sensor with no name loaded and was fed as world.sensors[None], which nothing can read
    ('osc = "/lux"\nto = "sensor"', "input.0.name", "to = 'sensor' needs name = NAME"),
    # an input_range without range was ignored (a 0..1023 reading went in unscaled); an empty one
    # made every reading malformed
    ('osc = "/lux"\nto = "sensor"\nname = "lux"\ninput_range = [0, 1023]', "input.0.input_range",
     "add range, or remove input_range"),
    ('osc = "/lux"\nto = "sensor"\nname = "lux"\nrange = [0, 1]\ninput_range = [5, 5]', "input.0.input_range",
     "input_range [5.0, 5.0] is empty"),
    # a text default for a number loaded, and every message short of the argument was malformed
    ('osc = "/lux"\nto = "sensor"\nname = "lux"\nvalue = { arg = 1, default = "low" }', "input.0.value",
     "default 'low' is text: value is a number"),
    ('osc = "/a"\nto = "note"\npitch = { arg = 1, default = "middle C" }', "input.0.pitch",
     "default 'middle C' is no pitch"),
])
def test_a_bad_input_map_names_key_and_line(tmp_path, table, key, message):
    path = tmp_path / "bad.toml"
    path.write_text(COLONY + "\n[[input]]\n" + table + "\n")
    rows = [i for i, row in enumerate(table.split("\n")) if row.startswith(key.split(".")[-1])]
    line = COLONY.count("\n") + 3 + rows[0] if rows else COLONY.count("\n") + 2  # else the table's own line
    with pytest.raises(ConfigError) as err:
        load_installation(path)
    assert err.value.key == key and message in err.value.message, str(err.value)
    assert err.value.line == line, str(err.value)


def test_a_serial_device_read_by_two_tables_is_refused_at_the_second(tmp_path):
    """Two readers of one device each took part of its lines: half the readings went missing."""
    path = tmp_path / "twice.toml"
    path.write_text(COLONY + '\n[[input]]\nserial = "/dev/ttyUSB0"\n\n[[input]]\nbaud = 115200\n'
                    'serial = "/dev/../dev/ttyUSB0"\n')
    with pytest.raises(ConfigError) as err:
        load_installation(path)
    assert err.value.key == "input.1.serial" and err.value.line == COLONY.count("\n") + 7
    assert "read by [[input]] table 0 (from 0) already" in err.value.message


def test_a_bad_map_is_exit_2_before_anything_runs(tmp_path, capsys):
    path = tmp_path / "bad.toml"
    path.write_text(COLONY + '\n[input]\ngenerate = "none"\n[[input.map]]\nosc = "/x"\nto = "drive"\n'
                    'drive = "hungr"\namount = 1\n')
    assert main(["offline", str(path), "--out", str(tmp_path / "out"), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "input.map.0.drive" in err and f"{path}:{COLONY.count(chr(10)) + 7}" in err and "'hunger'" in err
    assert not (tmp_path / "out" / "events.jsonl").exists()


def test_every_kind_declares_the_drives_and_action_group_it_builds(tmp_path):
    """What the config checks a map against (``drive_names``/``rewardable``) is what the creature has."""
    import installations

    seen = set()
    for path in map(installations.path, installations.names()):
        inst = load_installation(path)
        if not {s.kind for s in inst.specs} - seen:
            continue
        session = Session(inst, SimulatedClock(), EventLog(), MemorySink())
        for creature in session.creatures:
            seen.add(creature.spec.kind)
            motivation = getattr(creature, "motivation", None)
            assert set(creature.drive_names(creature.spec)) == set(getattr(motivation, "names", ())), creature.spec.kind
            assert creature.rewardable(creature.spec) == bool(creature.reward_groups())
    assert seen == set(load_all())


# -- serial devices --------------------------------------------------------------------------------
def arrived(fd: int) -> None:
    """Wait until the terminal has input to read (the kernel moves it across the pty)."""
    assert select.select([fd], [], [], 10.0)[0], "nothing arrived on the pseudo-terminal"


def test_serial_lines_from_a_pseudo_terminal_are_heard_as_osc(tmp_path):
    session, clock = colony(tmp_path)
    master, slave = pty.openpty()
    said: list[str] = []
    try:
        source = SerialSource(os.ttyname(slave), 115200, clock, session.inputs, said.append)
        assert source.poll(0.0) == 0 and source.port is not None  # opened (raw mode), nothing yet
        os.write(master, b"lux 0.5\r\nany,1,2,3,4\nfader")  # the last line is not finished yet
        clock.advance_to(1.0)
        arrived(slave)
        assert source.poll(1.0) == 0
        os.write(master, b" 1\n\xff\xfe\n/note 60 90\n")
        clock.advance_to(2.0)
        arrived(slave)
        assert source.poll(2.0) == 1
        source.close()
    finally:
        os.close(master)
        os.close(slave)
    assert session.world.sensor("lux").data == [0.5]
    assert session.world.sensor("count").data == [4.0]
    session.world.deliver(2.0)
    assert [e["pitch"] for e in events(session, "heard")] == [60]
    counts = session.inputs.counts
    assert counts["unmapped serial"] == 1  # /fader 1 (the fader is a MIDI map)
    assert counts["malformed serial"] == 1  # bytes that are not UTF-8
    assert said == []  # the device was there: nothing to report


def test_a_missing_serial_device_is_reported_once_and_retried(tmp_path):
    session, clock = colony(tmp_path)
    said: list[str] = []
    opened: list[str] = []
    master, slave = pty.openpty()
    device = str(tmp_path / "ttyUSB0")

    def opener(path, **kwargs):
        import serial

        opened.append(path)
        if not os.path.exists(path):
            raise serial.SerialException(f"could not open port {path}")
        return serial.serial_for_url(os.ttyname(slave), **kwargs)

    try:
        source = SerialSource(device, 9600, clock, session.inputs, said.append, opener=opener)
        for t in (0.0, 0.5, 1.0, 1.5):
            clock.advance_to(t)
            source.poll(t)
        assert len(opened) == 1 and len(said) == 1 and "unavailable" in said[0]  # retried only after RETRY
        clock.advance_to(RETRY + 0.1)
        source.poll(clock.now())
        assert len(opened) == 2 and len(said) == 1  # still absent, still reported only once
        open(device, "w").close()  # plugged in
        clock.advance_to(2 * RETRY + 0.2)
        source.poll(clock.now())
        os.write(master, b"lux 0.75\n")
        arrived(slave)
        source.poll(clock.now())
        assert "connected" in said[-1] and session.world.sensor("lux").data == [0.75]
        source.close()
    finally:
        os.close(master)
        os.close(slave)


def test_an_over_long_serial_line_is_dropped_to_its_newline_and_counted_once(tmp_path):
    """A device printing a long line (a boot banner, a debug dump, the wrong baud rate) is one
    malformed line: its tail after the first MAX_LINE bytes is no line of its own."""
    session, clock = colony(tmp_path)
    master, slave = pty.openpty()
    try:
        source = SerialSource(os.ttyname(slave), 115200, clock, session.inputs, [].append)
        source.poll(0.0)
        for step, chunk in enumerate((b"calibrating " + b"." * 3000, b"." * 3000, b"." * 3000 + b" lux 0.9\n",
                                      b"lux 0.5\n"), 1):
            os.write(master, chunk)
            arrived(slave)
            clock.advance_to(0.02 * step)
            source.poll(clock.now())
        source.close()
    finally:
        os.close(master)
        os.close(slave)
    assert session.world.sensor("lux").data == [0.5]  # not 0.9, the tail of the long line
    assert session.inputs.counts["malformed serial"] == 1 and session.inputs.counts["mapped serial"] == 1


def test_a_line_cut_off_by_an_unplug_is_not_joined_to_the_first_after_it(tmp_path):
    session, clock = colony(tmp_path)
    said: list[str] = []
    terminals = [pty.openpty(), pty.openpty()]  # the device before the unplug, and after

    def opener(path, **kwargs):
        import serial

        return serial.serial_for_url(os.ttyname(terminals[len(said) and 1][1]), **kwargs)

    try:
        source = SerialSource("/dev/ttyACM0", 9600, clock, session.inputs, said.append, opener=opener)
        source.poll(0.0)
        os.write(terminals[0][0], b"lux 0.9")  # the cable is pulled before the line ends
        arrived(terminals[0][1])
        source.poll(0.0)
        os.close(terminals[0][0])
        source.poll(0.0)
        assert "lost" in said[0] and source.port is None
        clock.advance_to(RETRY)
        source.poll(RETRY)
        os.write(terminals[1][0], b"\r\nlux 0.2\n")  # the device boots: a newline, then its readings
        arrived(terminals[1][1])
        source.poll(RETRY)
        source.close()
    finally:
        os.close(terminals[0][1])
        os.close(terminals[1][0])
        os.close(terminals[1][1])
    assert "connected" in said[-1] and session.world.sensor("lux").data == [0.2]


@pytest.mark.parametrize("line,message", [
    ("light 0.5", ("/light", [0.5])),
    ("/a/b,1,x, true", ("/a/b", [1, "x", True])),
    ("   ", None),
])
def test_serial_line_forms(line, message):
    assert line_message(line) == message


def test_values_and_note_names():
    assert [value_of(x) for x in ("3", "2.5", "TRUE", "C4")] == [3, 2.5, True, "C4"]
    assert [as_pitch(x) for x in ("C4", "c-1", "Bb3", "F#5", 69.4)] == [60, 0, 58, 78, 69]
    for truth in (True, False):  # OSC's T and F: a sensor reads them as 1 and 0, no note is meant by them
        with pytest.raises(Unreadable, match="a truth value is not a pitch"):
            as_pitch(truth)


def test_maps_inside_an_input_table_and_extends(tmp_path):
    base = tmp_path / "base.toml"
    base.write_text(COLONY)
    path = tmp_path / "child.toml"
    path.write_text('extends = "base.toml"\n' + textwrap.dedent("""
        [input]
        generate = "none"
        [[input.map]]
        osc = "/n"
        to = "note"
        """))
    inst = load_installation(path)
    assert inst.settings.input.generate == "none" and [r.spec.osc for r in inst.routes] == ["/n"]


def test_transcribed_audio_notes_reach_only_those_that_hear_input(tmp_path):
    from midi.notes import NoteEvent

    session, clock = colony(tmp_path)
    session.world.inject(NoteEvent(0.5, 60, 90, 0, 0.3), via="audio")
    session.world.deliver(1.0)
    assert {e["creature"] for e in events(session, "placed")} == {"bo"}


@pytest.mark.parametrize("args,ok", [
    ([60.0, 100.0, 0.5], True), ([60.0, 100.0, 0.5, 2.0], True), ([60, 100, 1], True),
    ([60.5, 100, 0.5], False), ([60, True, 0.5], False), ([60, 100, 0.5, float("nan")], False),
])
def test_the_shipped_address_space_takes_whole_floats_where_it_takes_ints(args, ok):
    from midi.osc import decode

    if ok:
        note = decode("/creature/A/note", args, 0.0, ("127.0.0.1", 1)).note
        assert (note.pitch, note.velocity, note.channel) == (60, 100, int(args[3]) if len(args) == 4 else 0)
    else:
        with pytest.raises(ValueError):
            decode("/creature/A/note", args, 0.0, ("127.0.0.1", 1))
    assert decode("/creature/A/hello", [9000.0], 0.0, ("127.0.0.1", 1)).args == (9000,)


def test_rehearsal_files_in_json_lines_and_their_errors(tmp_path):
    from creatures.runtime.input_sources import RehearsalError, load_rehearsal

    good = tmp_path / "r.jsonl"
    good.write_text('{"time": 2.0, "address": "/b", "args": ["x", 1.5]}\n{"time": 1.0, "address": "midi", '
                    '"args": [144, 60, 90]}\n')
    assert [(r.time, r.address, r.args) for r in load_rehearsal(good)] == [(1.0, "midi", (144, 60, 90)),
                                                                           (2.0, "/b", ("x", 1.5))]
    bad = tmp_path / "r.csv"
    bad.write_text("time,address,args\n1.0,/a,1\nsoon,/b\n")
    with pytest.raises(RehearsalError, match="r.csv:3: row is not time,address"):
        load_rehearsal(bad)
    config = tmp_path / "c.toml"
    config.write_text(COLONY + '\n[[input]]\nfile = "r.csv"\n')
    with pytest.raises(ConfigError, match="input.0.file: .*r.csv:3"):
        load_installation(config)


def test_rehearsal_files_as_a_spreadsheet_or_an_editor_saves_them(tmp_path):
    """A spreadsheet's "CSV UTF-8" begins with a byte-order mark, which made the header a row
    and the file an error at line 1; an editor's last line of spaces did the same to JSON lines."""
    from creatures.runtime.input_sources import load_rehearsal

    sheet = tmp_path / "sheet.csv"
    sheet.write_bytes("\ufefftime,address,args\r\n0.5,/lux,0.3\r\n".encode())
    lines = tmp_path / "lines.jsonl"
    lines.write_bytes('\ufeff{"time": 1, "address": "/lux", "args": [1]}\n  \n'.encode())
    assert [(r.time, r.address, r.args) for r in load_rehearsal(sheet)] == [(0.5, "/lux", (0.3,))]
    assert [(r.time, r.address, r.args) for r in load_rehearsal(lines)] == [(1.0, "/lux", (1,))]


def test_a_rehearsal_file_a_european_spreadsheet_or_another_encoding_saved_is_said_at_its_line(tmp_path):
    """Semicolons between fields (a spreadsheet in a European locale) were an IndexError; a
    Latin-1 byte was "cannot read rehearsal file" with no line, in a file of a million rows."""
    from creatures.runtime.input_sources import RehearsalError, load_rehearsal

    semicolons = tmp_path / "semi.csv"
    semicolons.write_text("time;address;args\n0.5;/lux;0.3\n")
    with pytest.raises(RehearsalError, match=r"semi.csv:1: fields are separated by ';'"):
        load_rehearsal(semicolons)
    latin = tmp_path / "latin.csv"
    latin.write_bytes("time,address,args\n0.5,/lux,0.3\n1.0,/caf\u00e9,1\n".encode("latin-1"))
    with pytest.raises(RehearsalError, match=r"latin.csv:3: not UTF-8 text \(byte 39: b'\\xe9'\)"):
        load_rehearsal(latin)


def test_the_readme_example_loads(tmp_path):
    readme = (__import__("pathlib").Path(__file__).parent.parent / "README.md").read_text()
    example = readme.split("### The input map: `[[input]]`", 1)[1].split("```toml\n", 1)[1].split("```", 1)[0]
    (tmp_path / "rehearsal.csv").write_text("time,address,args\n0.5,/calm\n")
    path = tmp_path / "readme.toml"
    path.write_text(COLONY + example)
    inst = load_installation(path)
    assert [r.spec.to for r in inst.routes] == ["reward", "note", "sensor", "drive"]


@pytest.mark.parametrize("air", [False, True])
def test_input_audio_does_not_reach_those_deaf_to_input(tmp_path, air):
    session, clock = colony(tmp_path, maps="", extra=f"[audio]\nair = {'true' if air else 'false'}\n")
    blocks: dict[str, list] = {"bo": [], "deaf": []}
    for creature in session.creatures:
        creature.listen = lambda t, block, sr, name=creature.name: blocks[name].append(block.copy())
    recorded = np.full(441, 0.25, dtype=np.float32)
    for step in (1, 2):
        clock.advance_to(step * 0.02)
        session.step(step * 0.02, 441, recorded)
    assert len(blocks["bo"]) == 2
    if not air:
        assert blocks["deaf"] == []  # no input, no room: nothing to hear
    else:  # the room only: what the input added is missing from the deaf creature's block
        assert len(blocks["deaf"]) == 1
        assert np.allclose(blocks["bo"][1] - blocks["deaf"][0], recorded)
