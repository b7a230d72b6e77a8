"""Two colonies of framework creatures, each a ``creatures run`` process, exchange notes and
state over OSC on 127.0.0.1; one is killed (SIGKILL) and restarted, and the other keeps
running and hears the new one. No audio or MIDI device is needed."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path
from typing import Callable

STONE = """
title = "stone colony"
tick = 0.02
[audio]
output_device = "NoSuchCard"
[osc]
port = {port}
peers = ["127.0.0.1:{peer}"]
[[creature]]
name = "stone"
kind = "sandstone"
drives.desire.inputs."eager presence" = 5.0  # sings at once
drives.desire.inputs.discord = 0.0  # and is not silenced by what it hears back
"""

ECHO = """
title = "echo colony"
tick = 0.02
[audio]
output_device = "NoSuchCard"
[osc]
port = {port}
peers = ["127.0.0.1:{peer}"]
[[creature]]
name = "echo"
kind = "exchange"
space.answer = 1.0  # strikes what it hears where it lands
space.strike_interval = 0.05
space.refractory = 0.5
"""


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Colony:
    """A ``creatures run`` process and its events log (flushed by the run every second)."""

    def __init__(self, config: Path, log: Path) -> None:
        self.log = log
        self.process = subprocess.Popen(
            [sys.executable, "-m", "creatures.cli", "run", str(config), "--duration", "300", "--log", str(log)],
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
            env={**os.environ, "PYTHONUNBUFFERED": "1"},
        )
        self.seen = 0  # events already looked at by expect()

    def events(self) -> list[dict]:
        if not self.log.exists():
            return []
        lines = self.log.read_text().split("\n")[:-1]  # a half-written last line is not an event yet
        return [json.loads(line) for line in lines]

    def expect(self, match: Callable[[dict], bool], timeout: float = 90.0, *, anywhere: bool = False) -> dict:
        """The first event after those already seen (``anywhere``: in the whole log, leaving
        what counts as seen alone) that matches, within ``timeout`` seconds."""
        deadline = time.monotonic() + timeout
        while True:
            events = self.events()
            for i in range(0 if anywhere else self.seen, len(events)):
                if match(events[i]):
                    self.seen = self.seen if anywhere else i + 1
                    return events[i]
            if time.monotonic() > deadline or self.process.poll() is not None:
                raise AssertionError(f"no matching event in {self.log.name} within {timeout} s "
                                     f"(exit code {self.process.poll()}): {self.stop()[-2000:]}")
            time.sleep(0.05)  # the log is flushed once a second; the deadline bounds the wait

    def skip_past(self) -> None:
        """Look only at what comes after now."""
        self.seen = len(self.events())

    def stop(self) -> str:
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGTERM)
        try:
            return self.process.communicate(timeout=60)[0] or ""
        except subprocess.TimeoutExpired:
            self.process.kill()
            return self.process.communicate()[0] or ""


def heard_from(name: str) -> Callable[[dict], bool]:
    return lambda e: e["kind"] == "heard" and e["source"] == name


def state_of(name: str, key: str) -> Callable[[dict], bool]:
    return lambda e: e["kind"] == "peer state" and e["creature"] == name and key in e["state"]


def test_two_colonies_exchange_notes_and_state_and_survive_a_restart(tmp_path):
    port_stone, port_echo = free_port(), free_port()
    (tmp_path / "stone.toml").write_text(STONE.format(port=port_stone, peer=port_echo))
    (tmp_path / "echo.toml").write_text(ECHO.format(port=port_echo, peer=port_stone))
    stone = Colony(tmp_path / "stone.toml", tmp_path / "stone.jsonl")
    echo = Colony(tmp_path / "echo.toml", tmp_path / "echo.jsonl")
    try:
        # stone sings; echo hears it over OSC, places each note in space and strikes it; stone
        # hears echo's answers. Each sees the other's drives and current action.
        sung = echo.expect(heard_from("stone"))
        echo.expect(lambda e: e["kind"] == "placed" and e["source"] == "stone")
        echo.expect(state_of("stone", "desire"))
        # What stone hears from echo is a note of stone's that echo placed (at the heard pitch,
        # or moved in its note space) and struck. Stone is echo's only sender; its notes that
        # arrived before its first hello was taken in are placed as outside input ("input",
        # creatures/runtime/network.py), the rest as "stone" (checked above).
        answer = stone.expect(heard_from("echo"))
        placed = echo.expect(lambda e: e["kind"] == "placed" and e["pitch"] == answer["pitch"], anywhere=True)
        assert placed["source"] in ("stone", "input")
        assert placed["heard"] in {e["pitch"] for e in stone.events() if e["kind"] == "note"} | {sung["pitch"]}
        seen = stone.expect(state_of("echo", "boredom"))
        assert isinstance(seen["state"]["boredom"], float) and "action" in seen["state"]

        echo.process.kill()  # SIGKILL: no bye, no clean exit
        echo.process.wait(timeout=30)
        stone.skip_past()
        echo = Colony(tmp_path / "echo.toml", tmp_path / "echo-restarted.jsonl")
        stone.expect(heard_from("echo"))  # stone kept running and hears the new echo
        echo.expect(heard_from("stone"))
        assert stone.process.poll() is None
    finally:
        echo_out, stone_out = echo.stop(), stone.stop()
    assert stone.process.returncode == 0 and "stopped after" in stone_out, stone_out
    assert echo.process.returncode == 0, echo_out
