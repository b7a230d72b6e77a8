"""``creatures rehearse CONFIG --days N``: a gallery week on the simulated clock, before the gallery.

The same :class:`~creatures.runtime.session.Session` a live run ticks, on a simulated clock
that starts on a Monday at midnight and runs through the opening hours (``[rehearse] hours``,
else ``[schedule]``, else a museum's 10:00–18:00, Tuesday to Sunday): closed, the colony sleeps as the live schedule sends it
to sleep (creatures/runtime/opening.py: no ticks, every note off, what it heard meanwhile
forgotten on waking) and the clock leaps to the next opening. Open, visitors
(:mod:`creatures.runtime.visitors`) come and go and play into it, as notes on the note bus
and, for a piece that hears sound, as tones or speech in its ears. Every hour is measured
(:mod:`creatures.runtime.measures`). A crash is caught as a supervisor would catch it: the
colony is rebuilt from the state it had at the start of the hour and goes on the next hour;
the hour is not crash-free.

Thesis: "exchange (installation)" describes a piece met by whoever walks in, whose
complexity waxes and wanes with them; this is that week, heard in minutes.
"""

from __future__ import annotations

import bisect
import dataclasses
import math
import tempfile
import time
from dataclasses import dataclass, field
from datetime import datetime, timedelta, timezone
from pathlib import Path
from typing import Any, Callable
from zoneinfo import ZoneInfo

import mido
import numpy as np

from audio.formants import speak
from creatures.clock import SimulatedClock
from creatures.events import EventLog
from creatures.runtime.input_sources import Rehearsal as InputFile
from creatures.runtime.input_sources import Row, note_on
from creatures.runtime.inputs import render_notes
from creatures.runtime.measures import ACTS, HourMeasures, HourTally, Swings
from creatures.runtime.opening import DAYS, OpeningHours
from creatures.runtime.schema import LoadedInstallation, ScheduleSection
from creatures.runtime.session import Session, write_snapshot
from creatures.runtime.visitors import Phrase, Visitors, generated, load_corpus

MONDAY = datetime(2029, 1, 1)
"""The rehearsed week's first day (a Monday, at midnight in the hours' zone)."""

GALLERY = ScheduleSection(days=["tue", "wed", "thu", "fri", "sat", "sun"], opens="10:00", closes="18:00")
"""Hours rehearsed when the config gives none: a museum's, closed on Mondays (48 open hours a week)."""

STEP = 60.0
"""Seconds between the instants at which the hours are looked at (openings fall on minutes)."""


class CountingSink:
    """MIDI out that counts and keeps nothing (a week of messages in memory would be the one
    unbounded store; :class:`midi.sinks.NoteSink`)."""

    def __init__(self) -> None:
        self.count = 0

    def send(self, time: float, msg: mido.Message) -> None:
        self.count += 1


@dataclass
class Rehearsal:
    """What a rehearsal measured: one row per opening hour, and the week's summary."""

    title: str
    days: int
    tick: float
    hours: list[HourMeasures]
    longest_silence: dict[str, float]
    """Per creature, the most open seconds between two of its acts (or to the end)."""
    opening_day: float
    """Open seconds of the longest opening day: what "silent for more than a day" compares to."""
    visitors: int = 0
    crashes: list[str] = field(default_factory=list)
    wall: float = 0.0

    @property
    def crash_free(self) -> int:
        return sum(not h.crashed for h in self.hours)

    @property
    def open_seconds(self) -> float:
        return sum(h.open_seconds for h in self.hours)

    def to_dict(self) -> dict[str, Any]:
        return {"title": self.title, "days": self.days, "tick": self.tick, "visitors": self.visitors,
                "opening_day": self.opening_day, "longest_silence": self.longest_silence,
                "crash_free_hours": self.crash_free, "crashes": self.crashes, "wall": self.wall,
                "hours": [h.to_dict() for h in self.hours]}


def open_spans(hours: ScheduleSection, days: int) -> list[tuple[float, float]]:
    """The opening hours of ``days`` days from :data:`MONDAY`, as seconds from its midnight."""
    opening = OpeningHours(hours.days, hours.opens or "00:00", hours.closes, hours.timezone)
    zone = ZoneInfo(hours.timezone) if hours.timezone else timezone.utc
    start = MONDAY.replace(tzinfo=zone)
    spans: list[tuple[float, float]] = []
    for k in range(int(days * 86400 / STEP)):
        t = k * STEP
        if not opening.is_open(start + timedelta(seconds=t)):
            continue
        if spans and spans[-1][1] == t:
            spans[-1] = (spans[-1][0], t + STEP)
        else:
            spans.append((t, t + STEP))
    return spans


