"""Accelerated soak: a 3-creature *exchange* colony for 24 simulated hours (an installation
runs unattended for weeks; what grows without bound shows up here, hours before a gallery
would notice).

The run is the same :class:`~creatures.runtime.session.Session` a live or offline run ticks,
on the simulated clock, with these settings (so it finishes in a few minutes on one core):

* ``tick = 20 s`` instead of 0.02 s. Every behaviour, model and motor program advances from
  elapsed time (DESIGN.md "Time"), so a coarse tick samples the same behaviour sparsely: each
  tick mostly ends one action and starts the next (an A* search), which is the costly part.
  The run therefore holds fewer action starts than a real day (about 4,300 per creature
  instead of ~25,000) but every kind of event a real day holds; leaks grow per event, and the
  growth is measured after warm-up. The schema caps ``tick`` at 0.5 s for real runs; the soak
  sets it directly.
* no audio (``audio=False``: no voices rendered, no ``out.wav``) — audio buffers are
  preallocated per tick and cannot grow; they are exercised by the offline tests.
* MIDI out to a :class:`CountingSink` (counts and checks messages, keeps none): the offline
  runner's ``MemorySink`` keeps every message for ``out.mid`` by design, which over weeks would
  be the one unbounded store; a live run sends to a port instead.
* a visitor plays the three input fragments every ``visit_every`` simulated seconds, so the
  colony never falls silent; the events log rotates at ``log_bytes`` with 2 backups.

Memory is sampled after ``gc.collect()`` at ``samples`` points: tracemalloc's traced bytes
(tracing starts before the colony is built, so growth is relative to all it holds) and the
process RSS. Growth compares the median of the last three samples with the median of the three
after warm-up (the first 10 %). The size of every queue that could grow (world pending notes,
scheduler heap and note tables, note spaces, placed/struck tables, motor arrivals, hanging
notes, the in-memory log) is read every tick and its maximum reported.

The soak found one leak: ``MotorSystem.arrivals`` kept every arrival of the body for ever
(~100 bytes every few seconds per creature); it is now a bounded deque.
"""

from __future__ import annotations

import dataclasses
import gc
import math
import os
import tempfile
import time
import tracemalloc
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import mido
import numpy as np

import installations
from bench import Row
from creatures.clock import SimulatedClock
from creatures.events import EventLog
from creatures.runtime.inputs import phrase_notes
from creatures.runtime.schema import load_installation
from creatures.runtime.session import Session


class CountingSink:
    """A MIDI sink that counts what it is sent and keeps nothing (a bounded sink for weeks).

    It checks what a synthesizer would notice: messages arrive in time order, and every
    note-on is matched by a note-off (``hanging`` counts notes left sounding).
    """

    def __init__(self) -> None:
        self.counts: Counter[str] = Counter()
        self.last_time = -math.inf
        self.out_of_order = 0
        self._on: Counter[tuple[int, int]] = Counter()

    def send(self, time: float, msg: mido.Message) -> None:
        self.counts[msg.type] += 1
        if time < self.last_time:
            self.out_of_order += 1
        self.last_time = max(self.last_time, time)
        if msg.type == "note_on" and msg.velocity > 0:
            self._on[(msg.channel, msg.note)] += 1
        elif msg.type in ("note_on", "note_off") and self._on[(msg.channel, msg.note)] > 0:
            self._on[(msg.channel, msg.note)] -= 1
        elif msg.type == "control_change" and msg.control == 123:  # all notes off
            for key in [k for k in self._on if k[0] == msg.channel]:
                del self._on[key]
        self._on += Counter()  # drop zero counts: the table stays as small as what sounds

    @property
    def hanging(self) -> int:
        return sum(self._on.values())


def rss_bytes() -> int:
    """Resident set size of this process (Linux ``/proc``; 0 where unavailable)."""
    try:
        with open("/proc/self/statm") as handle:
            return int(handle.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError):
        return 0


@dataclass
class Sample:
    t: float
    traced: int
    rss: int
    queues: dict[str, int]


