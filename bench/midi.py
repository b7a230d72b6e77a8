"""MIDI benchmarks: raw-byte parsing beside mido's own Parser, loading a 100,000-note file
beside mido's parse of it, and MIDI-in → creature decision → MIDI-out latency through the live
loop's own code path.

Targets: latency p99 ≤ 5 ms; the file load at least 1.5× as fast as mido's parse alone,
measured in the same run. The raw-byte parse is printed beside mido's without a target.
"""

from __future__ import annotations

import bisect
import tempfile
import time
from collections import defaultdict
from pathlib import Path
from typing import NamedTuple

import mido
import numpy as np
from threadpoolctl import threadpool_limits

import installations
from bench import Row, best_of
from creatures.clock import SimulatedClock
from creatures.events import EventLog
from creatures.runtime.live import LiveInputs
from creatures.runtime.schema import load_installation
from creatures.runtime.session import Session
from creatures.runtime.ticking import TickLoop, setup_kept
from midi.files import TempoMap, read_notes, write_notes
from midi.notes import NoteEvent
from midi.parser import StreamParser
from midi.ports import MemoryInput, MemoryPorts


def _channel_stream(rng: np.random.Generator, n: int) -> bytes:
    """``n`` note-on/off and control messages, each with its status byte (mido's Parser
    cannot read running status, so the comparison uses a stream both can read)."""
    status = rng.choice([0x80, 0x90, 0xB0], n) | rng.integers(0, 16, n)
    data = rng.integers(0, 128, (n, 2))
    return np.column_stack([status, data]).astype(np.uint8).tobytes()


def _parse_rows(rng: np.random.Generator, n: int) -> list[Row]:
    stream = _channel_stream(rng, n)

    def ours() -> None:
        parser = StreamParser()
        parser.feed(stream)
        assert len(parser.pending()) == n

    def theirs() -> None:
        parser = mido.Parser()
        parser.feed(stream)
        assert len(list(parser)) == n

    t_ours, t_theirs = best_of(ours), best_of(theirs)
    return [Row("parse raw bytes (running-status aware)", n / t_ours, "msgs/s",
                baseline="mido.Parser", ratio=t_theirs / t_ours)]


def _file_rows(rng: np.random.Generator, n: int) -> list[Row]:
    starts = np.cumsum(rng.uniform(0.0, 0.05, n))
    notes = [
        NoteEvent(float(t), int(p), int(v), int(c), float(d))
        for t, p, v, c, d in zip(starts, rng.integers(0, 128, n), rng.integers(1, 128, n),
                                 rng.integers(0, 16, n), rng.uniform(0.01, 1.0, n))
    ]
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "big.mid"
        write_notes(path, notes, tempo=TempoMap.from_seconds(480, [(starts[-1] / 3, 90.0), (starts[-1] / 2, 150.0)]))
        t_ours = best_of(lambda: read_notes(path), repeat=2)
        t_mido = best_of(lambda: mido.MidiFile(path), repeat=2)
    # Ours is the whole load (parse, tempo map, pairing, NoteEvents); mido's only its parse
    # to messages. Target: at most 1/1.5 of mido's time, measured in this run.
    return [Row(f"load .mid of {n:,} notes to NoteEvents (midi.smf)", t_ours, "s", target=t_mido / 1.5,
                higher_is_better=False, baseline="mido.MidiFile parse only", ratio=t_mido / t_ours),
            Row("mido.MidiFile parse of the same file (peer, same run)", t_mido, "s", higher_is_better=False)]


class _FastForward:
    """Wall time with the loop's idle sleeps skipped: it runs at real speed while the loop works
    and jumps ahead when the loop would sleep. A long performance is replayed in the time its
    processing takes, and every wait a note really has — the poll interval, a tick in progress —
    is still in its latency."""

    def __init__(self) -> None:
        self.skipped = 0.0

    def now(self) -> float:
        return time.perf_counter() + self.skipped

    def wait(self, seconds: float) -> None:
        self.skipped += seconds


class _Player(MemoryInput):
    """A keyboard playing ``score`` (``(time, message)``, in time order): each message is in
    the port from its time on, whatever the loop is doing then."""

    def __init__(self, name: str, clock: _FastForward, score: list[tuple[float, mido.Message]]) -> None:
        super().__init__(name)
        self.clock = clock
        self.score = score
        self.played = 0

    def _receive(self, block: bool = True) -> None:
        now = self.clock.now()
        while self.played < len(self.score) and self.score[self.played][0] <= now:
            self._messages.append(self.score[self.played][1])
            self.played += 1


class _Arrivals:
    """A MIDI sink that stamps, by pitch, the time each message of one channel reaches it."""

    def __init__(self, clock: _FastForward, channel: int) -> None:
        self.clock = clock
        self.channel = channel
        self.at: dict[int, list[float]] = defaultdict(list)

    def send(self, time_: float, msg: mido.Message) -> None:
        # A struck note object sounds (note-on), or swells if it still sounds (polytouch).
        if msg.type in ("note_on", "polytouch") and msg.channel == self.channel:
            self.at[msg.note].append(self.clock.now())


WARM_UP = 200
"""Notes of the warm-up run before the measured one: its first path searches load compiled code
(numba), or compile it where the cache is cold (one tick of 42 s measured here)."""


