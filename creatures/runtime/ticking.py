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

Every tick's lateness (how long after its grid time it began) is measured: a tick more than
:data:`LATE_TICK` late is counted, and the run reports the count and the worst (the summary,
and ``timing`` events in the log), so what the loop cannot keep is seen, not hidden.
"""

from __future__ import annotations

import gc
import os
import sys
from contextlib import contextmanager
from typing import Callable, Iterator, Protocol

import numpy as np

from creatures.behaviour.motivation import between_ticks
from creatures.clock import Clock, SimulatedClock
from creatures.runtime.session import Session
from midi.notes import NoteEvent

POLL = 0.001
"""Seconds between looks at the inputs while waiting for the next tick."""

BEHIND = 1.0
"""Seconds behind the tick grid after which the loop skips ahead instead of racing to catch up."""

LATE_TICK = 0.005
"""Seconds after its grid time past which a tick counts as late (a quarter of the shipped 20 ms tick)."""

KEPT_LATENESS = 1 << 16
"""Latest tick latenesses kept for percentiles (about 20 minutes at a 20 ms tick; a fixed array)."""


class TickTiming:
    """How late each tick began: counts, the worst, and the latest :data:`KEPT_LATENESS` values
    (a ring, so a run of weeks keeps a fixed size) for percentiles."""

    def __init__(self) -> None:
        self.ticks = 0
        self.late = 0  # ticks more than LATE_TICK late
        self.worst = 0.0
        self._ring = np.zeros(KEPT_LATENESS)

    def add(self, lateness: float) -> None:
        self._ring[self.ticks % KEPT_LATENESS] = lateness
        self.ticks += 1
        if lateness > LATE_TICK:
            self.late += 1
        self.worst = max(self.worst, lateness)

    def recent(self) -> np.ndarray:
        """The kept latenesses (seconds), oldest first."""
        if self.ticks <= KEPT_LATENESS:
            return self._ring[: self.ticks].copy()
        i = self.ticks % KEPT_LATENESS
        return np.concatenate([self._ring[i:], self._ring[:i]])

    def percentile(self, q: float) -> float:
        kept = self.recent()
        return float(np.percentile(kept, q)) if len(kept) else 0.0


IDLE_COLLECT = 0.005
"""Seconds to the next tick above which the loop may collect garbage while it waits."""

FULL_COLLECT_EVERY = 600.0
"""Seconds between the loop's full collections (each in the wait after a tick)."""

HELD_OFF = 1 << 30
"""The oldest generation's threshold while a run holds automatic full collections off."""


class IdleCollections:
    """The live loop's garbage collection, in the waits between ticks rather than on them.

    Python starts a collection on whichever allocation crosses a threshold, so a full one
    lands mid-tick; measured on the exchange colony even after :func:`setup_kept`'s freeze:
    80–318 ms each, ticks and answers that late. While :func:`setup_kept` holds automatic full
    collections off, this collects the young generations once in each wait longer than
    :data:`IDLE_COLLECT` (cheap: only what the last ticks allocated), and everything every
    :data:`FULL_COLLECT_EVERY` seconds, so cycles that reached the oldest generation are still
    freed in a run of weeks (one tick in ten minutes may then start late; never a tick
    interrupted by one)."""

    def __init__(self, full_every: float = FULL_COLLECT_EVERY) -> None:
        self.full_every = full_every
        self._next_full: float | None = None
        self._collected_before: float | None = None  # the deadline of the wait last collected in

    def __call__(self, now: float, deadline: float) -> None:
        """Collect, if the wait until ``deadline`` (the next tick) allows and none has yet."""
        if deadline - now <= IDLE_COLLECT or deadline == self._collected_before:
            return
        self._collected_before = deadline
        if self._next_full is None:
            self._next_full = now + self.full_every
        if now >= self._next_full:
            self._next_full = now + self.full_every
            gc.collect()
        else:
            gc.collect(1)


@contextmanager
def setup_kept() -> Iterator[IdleCollections]:
    """Inside: everything built so far (modules, compiled code, motor graphs), which lives as
    long as the run, is out of the garbage collector's way, so a full collection no longer
    walks it (measured: 200 ms pauses with the exchange colony, each one a note answered
    200 ms late), and automatic full collections are held off: the loop collects in its
    waits instead (the :class:`IdleCollections` yielded, for :attr:`TickLoop.collect`).
    After: collected as before (a process that goes on: tests, benchmarks)."""
    gc.collect()
    gc.freeze()
    thresholds = gc.get_threshold()
    gc.set_threshold(thresholds[0], thresholds[1], HELD_OFF)
    try:
        yield IdleCollections()
    finally:
        gc.set_threshold(*thresholds)
        gc.unfreeze()


