"""Peers measured in the same run: what a user would use instead, timed beside ours.

A ratio to a peer only means something when both sides run on the same machine at the same
moment, so each peer is run by the benchmark itself; where it is not installed the row says
so (:func:`skipped`) instead of carrying a number from elsewhere.
"""

from __future__ import annotations

import shutil
import subprocess
import tempfile
import time
from pathlib import Path

from bench import Row


def skipped(name: str, reason: str) -> Row:
    """A row for a peer that could not be measured: no number (NaN), the reason in its name."""
    return Row(f"{name}: skipped ({reason})", float("nan"), "")


CSOUND_STRING = """<CsoundSynthesizer>
<CsOptions>
-n -d -m0
</CsOptions>
<CsInstruments>
sr = {sample_rate}
ksmps = {ksmps}
nchnls = 1
0dbfs = 1
gimass ftgen 0, 0, {masses}, -7, {mass}, {masses}, {mass}
gistiff ftgen 0, 0, {masses}, -7, {stiffness}, {masses}, {stiffness}
gidamp ftgen 0, 0, {masses}, -7, {damp}, {masses}, {damp}
instr 1
ipoint ftgentmp 0, 0, {masses}, 10, 1
ivel ftgentmp 0, 0, {masses}, -7, 0, {masses}, 0
a1 scantable 0.5, p4, ipoint, gimass, gistiff, gidamp, ivel
out a1
endin
</CsInstruments>
<CsScore>
{score}
</CsScore>
</CsoundSynthesizer>
"""
"""Csound's ``scantable`` (Matt Gilliard's opcode, Opcodes/wave-terrain.c): a ring of masses
updated once per k-cycle — ``v ← (v + stiffness·Δx/(mass·kr))·damp``, ``x ← x + v/kr`` — and
read without interpolation at audio rate. Each instance gets its own position and velocity
tables (``ftgentmp``), since the opcode writes them in place; mass, stiffness and damping
tables are shared and only read."""


def csound_string_seconds(*, voices: int, seconds: float, masses: int, sample_rate: int, haptic_rate: int,
                          mass: float, stiffness: float, damp: float, repeat: int = 2) -> float | None:
    """Wall time Csound takes to render ``voices`` ``scantable`` strings for ``seconds``
    (``csound -n``: no sound file written), less the time of the same orchestra with an empty
    score of the same length (start-up, table set-up, the empty k-loop), best of ``repeat``.
    None when ``csound`` is not installed."""
    if shutil.which("csound") is None:
        return None
    ksmps = sample_rate // haptic_rate
    if ksmps * haptic_rate != sample_rate:
        raise ValueError(f"Csound updates the string once per k-cycle: {sample_rate} Hz / {haptic_rate} Hz must be whole")
    notes = "\n".join(f"i1 0 {seconds} {110.0 + 0.37 * k:.3f}" for k in range(voices))
    fields = dict(sample_rate=sample_rate, ksmps=ksmps, masses=masses, mass=mass, stiffness=stiffness, damp=damp)
    with tempfile.TemporaryDirectory() as tmp:
        full, empty = Path(tmp) / "strings.csd", Path(tmp) / "empty.csd"
        full.write_text(CSOUND_STRING.format(score=notes, **fields))
        empty.write_text(CSOUND_STRING.format(score=f"f0 {seconds}", **fields))
        return _best_run(full, repeat) - _best_run(empty, repeat)


def _best_run(csd: Path, repeat: int) -> float:
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        done = subprocess.run(["csound", str(csd)], capture_output=True, text=True)
        elapsed = time.perf_counter() - t0
        if done.returncode != 0:
            raise RuntimeError(f"csound failed on {csd.name}: {done.stderr.strip().splitlines()[-3:]}")
        best = min(best, elapsed)
    return best
