"""``creatures offline``: an installation on the simulated clock, as fast as the CPU allows.

The same creatures as a live run, fed recorded (or generated) audio and MIDI, writing
``out.mid``, ``out.wav``, ``frames/`` (and ``out.mp4``), ``events.jsonl`` and ``report/``.
Time advances in behaviour ticks; audio is produced in blocks that exactly cover each tick
(frame counts come from elapsed time, so rounding never drifts), and frames fall due on their
own clock.

Every output is written into a hidden staging directory inside the output directory and moved
into place only once the run has finished (renames within one file system are atomic): a run
that fails — disk full, a crash, Ctrl-C — leaves the previous run's outputs exactly as they
were, and a run that succeeds replaces them all, so the files beside each other are always
from one run.
"""

from __future__ import annotations

import contextlib
import math
import os
import shutil
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from audio.output import WavOutput
from audio.sources import load_audio
from audio.transcribe import OFFLINE_WINDOW
from creatures.clock import SimulatedClock
from creatures.events import EventLog
from creatures.runtime.bodies import BodyFrames
from creatures.runtime.inputs import phrase_notes, render_notes
from creatures.runtime.schema import LoadedInstallation
from creatures.runtime.speech_input import spoken_poem
from creatures.runtime.session import Session
from midi.files import read_notes, write_notes
from midi.notes import NoteEvent
from midi.sinks import MemorySink


class OutputDirectoryError(OSError):
    """The output directory cannot be created or written; nothing was run."""


@dataclass
class OfflineSummary:
    simulated: float
    wall: float
    notes_played: int
    files: dict[str, Path] = field(default_factory=dict)
    messages: list[str] = field(default_factory=list)

    @property
    def speed(self) -> float:
        """Simulated seconds per wall-clock second (× real time)."""
        return self.simulated / self.wall if self.wall > 0 else math.inf


STAGING = ".run-"
"""Prefix of the hidden directory inside the output directory that a run writes into."""


def _stage(out: Path) -> Path:
    """A fresh staging directory inside ``out`` (created if need be): where the run writes."""
    try:
        out.mkdir(parents=True, exist_ok=True)
        return Path(tempfile.mkdtemp(prefix=STAGING, dir=out))
    except OSError as exc:
        raise OutputDirectoryError(f"cannot write outputs to {out}: {exc.strerror or exc}") from None


def _publish(staged: Path, out: Path) -> None:
    """Move a finished run's outputs from ``staged`` into ``out``, replacing the previous
    run's: files by atomic rename, directories (frames, report) by removing the old first.
    The previous log's rotated parts go too, and so do staging directories left behind by
    runs that were killed (the same clean-up :func:`creatures.persist.atomic_write` does)."""
    for old in out.glob("events.jsonl.*"):
        if old.suffix[1:].isdigit() and not (staged / old.name).exists():
            old.unlink()
    for item in sorted(staged.iterdir()):
        target = out / item.name
        if target.is_dir() and not target.is_symlink():  # a directory cannot be renamed over
            shutil.rmtree(target)
        os.replace(item, target)
    staged.rmdir()
    for stale in out.glob(f"{STAGING}*"):
        shutil.rmtree(stale, ignore_errors=True)


def _inputs(inst: LoadedInstallation, audio: Path | None, midi: Path | None, duration: float,
            rng: np.random.Generator) -> tuple[list[NoteEvent], np.ndarray | None]:
    """Notes and mono audio to feed: the given files, the config's files, or generated."""
    settings = inst.settings
    sr = settings.audio.sample_rate
    audio = audio or inst.resolve(settings.input.audio)
    midi = midi or inst.resolve(settings.input.midi)
    notes = read_notes(midi) if midi is not None else []
    samples = load_audio(audio, samplerate=sr) if audio is not None else None
    if midi is None and audio is None and settings.input.generate == "phrase":
        notes = phrase_notes(rng=rng)
        samples = render_notes(notes, sr, duration)
    elif midi is None and audio is None and settings.input.generate == "speech":
        samples = spoken_poem(duration, sr, rng)
    return [n for n in notes if n.time < duration], samples


