"""Offline speed of the shipped installations: simulated seconds per wall second.

The issue's target is ≥ 20× real time for *exchange* with 3 creatures (MIDI, WAV and the
events log written; report and frames off, as they are optional and measured elsewhere).
The other shipped installations are measured too, without a target, and the same exchange
colony written as authored creatures (installations/authored/exchange.toml) against the class
(issue 15: ≥ 0.9× its speed, measured alternately in the same run).
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

import installations
from bench import Row
from creatures.runtime.offline import run_offline
from creatures.runtime.schema import load_installation


AUTHORED_EXCHANGE = Path(installations.__file__).parent / "authored" / "exchange.toml"


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
    rows = [Row("exchange, 3 creatures, offline", speed("exchange", seconds), "× real time", target=20.0),
            Row("authored exchange offline", speed(AUTHORED_EXCHANGE, seconds), "× real time", target=20.0)]
    # In pairs run back to back, by CPU time: load on the shared machine falls on both of a
    # pair alike; the median pair is the measure (single ratios ranged 0.76-1.28 by wall time).
    pairs = [speed(AUTHORED_EXCHANGE, seconds, cpu=True) / speed("exchange", seconds, cpu=True) for _ in range(5)]
    ratio = float(np.median(pairs))
    rows.append(Row("authored exchange offline vs class-based exchange (CPU, median of 5 pairs)", ratio, "×",
                    target=0.9, baseline="class exchange", ratio=ratio))
    for name in installations.names():
        if name != "exchange":
            rows.append(Row(f"{name}, offline", speed(name, seconds), "× real time"))
    return rows
