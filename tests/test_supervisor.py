"""The supervisor runs blocking jobs off the creature's thread; a wake runs one at once."""

from __future__ import annotations

import threading

import pytest

from creatures.supervisor import Supervisor


def test_jobs_run_on_the_supervisor_thread_and_a_wake_runs_one_at_once():
    ran: list[str] = []
    woken = threading.Event()

    def look() -> None:
        ran.append(threading.current_thread().name)
        woken.set()

    with Supervisor("test-supervisor") as supervisor:
        job = supervisor.every(3600.0, look)  # not due for an hour ...
        job.wake()  # ... but a failed send wants it now
        assert woken.wait(5.0)
    assert ran == ["test-supervisor"]


def test_unstarted_jobs_run_when_due_on_the_callers_thread_and_failures_are_counted():
    now = [0.0]
    supervisor = Supervisor(now=lambda: now[0])
    calls: list[float] = []
    supervisor.every(1.0, lambda: calls.append(now[0]))
    supervisor.every(1.0, lambda: 1 / 0)
    assert supervisor.run_due() == 0
    now[0] = 1.0
    assert supervisor.run_due() == 2 and calls == [1.0] and supervisor.failures == 1
    now[0] = 1.5
    assert supervisor.run_due() == 0
    with pytest.raises(ValueError):
        supervisor.every(0.0, lambda: None)
