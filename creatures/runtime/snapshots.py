"""Dated snapshots of a colony's learned state, kept by a retention rule (``[snapshots]``).

A show left running for weeks keeps only its latest state in the state folder: what the
creatures knew last Tuesday is gone. Every ``every`` seconds of the run's clock a live run also
copies the state it has just saved into ``STATE/snapshots/<UTC stamp>/`` (the same JSON files,
so `creatures state diff/rollback/merge` read them as they read a state folder). A snapshot is
written into a hidden folder and renamed into place: one that exists is whole. The retention
rule keeps the newest snapshot of each of the last ``keep_daily`` days and of each of the last
``keep_weekly`` ISO weeks; the rest are removed, so a year of snapshots stays bounded.
"""

from __future__ import annotations

import shutil
from datetime import datetime, timezone
from pathlib import Path

from creatures.config import nearest
from creatures.persist import StateFileError, write_json_text

FOLDER = "snapshots"
STAMP = "%Y-%m-%dT%H%M%SZ"
"""A snapshot's folder name: its UTC time, sortable as text."""


def stamp_of(path: Path) -> datetime | None:
    """The time a snapshot folder was taken, or None for anything else in the folder."""
    try:
        return datetime.strptime(path.name, STAMP).replace(tzinfo=timezone.utc)
    except ValueError:
        return None


def refuse_to_change(folder: Path, what: str) -> None:
    """A :class:`StateFileError` when ``folder`` is a snapshot (``STATE/snapshots/<stamp>``):
    a snapshot is the colony as it was on that day, which a rollback reads back; a merge or a
    rollback written into one changed that history, with nothing said, and so did a live run
    given one as its ``--state`` (each save rewrote it)."""
    if folder.resolve().parent.name == FOLDER and stamp_of(folder.resolve()) is not None:
        raise StateFileError(f"{folder}: is a snapshot, kept as the colony was then; {what} the state folder "
                             f"({folder.resolve().parent.parent}), and its next snapshot keeps that (nothing changed; "
                             "to work from the snapshot itself, copy it into a folder of its own)")


def listed(state_dir: Path) -> list[tuple[datetime, Path]]:
    """The snapshots of ``state_dir``, oldest first."""
    root = state_dir / FOLDER
    if not root.is_dir():
        return []
    found = [(stamp_of(p), p) for p in root.iterdir() if p.is_dir()]
    return sorted((when, p) for when, p in found if when is not None)


def find(state_dir: Path, given: Path) -> Path:
    """The snapshot ``given`` names: a folder, else the one of that name in ``STATE/snapshots``.
    Neither is a :class:`StateFileError` that names the nearest snapshot (or lists them): a
    mistyped stamp said only "not a state folder or snapshot"."""
    if given.is_dir():
        return given
    named = state_dir / FOLDER / given
    if named.is_dir():
        return named
    names = [path.name for _, path in listed(state_dir)]
    raise StateFileError(f"{given}: no such snapshot (not a folder, nor a snapshot in {state_dir / FOLDER})"
                         f"{nearest(str(given), names, 'snapshots')}")


def take(state_dir: Path, files: list[tuple[str, str]], at: datetime) -> Path:
    """Write ``files`` (a :meth:`Session.snapshot`) as the snapshot taken at ``at``."""
    root = state_dir / FOLDER
    target = root / at.astimezone(timezone.utc).strftime(STAMP)
    hidden = root / f".{target.name}.partial"
    shutil.rmtree(hidden, ignore_errors=True)  # left by a run killed mid-snapshot
    hidden.mkdir(parents=True)
    for name, text in files:
        write_json_text(hidden / name, text)
    if target.exists():  # two snapshots in one second: the later one wins
        shutil.rmtree(target)
    hidden.rename(target)
    return target


def kept(stamps: list[datetime], *, daily: int, weekly: int) -> set[datetime]:
    """Which of ``stamps`` the rule keeps: the newest of each of the last ``daily`` days and of
    each of the last ``weekly`` ISO weeks that have snapshots, and always the newest of all."""
    keep: set[datetime] = set()
    for count, period in ((daily, lambda d: d.date()), (weekly, lambda d: d.isocalendar()[:2])):
        seen: set[object] = set()
        for when in sorted(stamps, reverse=True):
            key = period(when)
            if key not in seen and len(seen) < count:
                seen.add(key)
                keep.add(when)
    if stamps:
        keep.add(max(stamps))
    return keep


def prune(state_dir: Path, *, daily: int, weekly: int, now: datetime | None = None) -> list[Path]:
    """Remove the snapshots the rule does not keep; returns those removed. With ``now``, only
    those taken up to it are weighed: one stamped later was taken while the clock ran ahead,
    and as the newest of all it would be the one kept while each snapshot taken now went."""
    snaps = [(when, path) for when, path in listed(state_dir) if now is None or when <= now]
    keep = kept([when for when, _ in snaps], daily=daily, weekly=weekly)
    removed = [path for when, path in snaps if when not in keep]
    for path in removed:
        shutil.rmtree(path)
    return removed


class Snapshotter:
    """When the next snapshot falls due, on the run's clock: a restarted run goes on from the
    newest snapshot on disk rather than taking one at once."""

    def __init__(self, state_dir: Path, *, every: float, daily: int, weekly: int) -> None:
        self.state_dir, self.every, self.daily, self.weekly = state_dir, every, daily, weekly
        snaps = listed(state_dir)
        self.last: datetime | None = snaps[-1][0] if snaps else None

    def due(self, at: datetime) -> bool:
        """Whether a snapshot falls due at ``at``: ``every`` seconds after the last, or at once
        when the clock is behind the last (set back: counting from a snapshot stamped in the
        future, none would fall due until the clock reached it, years after a wrong RTC)."""
        return self.last is None or at < self.last or (at - self.last).total_seconds() >= self.every

    def take(self, files: list[tuple[str, str]], at: datetime) -> Path:
        """Take the snapshot and apply the retention rule."""
        path = take(self.state_dir, files, at)
        self.last = at
        prune(self.state_dir, daily=self.daily, weekly=self.weekly, now=at)
        return path
