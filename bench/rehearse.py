"""``creatures rehearse`` of exchange: how long a rehearsed gallery week takes on one core.

Issue 20's target: a week of exchange rehearsed in ≤ 30 min on one core. The week is the
rehearsal's default gallery (10:00–18:00, Tuesday to Sunday: 48 open hours) at exchange's
``[rehearse] tick``. Measuring it whole takes most of that half hour, longer than the whole
suite may (10 minutes), so the suite rehearses ``HOURS`` open hours of the same week and
projects the week from them (the colony's cold build once, then the hours): each open hour costs the same (the colony's state is bounded,
as bench/soak.py shows over a day, and the nights are skipped, not ticked). ``python -m bench
rehearse`` with ``REHEARSE_DAYS=6`` in the environment rehearses the whole week instead. Every
time here is this process's CPU time (one core), so the week is held to the target in CPU
seconds, not those of a shared machine's wall clock.

``REHEARSE_WEEK=all`` (or a comma-separated list of shipped installations) also rehearses each
one's whole gallery week (seven days, 48 open hours, its visitors at their default rate) at the
suite's rehearsal tick, 0.5 s, and reports each creature's longest silence in open time against
an opening day (issue 20: "no creature falls silent for more than an opening day"). The suite's
test does this with 5-minute days; a week of them all takes about an hour of CPU (README).
"""

from __future__ import annotations

import os
import time

import installations
from bench import Row
from creatures.clock import SimulatedClock
from creatures.events import EventLog
from creatures.runtime.rehearse import GALLERY, CountingSink, rehearse
from creatures.runtime.schema import ScheduleSection, load_installation
from creatures.runtime.session import Session

TARGET = 1800.0
"""Seconds a rehearsed week of exchange may take on one core (issue 20), held in CPU seconds."""

HOURS = 1
"""Open hours the suite rehearses (quick: a tenth of one)."""


def setup_cost(inst) -> float:
    """CPU seconds of building the colony once, cold (the motor material and graphs, which
    later colonies of the process share): paid once a rehearsal, not once an hour."""
    start = time.process_time()
    Session(inst, SimulatedClock(), EventLog(), CountingSink())
    return time.process_time() - start


WEEK_TICK = 0.5
"""The behaviour tick of a rehearsed week of every installation (tests/test_rehearse.py's)."""


def week_rows(names: list[str]) -> list[Row]:
    """Each named installation's gallery week: the longest silence of a creature that sounds
    (not one whose acts make no sound: installations.UNHEARD), as a
    fraction of the opening day, target ≤ 1, and the hours without a crash."""
    rows = []
    for name in names:
        inst = load_installation(installations.path(name))
        inst.settings.rehearse.hours = GALLERY
        inst.settings.rehearse.tick = WEEK_TICK
        start = time.process_time()
        r = rehearse(inst, 7)
        cpu = time.process_time() - start
        sounding = {who: s for who, s in r.longest_silence.items() if (name, who) not in installations.UNHEARD}
        who = max(sounding, key=sounding.get)
        rows.append(Row(f"{name}, a gallery week: longest silence ({who}, {sounding[who]:.0f} s) / opening day, "
                        f"{r.crash_free}/{len(r.hours)} hours crash-free, {cpu:.0f} s CPU",
                        sounding[who] / r.opening_day, "days", target=1.0, higher_is_better=False))
    return rows


def run(quick: bool = False) -> list[Row]:
    inst = load_installation(installations.path("exchange"))
    setup = setup_cost(inst)
    days = int(os.environ.get("REHEARSE_DAYS", "0"))
    week_hours = 8 * len(GALLERY.days)
    if days:
        inst.settings.rehearse.hours = GALLERY
        start = time.process_time()
        rehearsal = rehearse(inst, days + 1)  # Monday is closed: days open days follow it
        open_hours = rehearsal.open_seconds / 3600
    else:
        minutes = 6 if quick else 60 * HOURS
        inst.settings.rehearse.hours = ScheduleSection(days=["tue"], opens="10:00", closes=f"{10 + minutes // 60}:"
                                                                                       f"{minutes % 60:02d}")
        start = time.process_time()
        rehearsal = rehearse(inst, 2)
        open_hours = rehearsal.open_seconds / 3600
    cpu = time.process_time() - start
    week = setup + cpu / open_hours * week_hours
    chosen = os.environ.get("REHEARSE_WEEK", "")
    every = week_rows(installations.names() if chosen == "all" else [n for n in chosen.split(",") if n])
    return [Row("exchange, building the colony (once a rehearsal), CPU", setup, "s"),
            Row(f"exchange, {open_hours:g} open h rehearsed (tick {rehearsal.tick:g} s), CPU", cpu, "s"),
            Row(f"exchange, a rehearsed gallery week ({week_hours} open h){'' if days else ', projected'}, CPU", week, "s",
                target=TARGET, higher_is_better=False)] + every
