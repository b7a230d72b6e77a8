"""``creatures check CONFIG``: what a show needs, looked at before it is left alone.

Each row is one thing a run would otherwise find out at the worst moment (the opening night,
a week in): the ports it binds free, the MIDI ports and audio device it names present, room on
the disk and the right to write in the state folder, an OpenGL platform when it draws bodies,
and a tick of the colony costing well under a tick on this machine (measured by running
simulated ticks of the very colony, after a rehearsal as a live run does).
"""

from __future__ import annotations

import os
import shutil
import tempfile
import time
from pathlib import Path
from typing import Callable

from creatures.clock import SimulatedClock
from creatures.events import EventLog
from creatures.paths import directory
from creatures.runtime.schema import LoadedInstallation
from creatures.runtime.session import Session
from midi.notes import NoteEvent
from midi.sinks import MemorySink

Row = tuple[str, bool, str]
"""What was checked, whether it passed, and what was found (or why it failed)."""

FREE_DISK = 200 * 1024 * 1024
"""Bytes a state folder's disk should have free: weeks of snapshots and events logs."""

BUDGET = 0.5
"""The share of a tick one simulated tick may take: the rest is headroom for a busy machine."""

TICKS = 100
"""Simulated ticks measured."""


def check(inst: LoadedInstallation, state: Path | None) -> list[Row]:
    """Every check, in order; none stops the others."""
    rows = [_guarded("ports free", lambda: _ports(inst))]
    rows += _midi(inst)
    if inst.settings.audio.output:
        rows.append(_guarded("audio output", lambda: _audio(inst)))
    if inst.settings.audio.input_device is not None:  # the microphone a listening piece hears through
        rows.append(_guarded("audio input", lambda: _audio(inst, "input")))
    rows += _state(state)
    if inst.settings.output.frames:
        rows.append(_guarded("OpenGL", _gl))
    rows.append(_guarded("tick budget", lambda: _budget(inst)))
    return rows


def _guarded(what: str, test: Callable[[], tuple[bool, str]]) -> Row:
    try:
        ok, detail = test()
    except Exception as exc:  # a check that raises has failed, and says why
        return what, False, str(exc)
    return what, ok, detail


def _ports(inst: LoadedInstallation) -> tuple[bool, str]:
    from creatures.runtime.live import check_before_running

    check_before_running(inst, state=None, log_path=None, pictures=None)  # raises naming the key
    return True, "OSC, console, health, shared room and stream ports can be bound"


def _midi(inst: LoadedInstallation) -> list[Row]:
    midi, rows = inst.settings.midi, []
    for what, name, ports in (("MIDI output", midi.output_port, "MidoOutputs"),
                              ("MIDI input", midi.input_port, "MidoInputs")):
        if name:
            def present(name: str = name, ports: str = ports) -> tuple[bool, str]:
                from midi import ports as backends  # MIDO_BACKEND's ports, as the run opens them

                try:
                    found = getattr(backends, ports)().names()
                except Exception as exc:  # no backend at all: its error names a C++ call, so say what to do
                    return False, f"{name!r}: MIDI ports cannot be listed ({exc}); {backends.BACKEND_HINT}"
                hit = [n for n in found if name in n]
                return bool(hit), f"{name!r}: " + (f"found {hit[0]!r}" if hit else f"absent (there are {found or 'none'})")

            rows.append(_guarded(what, present))
    return rows


def _audio(inst: LoadedInstallation, kind: str = "output") -> tuple[bool, str]:
    """The output device, or the microphone (``kind = "input"``): duncan's trainer, the
    soundcreatures' performer and every piece with ``[audio] input_device`` are heard through
    it, and a live run without it hears nothing (a silent piece, its absence said only in the
    run's log)."""
    from audio.device import AudioDeviceUnavailable, device_rate, find_device

    audio = inst.settings.audio
    if kind == "output":
        device = audio.output_device
    else:  # "default" is the system's microphone, as the live run opens it
        device = None if audio.input_device == "default" else audio.input_device
    rate = device_rate(device, kind=kind)
    if rate is None:
        try:  # why not, in the words a live run uses: PortAudio missing, no device at all, or the ones there are
            find_device(device, kind=kind)
        except AudioDeviceUnavailable as exc:
            return False, f"{device or 'default'}: {exc}"
    return rate is not None, f"{device or 'default'}: " + (f"{rate} Hz" if rate else f"no such {kind} device")


def _state(state: Path | None) -> list[Row]:
    if state is None:
        return [("state folder", False, "none: nothing learned would be kept (state = \"DIR\" or --state DIR)")]
    try:
        directory(state, "state folder")
    except OSError as exc:  # a file, or a link to nothing: a run would be refused
        return [("state folder", False, str(exc))]
    where = next(folder for folder in (state, *state.parents) if folder.exists())  # where a run makes it
    rows = []
    try:
        with tempfile.NamedTemporaryFile(dir=where, prefix=".check."):
            pass
        rows.append(("state folder", True, f"{state} writable"))
    except OSError as exc:
        rows.append(("state folder", False, f"{where}: cannot write ({exc.strerror or exc})"))
    try:
        free = shutil.disk_usage(where).free
        rows.append(("disk", free >= FREE_DISK, f"{free / 2**20:.0f} MB free at {where} (want {FREE_DISK / 2**20:.0f})"))
    except OSError as exc:
        rows.append(("disk", False, f"{where}: {exc}"))
    return rows


def _gl() -> tuple[bool, str]:
    from creatures.body.render import gl_platform

    return True, f"offscreen platform {gl_platform()}"


def _budget(inst: LoadedInstallation) -> tuple[bool, str]:
    from creatures.runtime.live import rehearse

    rehearse(inst)
    tick, sr = inst.settings.tick, inst.settings.audio.sample_rate
    # Twice, the first pass not counted: on a fresh install (numba's cache empty) a path the
    # rehearsal did not take compiles in its first call, one tick of ~7 s that made the mean
    # 77 ms (p99 11 ms) and failed the check, where a live run compiles during its own warm-up
    # and kept every tick (measured: exchange, 0 late ticks on a cold cache).
    for _ in range(2):
        clock = SimulatedClock()
        session = Session(inst, clock, EventLog(keep_in_memory=0), MemorySink())
        for i, pitch in enumerate((60, 64, 67, 72, 65, 62)):
            session.world.inject(NoteEvent(0.1 + 0.2 * i, pitch, 90, 0, 0.2))
        costs = []
        for step in range(1, TICKS + 1):
            clock.advance_to(step * tick)
            began = time.perf_counter()
            session.step(clock.now(), int(round(tick * sr)), None)
            costs.append(time.perf_counter() - began)
    costs.sort()
    mean, p99 = sum(costs) / len(costs), costs[int(0.99 * (len(costs) - 1))]
    return mean <= BUDGET * tick, (f"a tick costs {mean * 1e3:.2f} ms on average (p99 {p99 * 1e3:.2f} ms) of "
                                   f"{tick * 1e3:g} ms; want at most {BUDGET * tick * 1e3:g} ms (on {os.cpu_count()} cores)")


def table(rows: list[Row]) -> str:
    width = max(len(what) for what, _, _ in rows)
    return "\n".join(f"{what:<{width}}  {'ok  ' if ok else 'FAIL'}  {detail}" for what, ok, detail in rows)
