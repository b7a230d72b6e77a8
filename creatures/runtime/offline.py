"""``creatures offline``: an installation on the simulated clock, as fast as the CPU allows.

The same creatures as a live run, fed recorded (or generated) audio and MIDI, writing
``out.mid``, ``out.wav``, ``frames/`` (and ``out.mp4``), ``events.jsonl`` and ``report/``.
Time advances in behaviour ticks; audio is produced in blocks that exactly cover each tick
(frame counts come from elapsed time, so rounding never drifts), and frames fall due on their
own clock.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from audio.output import WavOutput
from audio.sources import load_audio
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


def _check_writable(out: Path) -> None:
    try:
        out.mkdir(parents=True, exist_ok=True)
        probe = out / ".write-probe"
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as exc:
        raise OutputDirectoryError(f"cannot write outputs to {out}: {exc.strerror or exc}") from None


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
    """Run ``inst`` on the simulated clock for ``duration`` seconds, writing into ``out``."""
    settings = inst.settings
    duration = float(duration if duration is not None else settings.duration)
    _check_writable(out)
    wall0 = time.perf_counter()
    clock = SimulatedClock()
    sink = MemorySink()
    messages: list[str] = []
    (out / "events.jsonl").unlink(missing_ok=True)  # a fresh log per run
    log = EventLog(out / "events.jsonl")
    session = Session(inst, clock, log, sink)
    session.world.emit("run", title=settings.title, mode="offline", duration=duration, seed=settings.seed,
                       creatures=[c.name for c in session.creatures])
    notes, samples = _inputs(inst, audio, midi, duration, session.input_rng)
    for note in notes:
        session.world.inject(note)
    transcribe = settings.audio.transcribe
    session.transcribe = samples is not None and (transcribe if transcribe is not None else not notes)

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
        session.close()
        if bar is not None:
            bar.close()
        if bodies is not None:
            bodies.close()
        log.close()

    files = {"events": out / "events.jsonl"}
    if wav is not None:
        wav.close()
        files["wav"] = out / "out.wav"
    if settings.output.midi:
        write_notes(out / "out.mid", sink.notes())
        files["midi"] = out / "out.mid"
    for creature in session.creatures:
        files.update(creature.finish(out))
    if bodies is not None and bodies.renderer is not None:
        files["frames"] = out / "frames"
        if settings.output.video:
            files["video"] = out / "out.mp4"
    summary = OfflineSummary(duration, time.perf_counter() - wall0, session.world.notes_played, files, messages)
    if settings.output.report:
        from creatures.runtime.report import write_report

        files["report"] = write_report(out / "events.jsonl", out / "report", title=settings.title)
    return summary
