"""Offline speed of the shipped installations: simulated seconds per wall second.

The issue's target is ≥ 20× real time for *exchange* with 3 creatures (MIDI, WAV and the
events log written; report and frames off, as they are optional and measured elsewhere).
Issue 22's pieces (the thesis's: (void*), curve, scribble, sand:stone with its statue,
ozymandias, listen's maps, three creatures beside a behaviour system) have the same target
"without frames", measured in this process's CPU seconds (one core; the shared machine's
other processes disturb it far less than the wall clock) — ozymandias with its image half
off, since that half *is* frames (a video walked from a frame graph; bench images). The other
shipped installations are measured too, without a target. exchange's creatures are
authored (installations/creatures/exchange.toml); the class they replaced was measured against
them here until it was removed (issue 15, target ≥ 0.9×: 0.98×, README "Authoring creatures").
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import installations
from bench import Row, best_of
from creatures.runtime.offline import run_offline
from creatures.runtime.schema import load_installation


PIECES = ("void", "curve", "scribble", "sandstone", "ozymandias", "listen_maps", "three_creatures_compared")
"""Issue 22's installations, each with the ≥ 20× target."""


def speed(name: str | Path, seconds: float, *, cpu: bool = False) -> float:
    """Simulated seconds per wall second (``cpu``: per second of this process's CPU time,
    which the other processes on a shared machine disturb far less, the best of three runs).
    Frames are off, and so is a creature's image half (its video is frames)."""
    inst = load_installation(name if isinstance(name, Path) else installations.path(name))
    inst.settings.output.report = False
    inst.settings.output.frames = False
    for spec in inst.specs:
        if getattr(spec, "images", None) is not None:
            spec.images = None
    with tempfile.TemporaryDirectory() as out:
        run_offline(inst, Path(out), duration=min(2.0, seconds))  # warm caches and JIT
        if cpu:  # the least disturbed of three runs, as the other benches time (best_of)
            return seconds / best_of(lambda: run_offline(inst, Path(out), duration=seconds), clock=time.process_time)
        return run_offline(inst, Path(out), duration=seconds).speed


def offline_speed(name: str, seconds: float, *, audio: bool) -> float:
    """A shipped installation's offline speed (best of two, wall clock), with or without its
    audio synthesis (out.wav): a piece's own bench measures both."""
    inst = load_installation(installations.path(name))
    inst.settings.output.report = False
    inst.settings.output.wav = audio
    with tempfile.TemporaryDirectory() as out:
        wall = best_of(lambda: run_offline(inst, Path(out), duration=seconds), repeat=2)
    return seconds / wall


def run(quick: bool = False) -> list[Row]:
    seconds = 10.0 if quick else 60.0
    rows = [Row("exchange, 3 creatures, offline", speed("exchange", seconds), "× real time", target=20.0)]
    for name in PIECES:
        rows.append(Row(f"{name}, offline, CPU time", speed(name, seconds, cpu=True), "× real time", target=20.0))
    for name in installations.names():
        if name != "exchange" and name not in PIECES:
            rows.append(Row(f"{name}, offline", speed(name, seconds), "× real time"))
    return rows