@dataclass
class SoakResult:
    simulated: float
    wall: float
    samples: list[Sample]
    notes_played: int
    events: int
    log_files: list[Path]
    log_bytes: list[int]
    sink: CountingSink
    max_queues: dict[str, int] = field(default_factory=dict)

    def medians(self, what: str) -> tuple[float, float]:
        """Median of ``traced`` or ``rss`` over the three samples after warm-up (the first
        10 %) and over the last three."""
        values = [getattr(s, what) for s in self.samples]
        warm = max(1, len(values) // 10)
        return float(np.median(values[warm:warm + 3])), float(np.median(values[-3:]))

    def growth(self, what: str) -> float:
        """Relative growth of ``traced`` or ``rss`` from after warm-up to the end."""
        before, after = self.medians(what)
        return after / before - 1.0


def queue_sizes(session: Session, sink: CountingSink, log: EventLog) -> dict[str, int]:
    """Every container in a running colony that would betray a leak by growing."""
    world, scheduler = session.world, session.scheduler
    return {
        "world pending": len(world._pending),
        "scheduler heap": len(scheduler._heap),
        "scheduler notes": len(scheduler._ends) + len(scheduler._handles) + len(scheduler._sounding),
        "note spaces": sum(len(getattr(c, "space", ())) for c in session.creatures),
        "placed/struck tables": sum(len(getattr(c, "placed_at", {})) + len(getattr(c, "_struck_at", {}))
                                    for c in session.creatures),
        "motor arrivals": sum(len(c.body.motor.arrivals) for c in session.creatures if hasattr(c, "body")),
        "sink hanging notes": sink.hanging,
        "log in memory": len(log.records),
    }


def soak(
    out: Path,
    *,
    seconds: float,
    tick: float = 20.0,
    name: str = "exchange",
    visit_every: float = 600.0,
    log_bytes: int = 1 << 20,
    samples: int = 24,
) -> SoakResult:
    """Run installation ``name`` for ``seconds`` simulated seconds writing its log into
    ``out``; return memory samples and queue sizes (see the module docstring)."""
    started_tracing = not tracemalloc.is_tracing()
    if started_tracing:  # before the colony is built, so its whole state is the baseline
        tracemalloc.start()
    inst = load_installation(installations.path(name))
    inst.settings.tick = tick
    clock = SimulatedClock()
    sink = CountingSink()
    log = EventLog(out / "events.jsonl", max_bytes=log_bytes, backups=2)
    session = Session(inst, clock, log, sink)
    visitor = phrase_notes(start=0.0, rng=session.input_rng)
    next_visit = 1.0
    steps = int(math.ceil(seconds / tick - 1e-9))
    sample_every = max(1, steps // samples)
    taken: list[Sample] = []
    biggest: dict[str, int] = {}
    wall0 = time.perf_counter()
    try:
        for step in range(1, steps + 1):
            t = min(step * tick, seconds)
            while next_visit <= t:
                for note in visitor:
                    session.world.inject(dataclasses.replace(note, time=round(note.time + next_visit, 6)))
                next_visit += visit_every
            clock.advance_to(t)
            session.step(t, 0, None, audio=False)
            queues = queue_sizes(session, sink, log)  # every tick: a burst between samples counts
            biggest = {k: max(v, biggest.get(k, 0)) for k, v in queues.items()}
            if step % sample_every == 0 or step == steps:
                gc.collect()
                taken.append(Sample(t, tracemalloc.get_traced_memory()[0], rss_bytes(), queues))
    finally:
        session.close()
        log.close()
        if started_tracing:
            tracemalloc.stop()
    wall = time.perf_counter() - wall0
    files = sorted(out.glob("events.jsonl*"))
    return SoakResult(seconds, wall, taken, session.world.notes_played, log.count, files,
                      [f.stat().st_size for f in files], sink, biggest)


def run(quick: bool = False) -> list[Row]:
    hours = 2.0 if quick else 24.0
    with tempfile.TemporaryDirectory() as out:
        result = soak(Path(out), seconds=hours * 3600.0)
    size_bound = (1 << 20) * 3 + 4096
    largest = max(result.max_queues, key=result.max_queues.get)
    before, after = result.medians("traced")
    rows = [
        Row(f"{hours:g} simulated h, 3 creatures, tick 20 s, no audio", result.simulated / result.wall,
            "× real time"),
        Row("traced memory growth after warm-up (tracemalloc)", 100 * result.growth("traced"), "%",
            target=5.0, higher_is_better=False),
        Row(f"  the same in bytes (colony traced: {before / 2**20:.1f} MiB)", (after - before) / 1024, "KiB"),
        Row("RSS growth after warm-up", 100 * result.growth("rss"), "%", target=5.0, higher_is_better=False),
        Row(f"largest queue ({largest}) of {len(result.max_queues)} watched", result.max_queues[largest], "items",
            target=1000, higher_is_better=False),
        Row("events log on disk (rotated, 1 MiB × 3 files)", sum(result.log_bytes) / 2**20, "MiB",
            target=size_bound / 2**20, higher_is_better=False),
        Row("notes played (the colony stayed alive)", result.notes_played, "notes"),
        Row("notes left hanging at the end", result.sink.hanging, "notes", target=0, higher_is_better=False),
    ]
    return rows