def run_offline(
    inst: LoadedInstallation,
    out: Path,
    *,
    audio: Path | None = None,
    midi: Path | None = None,
    duration: float | None = None,
    progress: bool = False,
) -> OfflineSummary:
    """Run ``inst`` on the simulated clock for ``duration`` seconds, writing into ``out``.

    Raises :class:`OutputDirectoryError` (before running) when ``out`` cannot be written;
    any failure during the run leaves the previous outputs in ``out`` untouched.
    """
    settings = inst.settings
    duration = float(duration if duration is not None else settings.duration)
    staged = _stage(out)
    try:
        summary = _run(inst, staged, audio=audio, midi=midi, duration=duration, progress=progress)
        _publish(staged, out)
    except BaseException:
        shutil.rmtree(staged, ignore_errors=True)
        raise
    summary.files = {name: out / path.relative_to(staged) for name, path in summary.files.items()}
    return summary


def _run(inst: LoadedInstallation, out: Path, *, audio: Path | None, midi: Path | None, duration: float,
         progress: bool) -> OfflineSummary:
    """The run itself, writing every output into ``out`` (the staging directory)."""
    settings = inst.settings
    wall0 = time.perf_counter()
    clock = SimulatedClock()
    sink = MemorySink()
    messages: list[str] = []
    log = EventLog(out / "events.jsonl")
    session = Session(inst, clock, log, sink)
    session.world.emit("run", title=settings.title, mode="offline", duration=duration, seed=settings.seed,
                       creatures=[c.name for c in session.creatures])
    notes, samples = _inputs(inst, audio, midi, duration, session.input_rng)
    for note in notes:
        session.world.inject(note)
    transcribe = settings.audio.transcribe
    session.transcribe = samples is not None and (transcribe if transcribe is not None else not notes)
    session.transcribe_window = OFFLINE_WINDOW  # nobody waits offline: the longer look hears chords better

    sr, tick = settings.audio.sample_rate, settings.tick
    wav = WavOutput(out / "out.wav", sr, 2) if settings.output.wav else None
    bodies = BodyFrames(settings.output, out, clock, messages) if settings.output.frames else None
    steps = int(math.ceil(duration / tick - 1e-9))
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=steps, unit="tick", desc=settings.title, leave=False, disable=None)
    try:
        for step in range(1, steps + 1):
            t0, t = (step - 1) * tick, min(step * tick, duration)
            clock.advance_to(t)
            a, b = int(round(t0 * sr)), int(round(t * sr))
            recorded = None if samples is None or a >= len(samples) else samples[a:min(b, len(samples))]
            mix = session.step(t, b - a, recorded, audio=wav is not None)
            if wav is not None:
                wav.write(mix)
            if bodies is not None:
                bodies.draw(session.creatures)
            if bar is not None:
                bar.update(1)
    except BaseException:
        if wav is not None:
            wav.abandon()
        raise
    finally:
        with contextlib.ExitStack() as closing:  # each is closed even when another fails (disk full)
            closing.callback(log.close)
            if bodies is not None:
                closing.callback(bodies.close)
            if bar is not None:
                closing.callback(bar.close)
            closing.callback(session.close)  # first: it logs the end and silences every note

    files = {"events": out / "events.jsonl"}
    if wav is not None:
        wav.close()
        files["wav"] = out / "out.wav"
    if settings.output.midi:
        write_notes(out / "out.mid", sink.notes())
        files["midi"] = out / "out.mid"
    for creature in session.creatures:
        files.update(creature.finish(out))
    session.save_state(out / "state")  # what the creatures learned: `creatures inspect DIR` shows it
    files["state"] = out / "state"
    if bodies is not None and bodies.renderer is not None:
        files["frames"] = out / "frames"
        if settings.output.video:
            files["video"] = out / "out.mp4"
    summary = OfflineSummary(duration, time.perf_counter() - wall0, session.world.notes_played, files, messages)
    if settings.output.report:
        from creatures.runtime.report import write_report

        files["report"] = write_report(out / "events.jsonl", out / "report", title=settings.title)
    return summary