class Played(NamedTuple):
    """One live run of the colony answering a keyboard (:func:`_play`)."""

    latency_ms: np.ndarray
    """Each note's wait from the input to its answer at the sink (inf: never answered)."""
    due: np.ndarray
    """When each note was at the input, on the loop's clock."""
    ticks: np.ndarray
    """(start, end) of every tick on the loop's clock."""


def _play(rng: np.random.Generator, total: int) -> Played:
    """The shipped *exchange* colony, live: a keyboard plays ``total`` notes 5–25 ms apart into an
    in-memory MIDI input; the live loop (:class:`TickLoop`, the code path of ``creatures run``,
    audio off) ticks the three creatures on their 40 ms grid and, between ticks, looks at the
    input every millisecond and hears what arrived (:class:`LiveInputs` → World); ada decides
    to answer every note she hears by striking it where it lands in space (World →
    NoteScheduler → sink): ``answer = 1`` with no wait between strikes or before re-striking a
    note, and no mutation, so each answer is found by its pitch. Latency: from the moment a note is at the
    input to its answer reaching the sink, on a clock that runs at wall speed whenever the
    loop works (:class:`_FastForward`), so a note that arrives during a tick waits for it."""
    inst = load_installation(installations.path("exchange"))
    inst.settings.midi.input_port = "bench keys"
    ada = inst.specs[0]
    ada.space.answer, ada.space.strike_interval, ada.space.refractory, ada.space.mutation = 1.0, 0.0, 0.0, 0.0
    wall = _FastForward()
    clock = SimulatedClock(wall.now())
    arrivals = _Arrivals(wall, ada.channel)
    pitches = np.concatenate([rng.permutation(128) for _ in range(total // 128 + 1)])[:total]
    velocities = rng.integers(40, 120, total)
    ticks: list[tuple[float, float]] = []
    with tempfile.TemporaryDirectory() as tmp, threadpool_limits(limits=1):  # as `creatures run` sets
        log = EventLog(Path(tmp) / "events.jsonl")  # as `creatures run --log`
        session = Session(inst, clock, log, arrivals)
        due = wall.now() + 0.5 + np.cumsum(rng.uniform(0.005, 0.025, total))
        keys = _Player("bench keys", wall, [(float(t), mido.Message("note_on", note=int(p), velocity=int(v)))
                                            for t, p, v in zip(due, pitches, velocities)])
        loop = TickLoop(session, LiveInputs(inst, session, clock, say=lambda m: None, ports=MemoryPorts(keys)),
                        wall, clock, inst.settings.tick, wait=wall.wait)

        def tick(t: float) -> None:
            began = wall.now()
            session.step(t, 0, None, audio=False)
            ticks.append((began, wall.now()))

        with setup_kept() as loop.collect:
            loop.run(tick, until=lambda t: t > due[-1] + 0.5)
        session.close()
        log.close()
    latency_ms = np.full(total, np.inf)  # an unanswered note counts as infinitely late
    for i, (pitch, sent) in enumerate(zip(pitches, due)):
        answers = arrivals.at[int(pitch)]
        k = bisect.bisect_left(answers, sent)
        if k < len(answers):
            latency_ms[i] = (answers[k] - sent) * 1e3
    return Played(latency_ms, due, np.array(ticks).reshape(-1, 2))


def _p99(values: np.ndarray) -> float:
    """The 99th percentile, NaN where there is nothing to take it of."""
    return float(np.percentile(values, 99)) if values.size else float("nan")


def _latency_rows(rng: np.random.Generator, n: int) -> list[Row]:
    """MIDI in → decision → MIDI out through the live loop (:func:`_play`), ``n`` notes measured in
    a run of their own after a warm-up run of :data:`WARM_UP` notes, so that no compiling (or
    loading of compiled code) is in the measurement however long it takes (the first note's wait
    in the warm-up run is shown)."""
    first = _play(rng, WARM_UP).latency_ms[0]
    latency_ms, due, ticks = _play(rng, n)
    starts, ends = ticks.T
    k = np.searchsorted(starts, due, side="right") - 1
    during_tick = (k >= 0) & (due < ends[np.maximum(k, 0)])
    what = f"MIDI in → exchange decision → out ({n:,} notes)"
    return [
        Row(f"{what} p50", float(np.percentile(latency_ms, 50)), "ms", higher_is_better=False),
        Row(f"{what} p99", float(np.percentile(latency_ms, 99)), "ms", target=5.0, higher_is_better=False),
        Row("  p99 of notes arriving between ticks (≤1 ms poll + decision)", _p99(latency_ms[~during_tick]), "ms",
            higher_is_better=False),
        Row("  notes arriving while a tick runs (they wait for its end)", float(during_tick.mean() * 100), "%"),
        Row("  colony's behaviour tick p99", _p99(ends - starts) * 1e3, "ms", higher_is_better=False),
        Row("  notes answered", float(np.isfinite(latency_ms).mean() * 100), "%"),
        Row("  first note of the warm-up run (loads compiled code; not counted)", float(first), "ms",
            higher_is_better=False),
    ]


def run(quick: bool) -> list[Row]:
    rng = np.random.default_rng(2001)
    return [
        *_parse_rows(rng, 20_000 if quick else 200_000),
        *_file_rows(rng, 10_000 if quick else 100_000),
        *_latency_rows(rng, 1_000 if quick else 10_000),
    ]
