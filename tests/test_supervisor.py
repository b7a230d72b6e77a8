"""The supervisor runs blocking jobs off the creature's thread; a wake runs one at once."""

from __future__ import annotations

import threading
import time

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


def test_a_job_that_never_returns_makes_the_health_status_stuck(monkeypatch):
    """A job that never returns (PortAudio stopping a stream whose JACK server died was one):
    the supervisor's thread then runs nothing else (no saves, no log flush, no heartbeat) while
    the ticks go on, and /health said "running" with 200. Now it says "stuck", naming the job,
    with 503."""
    import json
    import urllib.error
    import urllib.request

    from creatures.runtime import health as health_module
    from creatures.runtime.health import Health, HealthServer

    monkeypatch.setattr(health_module, "STUCK", 0.2)
    release, entered = threading.Event(), threading.Event()

    def hangs() -> None:
        entered.set()
        release.wait(10.0)

    supervisor = Supervisor("test-supervisor")
    health = Health(supervisor)
    server = HealthServer(health, "127.0.0.1", 0)
    try:
        with supervisor:
            health.publish(ticks=1)
            assert health.status()["state"] == "running" and supervisor.stuck(0.0) is None
            supervisor.every(3600.0, hangs, name="audio output (default)").wake()
            assert entered.wait(5.0)
            deadline = time.monotonic() + 5.0
            while health.status()["state"] != "stuck" and time.monotonic() < deadline:
                health.publish(ticks=2)  # the creatures' thread goes on publishing
                time.sleep(0.05)
            health.publish(ticks=3)
            with pytest.raises(urllib.error.HTTPError) as answer:
                urllib.request.urlopen(f"http://127.0.0.1:{server.port}/health", timeout=5)
            assert answer.value.code == 503
            status = json.loads(answer.value.read())
            assert status["state"] == "stuck" and status["stuck"]["job"] == "audio output (default)"
            release.set()
            deadline = time.monotonic() + 5.0
            while supervisor.busy is not None and time.monotonic() < deadline:
                time.sleep(0.01)
            assert health.status()["state"] == "running"
    finally:
        release.set()
        server.close()
