"""Offline speed of the shipped installations: simulated seconds per wall second.

The issue's target is ≥ 20× real time for *exchange* with 3 creatures (MIDI, WAV and the
events log written; report and frames off, as they are optional and measured elsewhere).
The other shipped installations are measured too, without a target. exchange's creatures are
authored (installations/creatures/exchange.toml); the class they replaced was measured against
them here until it was removed (issue 15, target ≥ 0.9×: 0.98×, README "Authoring creatures").
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import installations
from bench import Row
from creatures.runtime.offline import run_offline
from creatures.runtime.schema import load_installation


def speed(name: str | Path, seconds: float, *, cpu: bool = False) -> float:
    """Simulated seconds per wall second (``cpu``: per second of this process's CPU time,
    which the other processes on a shared machine disturb far less)."""
    inst = load_installation(name if isinstance(name, Path) else installations.path(name))
    inst.settings.output.report = False
    inst.settings.output.frames = False
    with tempfile.TemporaryDirectory() as out:
        run_offline(inst, Path(out), duration=min(2.0, seconds))  # warm caches and JIT
        t0 = time.process_time()
        summary = run_offline(inst, Path(out), duration=seconds)
        return seconds / (time.process_time() - t0) if cpu else summary.speed


def run(quick: bool = False) -> list[Row]:
    seconds = 10.0 if quick else 60.0
    rows = [Row("exchange, 3 creatures, offline", speed("exchange", seconds), "× real time", target=20.0)]
    for name in installations.names():
        if name != "exchange":
            rows.append(Row(f"{name}, offline", speed(name, seconds), "× real time"))
    return rows