class _Ears:
    """The sound the visitors make, for a piece that hears: blocks cut from what they play."""

    def __init__(self, sample_rate: int, rng: np.random.Generator) -> None:
        self.sr, self.rng = sample_rate, rng
        self.sounding: list[tuple[int, np.ndarray]] = []

    def add(self, start: float, phrase: Phrase) -> None:
        if phrase.line is not None:
            samples, _ = speak(phrase.line, self.rng, self.sr)
        else:
            samples = render_notes(list(phrase.notes), self.sr, phrase.length + 0.5)
        self.sounding.append((int(round(start * self.sr)), samples.astype(np.float32)))

    def block(self, a: int, b: int) -> np.ndarray:
        out = np.zeros(b - a, np.float32)
        for s, x in self.sounding:
            lo, hi = max(a, s), min(b, s + len(x))
            if hi > lo:
                out[lo - a : hi - a] += x[lo - s : hi - s]
        self.sounding = [(s, x) for s, x in self.sounding if s + len(x) > b]
        return out


def _boredom(session: Session) -> list[tuple[Any, Swings]]:
    """The colony's boredom drives (exchange's, sandstone's), each with its cycle counter."""
    found = []
    for creature in session.creatures:
        motivation = getattr(creature, "motivation", None)
        if motivation is not None and "boredom" in getattr(motivation, "names", ()):
            found.append((motivation, Swings()))
    return found


def _row_time(row: Row) -> float:
    return row.time


@dataclass(frozen=True)
class Plan:
    """What a rehearsal of one config will open and play, read before any hour is rehearsed:
    ``creatures rehearse --compare`` makes both configs' plans first, so a slip in the second
    (days holding no opening hours, a corpus that cannot be read) is said before the minutes
    the first one's week takes, not after."""

    days: int
    spans: list[tuple[float, float]]
    corpus: list[Phrase]
    unplayed: list[str] = field(default_factory=list)
    """What the config feeds a run that the week leaves out, said (:func:`unplayed_files`)."""


def plan(inst: LoadedInstallation, days: int | None = None) -> Plan:
    """The opening spans of ``days`` simulated days (default ``[rehearse] days``) and the
    visitors' corpus; :class:`ConfigError` or :class:`CorpusError` when either cannot be."""
    settings = inst.settings
    params = settings.rehearse
    days = days or params.days
    hours = params.hours or (settings.schedule if settings.schedule.opens is not None else GALLERY)
    spans = open_spans(hours, days)
    if not spans:  # e.g. one day: a rehearsal begins on a Monday, a gallery's day off
        raise inst.error(("rehearse", "days"), f"{days} day(s) from Monday hold no opening hours (open "
                                               f"{', '.join(hours.days)}): rehearse more days (--days, "
                                               "[rehearse] days) or set [rehearse] hours")
    corpus = load_corpus(inst.resolve(params.corpus, ("rehearse", "corpus"))) if params.corpus else generated(settings.input.generate == "speech")
    return Plan(days, spans, corpus, unplayed_files(inst))


def unplayed_files(inst: LoadedInstallation) -> list[str]:
    """The config's rehearsal files (``[[input]] file``), each said as not played: its rows are
    one take timed from a run's start (an offline run plays it from 0 s, a live one from its
    start), a stand-in for visitors, while a rehearsed week begins on a Monday at midnight,
    most of it closed, and its visitors are ``[rehearse]``'s. Played at the week's start they
    would fall in a closed night; played each opening, one take would become every visitor."""
    return [str(inst.error(("input", "map", i, "file"),
                           f"the rehearsal file {spec.file!r} ({len(inst.rehearsals[i])} rows) is not played in a "
                           "rehearsed week: its rows are one take timed from a run's start (`creatures offline` and "
                           "live runs play it); the week's visitors are [rehearse]'s"))
            for i, spec in enumerate(inst.settings.input.map) if spec.file is not None]


