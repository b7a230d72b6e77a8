"""Opening hours (``[schedule]``): the colony sleeps while the gallery is closed.

Asleep, the creatures are paused as the console pauses them (creatures/runtime/live.py): no
tick of behaviour, so no selection and no learning, every note off, silence to the device; the
process, its devices and its learned state stay, so waking is instant and the colony goes on
from what it knew. The notes heard while asleep are forgotten on waking (the past, not a burst
to answer). Hours are the wall clock's in ``timezone`` (default: the machine's own).
"""

from __future__ import annotations

from datetime import datetime, time, tzinfo
from typing import Callable
from zoneinfo import ZoneInfo

DAYS = ("mon", "tue", "wed", "thu", "fri", "sat", "sun")


def clock_time(text: str) -> time:
    """``"HH:MM"`` (``"24:00"`` is the end of the day)."""
    hours, _, minutes = text.partition(":")
    if not (hours.isdigit() and minutes.isdigit() and len(minutes) == 2):
        raise ValueError(f"{text!r} is not a time of day HH:MM")
    h, m = int(hours), int(minutes)
    if (h, m) == (24, 0):
        return time.max
    return time(h, m)  # raises for 25:00 or 10:61


class OpeningHours:
    """Open on ``days`` from ``opens`` to ``closes``; ``closes`` before ``opens`` runs past
    midnight (a night opening belongs to the day it opened)."""

    def __init__(self, days: list[str], opens: str, closes: str, zone: str | None = None) -> None:
        self.days = {DAYS.index(d) for d in days}
        self.opens, self.closes = clock_time(opens), clock_time(closes)
        self.zone: tzinfo | None = ZoneInfo(zone) if zone else None

    def is_open(self, when: datetime) -> bool:
        local = when.astimezone(self.zone)
        now, day = local.time(), local.weekday()
        if self.opens <= self.closes:
            return day in self.days and self.opens <= now < self.closes
        return (day in self.days and now >= self.opens) or ((day - 1) % 7 in self.days and now < self.closes)


class Schedule:
    """Sends the colony to sleep and wakes it as the hours turn; :meth:`poll` is called from the
    tick loop's housekeeping, with the time from ``now`` (the wall clock live, a simulated one
    in tests)."""

    def __init__(self, hours: OpeningHours, sleep: Callable[[bool], None], now: Callable[[], datetime]) -> None:
        self.hours, self.sleep, self.now = hours, sleep, now
        self.asleep = False
        self.closings = self.openings = 0

    def poll(self) -> bool | None:
        """Apply the hours now; returns True when it just closed, False when it just opened."""
        closed = not self.hours.is_open(self.now())
        if closed == self.asleep:
            return None
        self.asleep = closed
        self.sleep(closed)
        if closed:
            self.closings += 1
        else:
            self.openings += 1
        return closed