REALTIME_PRIORITY = 5
"""SCHED_RR priority of the creature's thread: above every ordinary process, below JACK's
server and clients (jackd's default is 10), so the audio graph still comes first."""


@contextmanager
def realtime(enabled: bool, say: Callable[[str], None]) -> Iterator[bool]:
    """Inside: the calling thread runs under real-time round-robin scheduling, where the OS
    allows it (root, or an ``rtprio`` limit: ``@audio - rtprio 5`` in limits.conf), so a busy
    machine cannot keep the tick waiting; says why not once otherwise. Threads started
    before (the supervisor) keep ordinary scheduling. Measured on 2 cores at load 8–11 with
    the exchange colony, fluidsynth and 20 OSC notes/s: ticks more than 5 ms late fell from
    39–50 % to 1–6 %, notes heard → answered p50 from 9–14 ms to 0.7 ms."""
    if not enabled or not hasattr(os, "sched_setscheduler"):
        yield False
        return
    try:
        os.sched_setscheduler(0, os.SCHED_RR, os.sched_param(REALTIME_PRIORITY))
    except OSError as exc:
        say(f"real-time scheduling refused ({exc.strerror or exc}); ticks may be late on a busy machine "
            f"(allow it with an rtprio limit of {REALTIME_PRIORITY}, or set realtime = false to silence this)")
        yield False
        return
    try:
        yield True
    finally:
        os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))


GIL_HANDOVER = 0.001
"""Seconds another Python thread may hold the interpreter before the loop's thread gets it
back, during a live run (Python's default is 5 ms: a supervisor job doing Python work, a port
check that parses a listing, could by itself make a tick 5 ms late; measured once under load:
5.7 ms during a port listing)."""


@contextmanager
def gil_handover(interval: float = GIL_HANDOVER) -> Iterator[None]:
    """Inside: the interpreter switches threads every ``interval`` seconds, so the supervisor
    thread (creatures/supervisor.py) never keeps the creatures' thread waiting long."""
    before = sys.getswitchinterval()
    sys.setswitchinterval(interval)
    try:
        yield
    finally:
        sys.setswitchinterval(before)


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
        self.skipped = 0  # times the loop fell BEHIND seconds behind and skipped ahead
        self.timing = TickTiming()
        self.heard_between = 0  # notes heard between ticks, at once
        self.collect: Callable[[float, float], None] | None = None  # garbage collection in the waits (setup_kept)
        # Work at tick boundaries, on this thread, after each tick and at each look between
        # ticks (never mid-tick): body stream frames, remote console requests.
        self.boundary: list[Callable[[float], None]] = []
        self.paused = False  # the remote console's pause: no notes delivered; the caller skips its ticks
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
            lateness = self.wall.now() - next_tick
            self.timing.add(max(0.0, lateness))
            if lateness > BEHIND:  # a stall: skip ahead instead of racing
                self.skipped += 1
                next_tick = self.wall.now()
            self.time.advance_to(max(next_tick, self.time.now()))
            self.inputs.poll(next_tick)  # what arrived while the previous tick ran
            on_tick(next_tick)
            for work in self.boundary:
                work(next_tick)
            next_tick += self.tick

    def between(self, deadline: float) -> None:
        """Until ``deadline``: every :data:`POLL` seconds, hear what arrived and send what is due."""
        while (now := self.wall.now()) < deadline:
            self.time.advance_to(max(now, self.time.now()))
            self.heard_between += self.inputs.poll(now)
            if not self.paused:
                self.hear_now(now)
            for work in self.boundary:
                work(now)
            if self.collect is not None:
                self.collect(self.wall.now(), deadline)
            self.wait(max(0.0, min(POLL, deadline - self.wall.now())))

    def hear_now(self, t: float) -> None:
        """Deliver every note started by ``t`` (creatures hear it; reflexes answer) and send
        every message due. Their impulses land on their drives' last tick
        (:func:`~creatures.behaviour.motivation.between_ticks`): no matrix exponential for a
        step off the tick grid on the way to an answer."""
        with between_ticks():
            self.session.world.deliver(t)
        self.session.scheduler.pump()
