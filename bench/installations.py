"""Offline speed of the shipped installations: simulated seconds per wall second.

The issue's target is ≥ 20× real time for *exchange* with 3 creatures (MIDI, WAV and the
events log written; report and frames off, as they are optional and measured elsewhere).
The other shipped installations are measured too, without a target.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import installations
from bench import Row
from creatures.runtime.offline import run_offline
from creatures.runtime.schema import load_installation


def speed(name: str, seconds: float) -> float:
    inst = load_installation(installations.path(name))
    inst.settings.output.report = False
    inst.settings.output.frames = False
    with tempfile.TemporaryDirectory() as out:
        run_offline(inst, Path(out), duration=min(2.0, seconds))  # warm caches and JIT
        return run_offline(inst, Path(out), duration=seconds).speed


def run(quick: bool = False) -> list[Row]:
    seconds = 10.0 if quick else 60.0
    rows = [Row("exchange, 3 creatures, offline", speed("exchange", seconds), "× real time", target=20.0)]
    for name in installations.names():
        if name != "exchange":
            rows.append(Row(f"{name}, offline", speed(name, seconds), "× real time"))
    return rows
