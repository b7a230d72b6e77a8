"""The live loop: ticks stay on their grid; a note heard between ticks is answered at once
(within a millisecond, not at the next tick); the creatures' time never runs backwards."""

from __future__ import annotations

import os
from typing import Callable

import mido
import pytest

from creatures.clock import SimulatedClock
from creatures.events import EventLog
from creatures.runtime.live import LiveInputs
from creatures.runtime.schema import load_installation
from creatures.runtime.session import Session
from creatures.runtime import ticking
from creatures.runtime.ticking import POLL, TickLoop, realtime
from midi.ports import MemoryInput, MemoryPorts
from midi.sinks import MemorySink

CONFIG = """
title = "ticking"
tick = 0.04
[midi]
input_port = "keys"
[[creature]]
name = "ada"
kind = "exchange"
space.answer = 1.0
space.strike_interval = 0.0  # answer every note, however close together
"""


class Rig:
    """A colony of one answering exchange creature, its loop on a simulated wall clock, and a
    keyboard whose notes reach the input at given wall times (as a device's would)."""

    def __init__(self, tmp_path, score: list[tuple[float, int]], *, tick_takes: float = 0.0) -> None:
        config = tmp_path / "ticking.toml"
        config.write_text(CONFIG)
        inst = load_installation(config)
        self.wall, clock = SimulatedClock(), SimulatedClock()
        self.keys = MemoryInput("keys")
        self.sink = MemorySink()
        self.session = Session(inst, clock, EventLog(), self.sink)
        inputs = LiveInputs(inst, self.session, clock, say=lambda m: None, ports=MemoryPorts(self.keys))
        self.loop = TickLoop(self.session, inputs, self.wall, clock, inst.settings.tick, wait=self.wait)
        self.score = list(score)
        self.tick_takes = tick_takes
        self.ticks: list[float] = []

    def play_until(self, t: float) -> None:
        while self.score and self.score[0][0] <= t:
            _, pitch = self.score.pop(0)
            self.keys.inject(mido.Message("note_on", note=pitch, velocity=90))

    def wait(self, seconds: float) -> None:
        self.play_until(self.wall.advance(seconds))

    def on_tick(self, t: float) -> None:
        self.ticks.append(t)
        self.play_until(self.wall.advance(self.tick_takes))  # the tick's work takes wall time
        self.session.step(t, 0, None, audio=False)

    def run(self, until: Callable[[float], bool]) -> None:
        self.loop.run(self.on_tick, until)

    def records(self, kind: str) -> list[dict]:
        return [e for e in self.session.log.records if e["kind"] == kind]


def test_a_note_between_ticks_is_answered_within_a_poll_not_at_the_next_tick(tmp_path):
    rig = Rig(tmp_path, [(0.0573, 64)])
    rig.run(until=lambda t: t > 0.2)
    assert rig.ticks == pytest.approx([0.04, 0.08, 0.12, 0.16, 0.2])  # the grid is kept
    (heard,) = rig.records("heard")
    assert 0.0573 <= heard["time"] <= 0.0573 + POLL + 1e-9
    answers = [(t, m) for t, m in rig.sink.messages if m.type == "note_on"]
    assert [(t, m.note) for t, m in answers] == [(heard["time"], 64)]  # struck where it landed, at once
    assert rig.loop.heard_between == 1


def test_a_note_that_arrives_at_a_tick_is_heard_at_the_ticks_own_instant(tmp_path):
    """Processing takes wall time: the tick at 0.08 s works until 0.085 s. A note that came in
    just before it is heard at 0.08 s, the tick's instant, even though the wall clock is later
    by then: a creature that stamped it with the wall time would see its tick (at 0.08 s) go
    back in time, and its drives refuse to."""
    rig = Rig(tmp_path, [(0.0795, 60), (0.0812, 62)], tick_takes=0.005)
    rig.run(until=lambda t: t > 0.2)
    heard = [(e["time"], e["pitch"]) for e in rig.records("heard")]
    assert heard[0] == (pytest.approx(0.08), 60)  # polled at the tick, heard within it
    assert heard[1][1] == 62 and 0.085 <= heard[1][0] <= 0.085 + POLL  # came mid-tick: heard after it
    answers = [(round(t, 6), m.note) for t, m in rig.sink.messages if m.type == "note_on"]
    assert answers == [(round(heard[0][0], 6), 60), (round(heard[1][0], 6), 62)]


def test_a_machine_far_behind_skips_ahead_and_counts_it(tmp_path):
    rig = Rig(tmp_path, [], tick_takes=1.5)  # every tick stalls the loop for longer than a second
    rig.run(until=lambda t: len(rig.ticks) >= 3)
    assert rig.loop.skipped >= 1
    assert rig.loop.timing.late >= 1 and rig.loop.timing.worst > 1.0
    assert rig.ticks[1] - rig.ticks[0] > 1.0


def test_the_loop_thread_turns_real_time_where_allowed_and_back_after():
    said: list[str] = []
    with realtime(True, said.append) as granted:
        inside = os.sched_getscheduler(0)
    if not granted:
        pytest.skip(f"real-time scheduling not allowed here: {said}")
    assert inside == os.SCHED_RR and os.sched_getscheduler(0) == os.SCHED_OTHER and not said


def test_real_time_refused_is_said_once_and_the_run_goes_on(monkeypatch):
    def refuse(*args: object) -> None:
        raise PermissionError(1, "Operation not permitted")

    monkeypatch.setattr(ticking.os, "sched_setscheduler", refuse)
    said: list[str] = []
    with realtime(True, said.append) as granted:
        assert not granted
    with realtime(False, said.append) as granted:  # realtime = false: not even asked
        assert not granted
    assert len(said) == 1 and "real-time scheduling refused (Operation not permitted)" in said[0]


def test_ticks_that_begin_late_are_counted_not_hidden(tmp_path):
    rig = Rig(tmp_path, [], tick_takes=0.05)  # each tick works 50 ms of a 40 ms grid: the next starts late
    rig.run(until=lambda t: len(rig.ticks) >= 10)
    timing = rig.loop.timing
    assert timing.ticks == 10 and rig.loop.skipped == 0
    assert timing.late == 9  # all but the first, each 10 ms later than the one before
    assert timing.worst == pytest.approx(0.09) and timing.percentile(50) == pytest.approx(0.045, abs=0.006)


def test_inside_a_live_run_another_thread_holds_the_interpreter_at_most_a_millisecond():
    """gil_handover: the supervisor's Python work cannot keep a tick waiting Python's default
    5 ms; the default comes back afterwards, even when the run fails."""
    import sys

    from creatures.runtime.ticking import GIL_HANDOVER, gil_handover

    before = sys.getswitchinterval()
    with pytest.raises(RuntimeError), gil_handover():
        assert sys.getswitchinterval() == pytest.approx(GIL_HANDOVER)
        raise RuntimeError("the run failed")
    assert sys.getswitchinterval() == before
