"""The live loop's time: behaviour ticks on a fixed grid, and between them, notes heard at once.

A player expects a creature to react when a key goes down, not at the next behaviour tick
(up to ``tick`` seconds later: 40 ms in the shipped configs). So between ticks the loop looks
at its inputs about every millisecond (:data:`POLL`); a note that arrives is delivered to the
creatures at once — their reflexes may answer it (exchange's ``answer``) — and whatever has
fallen due leaves the scheduler then (note-offs and notes timed between ticks go out on time
too). Behaviour ticks stay on their grid of elapsed seconds.

Creatures live on their own clock (a :class:`SimulatedClock`) that the loop moves to each
instant it lets them act: a tick's time, or the moment a note is heard. Their time therefore
never runs backwards — a creature that stamped a heard note with the wall time while its tick
had a grid time a little earlier would see its drives go back in time — and a tick is one
instant, as offline.
"""

from __future__ import annotations

import gc
from contextlib import contextmanager
from typing import Callable, Iterator, Protocol

from creatures.clock import Clock, SimulatedClock
from creatures.runtime.session import Session
from midi.notes import NoteEvent

POLL = 0.001
"""Seconds between looks at the inputs while waiting for the next tick."""

BEHIND = 1.0
"""Seconds behind the tick grid after which the loop skips ahead instead of racing to catch up."""


@contextmanager
def setup_kept() -> Iterator[None]:
    """Inside: everything built so far (modules, compiled code, motor graphs), which lives as
    long as the run, is out of the garbage collector's way, so a full collection no longer
    walks it (measured: 200 ms pauses with the exchange colony, each one a note answered
    200 ms late). After: collected as before (a process that goes on: tests, benchmarks)."""
    gc.collect()
    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()


class Inputs(Protocol):
    """Where live notes come from (``creatures.runtime.live.LiveInputs``)."""

    def poll(self, t: float) -> int:
        """Put the notes that arrived into the colony's note bus at time ``t``; how many."""
        ...

    def wait(self, timeout: float) -> None:
        """Sleep up to ``timeout`` seconds (waking early when input arrives, where it can)."""
        ...


class TickLoop:
    """Runs a session's ticks on the grid of ``wall`` time, hearing notes between them.

    ``wall`` is real time (a :class:`~creatures.clock.WallClock`) in a live run; tests and the
    benchmark may pass a simulated clock and a ``wait`` that advances it. ``time`` is the
    session's own clock, which only this loop moves.
    """

    def __init__(self, session: Session, inputs: Inputs, wall: Clock, time: SimulatedClock, tick: float, *,
                 wait: Callable[[float], None] | None = None) -> None:
        self.session = session
        self.inputs = inputs
        self.wall = wall
        self.time = time
        self.tick = tick
        self.wait = wait or inputs.wait
        self.late = 0  # times the loop fell BEHIND seconds behind and skipped ahead
        self.heard_between = 0  # notes heard between ticks, at once
        session.world.listeners.append(self._send_now)

    def _send_now(self, creature: str, note: NoteEvent) -> None:
        """A note a creature has just decided leaves at once: before the rest of the colony
        has heard it, and mid-tick rather than at the tick's end."""
        self.session.scheduler.pump()

    def run(self, on_tick: Callable[[float], None], until: Callable[[float], bool]) -> None:
        """Call ``on_tick(t)`` at every grid time ``t`` until ``until(t)`` says stop."""
        next_tick = self.wall.now() + self.tick
        while not until(next_tick):
            self.between(next_tick)
            if self.wall.now() - next_tick > BEHIND:  # a stall: skip ahead instead of racing
                self.late += 1
                next_tick = self.wall.now()
            self.time.advance_to(max(next_tick, self.time.now()))
            self.inputs.poll(next_tick)  # what arrived while the previous tick ran
            on_tick(next_tick)
            next_tick += self.tick

    def between(self, deadline: float) -> None:
        """Until ``deadline``: every :data:`POLL` seconds, hear what arrived and send what is due."""
        while (now := self.wall.now()) < deadline:
            self.time.advance_to(max(now, self.time.now()))
            self.heard_between += self.inputs.poll(now)
            self.hear_now(now)
            self.wait(min(POLL, deadline - now))

    def hear_now(self, t: float) -> None:
        """Deliver every note started by ``t`` (creatures hear it; reflexes answer) and send
        every message due."""
        self.session.world.deliver(t)
        self.session.scheduler.pump()
