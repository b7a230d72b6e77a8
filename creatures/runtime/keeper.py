"""Keeping a show running unattended: a systemd unit, and a supervisor that restarts a crash.

``creatures run CONFIG --supervise`` runs the colony as a child process and starts it again
when it dies by a signal or a failure (a clean stop — Ctrl-C, SIGTERM, ``--duration`` reached —
ends it). The child restores the learned state its last periodic save left in the state folder
(``save_every``), so a crash loses at most that many seconds of learning. Restarts come
:data:`RESTART_AFTER` seconds apart, slowing to :data:`SLOWEST` when the run keeps dying at
once. A run refused before it began — exit code :data:`REFUSED`, a config or a state file
that does not load, already said why — is not restarted: the same files would be refused
again, and a gallery machine would say so every half minute for as long as no one looks.
A run that ends with :data:`AFRESH` asks for a new process (its audio device cannot come back
in this one: audio/resilient.py) and is restarted like a crash.
Under systemd the unit that ``creatures service`` writes lets systemd do the restarting
instead (``Restart=on-failure``, ``RestartPreventExitStatus`` the same code) and adds its
watchdog (creatures/runtime/sd_notify.py).
"""

from __future__ import annotations

import shlex
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Callable

from creatures.paths import UnsafePathError, read_regular, regular_file
from creatures.persist import write_json_text
from creatures.stop import STOPPING, hung_up, named

RESTART_AFTER = 1.0
"""Seconds between a crash and the restart."""

SLOWEST = 30.0
"""Longest wait between restarts of a run that keeps dying within :data:`STEADY` seconds."""

STEADY = 60.0
"""A run that lived this long was healthy: the next crash restarts it at once again."""

REFUSED = 2
"""The exit code of a run refused before it began (a config or state that does not load)."""

AFRESH = 75
"""The exit code of a run that saved and stopped to be started afresh: PortAudio could not let
go of a stream whose JACK server died, and no stream can open in that process after it
(``EX_TEMPFAIL``: systemd's ``Restart=on-failure`` restarts it too)."""


def supervise(command: list[str], say: Callable[[str], None] = print, *,
              launch: Callable[[list[str]], subprocess.Popen[bytes]] = subprocess.Popen) -> int:
    """Run ``command`` until it ends cleanly; returns its last exit code. SIGTERM, SIGINT and
    SIGHUP are passed to the child, which then saves and stops as it would alone (a SIGHUP the
    keeper died of left its child running, holding the state folder's lock). A stop that comes
    while no child runs (the wait before a restart, up to :data:`SLOWEST` seconds) ends the wait
    and the keeper, exit code ``128 + signal``: it went on to start a new child, which ran on
    with no one left to stop it but a second signal."""
    stopped = threading.Event()
    asked: list[int] = []
    child: subprocess.Popen[bytes] | None = None

    def forward(signum: int, _: object) -> None:
        asked.append(signum)
        stopped.set()
        hung_up(signum)
        if child is not None and child.poll() is None:
            child.send_signal(signum)

    previous = {s: signal.signal(s, forward) for s in STOPPING}
    wait, restarts = RESTART_AFTER, 0
    try:
        while True:
            began = time.monotonic()
            child = launch(command)
            if asked and child.poll() is None:  # the stop came while it was being started
                child.send_signal(asked[0])
            code = child.wait()
            if asked or code == 0 or code - 128 in STOPPING:
                return code
            if code == REFUSED:
                say("creatures: the run was refused before it began (above: why); not restarting, since the "
                    "same files would be refused again: fix them and start it again")
                return code
            if time.monotonic() - began > STEADY:
                wait = RESTART_AFTER
            elif restarts:
                wait = min(wait * 2, SLOWEST)
            restarts += 1
            why = (f"killed by {signal.Signals(-code).name}" if code < 0 else "to be started afresh, its audio device "
                   "lost for that process" if code == AFRESH else f"exit code {code}")
            say(f"creatures: the run stopped ({why}); restart {restarts} in {wait:g} s")
            if stopped.wait(wait):
                say(f"creatures: {named(asked[0])} before the restart: not restarting")
                return 128 + asked[0]
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)


def unit(config: Path, state: Path | None, *, watchdog: float, python: str = sys.executable) -> str:
    """A systemd service unit running ``config`` (``Type=notify``: started once the first tick
    has played; restarted on failure and when the watchdog hears nothing for ``watchdog`` s)."""
    command = [python, "-m", "creatures.cli", "run", str(config.resolve())]
    if state is not None:
        command += ["--state", str(state.resolve())]
    return "\n".join([
        "[Unit]",
        f"Description=creature-music: {config.stem}",
        "After=network.target sound.target",
        "StartLimitIntervalSec=0",
        "",
        "[Service]",
        "Type=notify",
        "NotifyAccess=main",
        f"ExecStart={shlex.join(command)}",
        f"WorkingDirectory={config.resolve().parent}",
        "Restart=on-failure",
        f"RestartPreventExitStatus={REFUSED}",
        f"RestartSec={RESTART_AFTER:g}",
        f"WatchdogSec={watchdog:g}",
        "TimeoutStopSec=30",
        "KillSignal=SIGTERM",
        "",
        "[Install]",
        "WantedBy=default.target",
        "",
    ])


WRITTEN_HERE = "[Unit]\nDescription=creature-music: "
"""How every unit :func:`unit` writes begins: one that does is this command's to replace."""


def write_unit(path: Path, text: str) -> None:
    """Write the unit ``text`` to ``path`` atomically. A file already there is replaced only if
    it is a unit this command wrote: ``creatures service show.toml --out show.toml`` (a slip of
    the hand) wrote the unit over the installation's config, which was gone. Anything else
    there is a :class:`FileExistsError` naming it, and nothing is written."""
    regular_file(path, "--out")
    try:
        there = read_regular(path, "--out", 64 * 1024)
    except FileNotFoundError:
        there = None
    except UnsafePathError:  # larger than any unit
        there = b""
    if there is not None and not there.startswith(WRITTEN_HERE.encode()):
        raise FileExistsError(f"--out {path}: holds a file that is not a unit `creatures service` wrote; not "
                              "replaced (nothing written): choose another --out, or move that file away")
    write_json_text(path, text)