def rehearse(inst: LoadedInstallation, days: int | None = None, *,
             taps: tuple[Callable[[dict[str, Any]], None], ...] = (),
             progress: Callable[[str], None] | None = None, planned: Plan | None = None) -> Rehearsal:
    """Rehearse ``inst`` for ``days`` simulated days (default ``[rehearse] days``), or as
    ``planned`` (:func:`plan`); ``taps`` see every events-log record as it is written
    (nothing is kept for a week); ``progress`` is told first what of the config the week does
    not play (:func:`unplayed_files`), then each opening hour as it is done (a week takes minutes)."""
    settings = inst.settings
    params = settings.rehearse
    planned = planned or plan(inst, days)
    days, spans, corpus = planned.days, planned.spans, planned.corpus
    tick = params.tick or settings.tick
    sr = settings.audio.sample_rate
    hearing = settings.input.generate != "none" or settings.input.audio is not None
    rng = np.random.default_rng([settings.seed, 20])
    visitors = Visitors(params, corpus, rng)
    ears = _Ears(sr, rng) if hearing else None
    wall0 = time.perf_counter()
    for line in planned.unplayed if progress is not None else ():
        progress(line)

    clock, log = SimulatedClock(), EventLog(keep_in_memory=0)  # the taps see every record; none is kept
    session = Session(inst, clock, log, CountingSink())
    names = [c.name for c in session.creatures]
    hours_open = len({hour for a, b in spans for hour in range(int(a // 3600), math.ceil(b / 3600))})
    per_day: dict[int, float] = {}
    for a, b in spans:
        per_day[int(a // 86400)] = per_day.get(int(a // 86400), 0.0) + b - a
    state = {"open_before": 0.0, "span": spans[0] if spans else (0.0, 0.0)}
    last = dict.fromkeys(names, 0.0)
    longest = dict.fromkeys(names, 0.0)
    tally: HourTally | None = None

    def open_time(t: float) -> float:
        a, b = state["span"]
        return state["open_before"] + min(max(t - a, 0.0), b - a)

    def heard(record: dict[str, Any]) -> None:
        if record["kind"] not in ACTS or tally is None:
            return
        tally.add(record)
        at = open_time(record["t"])
        who = record["creature"]
        longest[who] = max(longest[who], at - last[who])
        last[who] = at
        visitors.hear(record["t"], record.get("pitch"))

    log.taps.append(heard)
    log.taps.extend(taps)
    # A visitor's note that an [[input]] MIDI map takes (a pad that possesses a character, a
    # clicker) reaches the colony through the map, held for the note's length, as a live
    # port's note-on and note-off would; any other note is heard as music.
    pads = InputFile([], 0.0, session.inputs)
    rows: list[HourMeasures] = []
    crashes: list[str] = []
    boredom = _boredom(session)
    counted = {"answered": 0, "unanswered": 0, "arrived": 0, "cycles": 0}

    def close_hour() -> None:
        cycles = sum(s.cycles for _, s in boredom)
        rows.append(tally.finish(answered=visitors.answered - counted["answered"],
                                 unanswered=visitors.unanswered - counted["unanswered"],
                                 cycles=cycles - counted["cycles"] if boredom else None,
                                 visitors=visitors.arrived - counted["arrived"]))
        counted.update(answered=visitors.answered, unanswered=visitors.unanswered, arrived=visitors.arrived,
                       cycles=cycles)
        if progress is not None:
            progress(f"{settings.title}: {DAYS[tally.day % 7]} {tally.hour:02d}h rehearsed ({len(rows)} of "
                     f"{hours_open} opening hours)")

    snapshot = session.snapshot()
    down_until = -math.inf
    for a, b in spans:
        state["span"] = (a, b)
        clock.advance_to(a)
        session.world.emit("resumed", by="schedule", forgotten=session.world.forget(a))
        visitors.open(a)
        steps = int(math.ceil((b - a) / tick - 1e-9))
        for step in range(1, steps + 1):
            t0, t = a + (step - 1) * tick, min(a + step * tick, b)
            hour = int(t0 // 3600)
            if tally is None or tally.hour != hour % 24 or tally.day != hour // 24:
                if tally is not None:
                    close_hour()
                tally = HourTally(hour // 24, hour % 24, names)
                snapshot = session.snapshot()
            if not tally.open or tally.open[-1][1] != t0:
                tally.open.append((t0, t))
            else:
                tally.open[-1] = (tally.open[-1][0], t)
            clock.advance_to(t)
            if t <= down_until:
                continue
            for start, phrase in visitors.play(t0, t):
                for note in phrase.notes:
                    at, on = round(start + note.time, 6), note_on(note)
                    if any(route.matches_midi("note", on) for route in session.inputs.midi_routes):
                        off = mido.Message("note_off", channel=on.channel, note=on.note, velocity=0)
                        for row in (Row(at, "midi", tuple(on.bytes())),
                                    Row(at + note.duration, "midi", tuple(off.bytes()))):
                            bisect.insort(pads.rows, row, lo=pads.next, key=_row_time)
                    else:
                        session.world.inject(dataclasses.replace(note, time=at))
                if ears is not None:
                    ears.add(start, phrase)
            pads.poll(t)
            x0, x1 = int(round(t0 * sr)), int(round(t * sr))
            try:
                session.step(t, x1 - x0, ears.block(x0, x1) if ears is not None else None, audio=False)
            except Exception as exc:  # a supervisor's catch: the colony is rebuilt, the hour is lost
                tally.crashed = True
                crashes.append(f"day {hour // 24 + 1} {hour % 24:02d}h: {type(exc).__name__}: {exc}")
                session = _rebuilt(inst, clock, log, snapshot)
                pads.router = session.inputs
                boredom = _boredom(session) if boredom else boredom
                down_until = (hour + 1) * 3600.0
                continue
            for motivation, swings in boredom:
                swings.update(motivation.level("boredom", t))
        state["open_before"] += b - a
        visitors.close(b)
        session.scheduler.all_notes_off()
        session.world.emit("paused", by="schedule")
    if tally is not None:
        close_hour()
    for who in names:  # the silence after its last act, to the last closing
        longest[who] = max(longest[who], state["open_before"] - last[who])
    session.close()
    return Rehearsal(settings.title, days, tick, rows, longest, max(per_day.values(), default=0.0),
                     visitors.arrived, crashes, time.perf_counter() - wall0)


def _rebuilt(inst: LoadedInstallation, clock: SimulatedClock, log: EventLog, snapshot: list[tuple[str, str]]) -> Session:
    """A fresh colony that knows what the crashed one knew at the start of its hour."""
    session = Session(inst, clock, log, CountingSink())
    with tempfile.TemporaryDirectory() as folder:
        write_snapshot(Path(folder), snapshot)
        session.load_state(Path(folder))
    return session


# -- the report --------------------------------------------------------------------------------
COLUMNS = (("acts/min", "acts_per_minute", "{:.1f}"), ("silence", "silence", "{:.2f}"),
           ("repeat", "repetition", "{:.2f}"), ("pc bits", "pitch_entropy", "{:.2f}"),
           ("answered", "answer_rate", "{:.2f}"), ("boredom", "boredom_cycles", "{}"))
"""The per-hour measures, as the report heads and prints them."""


def _cell(row: HourMeasures | None, key: str, form: str) -> str:
    value = None if row is None else getattr(row, key)
    return "-" if value is None else form.format(value)


def _span(seconds: float) -> str:
    """A silence as read at a glance: seconds under a minute (``0 min`` hid 40 s), else minutes."""
    return f"{seconds:.0f} s" if seconds < 60 else f"{seconds / 60:.0f} min"


def _summary(r: Rehearsal) -> list[str]:
    silent = ", ".join(f"{who} {_span(s)}" for who, s in r.longest_silence.items())
    return [f"{r.title}: {r.days} days, {len(r.hours)} opening hours, tick {r.tick:g} s, {r.visitors} visitors, "
            f"{r.crash_free} of {len(r.hours)} hours crash-free, {r.open_seconds / max(r.wall, 1e-9):.0f}x real time",
            f"  longest silence of each creature (open time; an opening day is {r.opening_day / 60:.0f} min): {silent}",
            *(f"  crash: {c}" for c in r.crashes)]


def report(first: Rehearsal, other: Rehearsal | None = None) -> str:
    """The per-hour table of one rehearsal, or of two side by side (``a | b`` in each column)."""
    lines = _summary(first) + (_summary(other) if other is not None else [])
    width = 9 if other is None else 15
    lines.append("day  hour  " + "".join(f"{head:>{width}}" for head, _, _ in COLUMNS) + "  crash")
    keyed = {(h.day, h.hour): h for h in first.hours}
    others = {(h.day, h.hour): h for h in other.hours} if other is not None else {}
    for key in sorted(set(keyed) | set(others)):
        a, b = keyed.get(key), others.get(key)
        cells = []
        for _, name, form in COLUMNS:
            cell = _cell(a, name, form) if other is None else f"{_cell(a, name, form)} | {_cell(b, name, form)}"
            cells.append(f"{cell:>{width}}")
        crashed = any(h is not None and h.crashed for h in (a, b))
        lines.append(f"{DAYS[key[0] % 7]}  {key[1]:02d}h   " + "".join(cells) + ("  yes" if crashed else "  -"))
    return "\n".join(lines)
