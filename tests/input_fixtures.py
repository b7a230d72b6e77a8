"""The colony the input-map tests feed: ``bo`` hears outside input, ``deaf`` (``hears_input =
false``) only other creatures; both are exchange creatures, with drives and an action-group.
And :func:`live_run`: ``creatures run`` in a subprocess, fed by foreign OSC senders."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
from pathlib import Path
from typing import Callable

import pytest
from pythonosc.osc_message_builder import OscMessageBuilder

COLONY = """
title = "input map"
tick = 0.02
[[creature]]
name = "bo"
kind = "exchange"
[[creature]]
name = "deaf"
kind = "exchange"
channel = 1
hears_input = false
"""


def all_read(port: int) -> None:
    """Return once the run listening on ``port`` has read everything sent to it before: a
    hello from a socket of our own, which it answers with an ask (:mod:`midi.peer_table`) once
    read. (Waiting for the line of an unmapped ``/done`` no longer does: unmapped addresses
    share one log line per 10 s.) The name is long so that the hello outweighs the ask."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as ear:
        ear.bind(("127.0.0.1", 0))
        ear.settimeout(60.0)
        hello = OscMessageBuilder("/creature/everything-sent-before-this-was-read/hello")
        hello.add_arg(ear.getsockname()[1], "i")
        ear.sendto(hello.build().dgram, ("127.0.0.1", port))
        assert b"/ask\x00" in ear.recv(1024)


def live_run(config: Path, log: Path, port: int, send: Callable[[], None]) -> tuple[list[str], str]:
    """``creatures run config --log log``; once it says it runs, ``send()``, then liblo's
    ``oscsend`` of the unmapped ``/done`` and :func:`all_read`; then SIGTERM. Returns the lines
    read while it ran and the rest of its output (it must exit 0)."""
    run = subprocess.Popen([sys.executable, "-m", "creatures.cli", "run", str(config), "--log", str(log)],
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                           env={**os.environ, "PYTHONUNBUFFERED": "1"})
    try:
        lines = []
        for line in run.stdout:  # the loop is listening once it says it runs
            lines.append(line)
            if "running; Ctrl-C or SIGTERM" in line:
                break
        else:
            pytest.fail("".join(lines))
        send()
        subprocess.run(["oscsend", "127.0.0.1", str(port), "/done"], check=True, timeout=30)
        all_read(port)
        run.send_signal(signal.SIGTERM)
        out = run.communicate(timeout=60)[0]
    finally:
        run.kill()
    assert run.returncode == 0, "".join(lines) + out
    return lines, out
