"""A thread beside the creature's that does what may block: device checks, file flushes.

Listing JACK's MIDI ports opens a JACK client each time; under load one listing took ~2.5 s,
and done on the creature's thread once a second it cost a live run four of every five ticks
(issue 14). Whatever can block — port discovery, reconnect checks, device listing, flushing
the events log — is a *job* here instead: each runs every ``interval`` seconds on the
supervisor's own thread, or at once when the creature's thread :meth:`Job.wake` s it (a send
that failed is the signal to look again). The creature's thread only reads what a job leaves
behind (an attribute swap is atomic in Python), never waits for one.

Without :meth:`Supervisor.start` nothing runs on its own and :meth:`Supervisor.run_due`
runs the jobs that are due on the caller's thread: what tests on a simulated clock use.
"""

from __future__ import annotations

import logging
import threading
import time
from typing import Callable

logger = logging.getLogger(__name__)


class Job:
    """One recurring piece of blocking work; see :meth:`Supervisor.every`."""

    def __init__(self, supervisor: Supervisor, interval: float, work: Callable[[], None], name: str) -> None:
        self.supervisor = supervisor
        self.interval = interval
        self.work = work
        self.name = name
        self.next = 0.0  # monotonic time it is due (0: at once)
        self.runs = 0

    def wake(self) -> None:
        """Run soon (never on the caller's thread when the supervisor is started)."""
        self.next = 0.0
        self.supervisor._wakeup.set()

    def cancel(self) -> None:
        with self.supervisor._lock:
            if self in self.supervisor.jobs:
                self.supervisor.jobs.remove(self)


class Supervisor:
    """Runs :class:`Job` s on one daemon thread (after :meth:`start`) until :meth:`stop`."""

    def __init__(self, name: str = "creatures-supervisor", *, now: Callable[[], float] = time.monotonic) -> None:
        self.name = name
        self.now = now
        self.jobs: list[Job] = []
        self.failures = 0  # jobs that raised (logged; the job runs again at its next time)
        self.busy: tuple[str, float] | None = None  # (job, monotonic start) while one runs
        self._lock = threading.Lock()
        self._wakeup = threading.Event()
        self._stopping = False
        self._thread: threading.Thread | None = None

    @property
    def running(self) -> bool:
        return self._thread is not None

    def every(self, interval: float, work: Callable[[], None], *, name: str = "") -> Job:
        """Run ``work()`` every ``interval`` seconds (first after ``interval``)."""
        if not interval > 0:
            raise ValueError(f"a job's interval must be > 0, got {interval!r}")
        job = Job(self, interval, work, name or getattr(work, "__qualname__", "job"))
        job.next = self.now() + interval
        with self._lock:
            self.jobs.append(job)
        self._wakeup.set()
        return job

    def run_due(self) -> int:
        """Run every job that is due, on the calling thread; returns how many ran."""
        now = self.now()
        with self._lock:
            due = [job for job in self.jobs if job.next <= now]
        for job in due:
            job.next = now + job.interval
            self.busy = (job.name, time.monotonic())
            try:
                job.work()
            except Exception:  # a job's failure must not end the supervision of the others
                self.failures += 1
                logger.exception("supervised job %s failed", job.name)
            finally:
                self.busy = None
            job.runs += 1
        return len(due)

    def stuck(self, longer_than: float) -> tuple[str, float] | None:
        """``(job name, seconds)`` when the job running now has run longer than ``longer_than``
        seconds (a backstop for a call that never returns: PortAudio stopping a stream whose
        JACK server died was one, before audio/resilient.py gave it a thread and a time limit),
        else None. Every other job (state saves, the log's flush, device checks, the heartbeat)
        waits behind it, so a run whose supervisor is stuck is not well however its ticks go."""
        busy = self.busy
        if busy is None:
            return None
        seconds = time.monotonic() - busy[1]
        return (busy[0], seconds) if seconds > longer_than else None

    def start(self) -> Supervisor:
        if self._thread is None:
            self._stopping = False
            self._thread = threading.Thread(target=self._loop, name=self.name, daemon=True)
            self._thread.start()
        return self

    def stop(self, timeout: float = 5.0) -> None:
        """Let the thread finish the job it is in (bounded by ``timeout``) and end."""
        thread, self._thread = self._thread, None
        if thread is not None:
            self._stopping = True
            self._wakeup.set()
            thread.join(timeout)

    def _loop(self) -> None:
        while not self._stopping:
            self._wakeup.clear()  # before running: a wake during the jobs is kept for the wait
            self.run_due()
            with self._lock:
                soonest = min((job.next for job in self.jobs), default=self.now() + 1.0)
            self._wakeup.wait(max(0.0, soonest - self.now()))

    def __enter__(self) -> Supervisor:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()
