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

from audio.mixer import Mixer
from audio.output import WavOutput
from audio.sources import load_audio
from creatures.body.frames import FrameClock, FrameWriter
from creatures.clock import SimulatedClock
from creatures.events import EventLog
from creatures.kinds import KINDS
from creatures.runtime.inputs import phrase_notes, render_notes
from creatures.runtime.schema import LoadedInstallation
from creatures.runtime.world import World
from midi.files import read_notes, write_notes
from midi.notes import NoteEvent
from midi.scheduler import NoteScheduler
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
    return [n for n in notes if n.time < duration], samples


def _heard(samples: np.ndarray | None, a: int, b: int, room: np.ndarray | None) -> np.ndarray | None:
    """What the creatures' ears get for frames ``[a, b)``: the input, plus the room's sound
    (every voice of the previous tick) when creatures hear each other through the air."""
    recorded = None if samples is None or a >= len(samples) else samples[a:min(b, len(samples))]
    if room is None or not len(room):
        return recorded
    heard = np.zeros(b - a, dtype=np.float32)
    if recorded is not None:
        heard[: len(recorded)] += recorded
    n = min(len(room), b - a)
    heard[:n] += room[:n]
    return heard


class _Bodies:
    """Draws every creature's body side by side into frames, when a GL platform exists."""

    def __init__(self, inst: LoadedInstallation, out: Path, clock: SimulatedClock, messages: list[str]) -> None:
        from creatures.body.render import BodyRenderer, RenderUnavailable

        o = inst.settings.output
        self.clock = FrameClock(o.fps, clock)
        try:
            self.renderer = BodyRenderer(o.width, o.height)
        except RenderUnavailable as exc:
            messages.append(f"no frames: {exc}")
            self.renderer = None
            return
        self.writer = FrameWriter(directory=out / "frames", video=out / "out.mp4" if o.video else None, fps=o.fps)

    def draw(self, creatures: list) -> None:
        if self.renderer is None:
            return
        due = self.clock.due()
        if not due:
            return
        positions, parents, marks = [], [], []
        offset = 0
        spacing = 1.5
        for i, creature in enumerate(creatures):
            shift = np.array([(i - (len(creatures) - 1) / 2) * spacing, 0.0, 0.0])
            body = creature.figure()
            if body is not None:
                p, par = body
                positions.append(p + shift)
                parents.append(np.where(par >= 0, par + offset, -1))
                offset += len(p)
            for position, pitch in creature.marks():
                from creatures.body.render import NoteMark

                marks.append(NoteMark(tuple(np.asarray(position) + shift), pitch))
        if positions:
            frame = self.renderer.render(np.concatenate(positions), np.concatenate(parents), marks)
            self.writer.write(frame, repeat=due)

    def close(self) -> None:
        if self.renderer is not None:
            self.writer.close()
            self.renderer.close()


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
    seeds = np.random.SeedSequence(settings.seed).spawn(len(inst.specs) + 1)
    notes, samples = _inputs(inst, audio, midi, duration, np.random.default_rng(seeds[-1]))

    wall0 = time.perf_counter()
    clock = SimulatedClock()
    sink = MemorySink()
    messages: list[str] = []
    (out / "events.jsonl").unlink(missing_ok=True)  # a fresh log per run
    log = EventLog(out / "events.jsonl")
    scheduler = NoteScheduler(sink, clock)
    world = World(clock, log, scheduler)
    for spec, seed in zip(inst.specs, seeds):
        world.add(KINDS[spec.kind](spec, world, np.random.default_rng(seed)))
    creatures = world.creatures
    for note in notes:
        world.inject(note)
    world.emit("run", title=settings.title, mode="offline", duration=duration, seed=settings.seed,
               creatures=[c.name for c in creatures])

    sr, tick = settings.audio.sample_rate, settings.tick
    block = int(math.ceil(tick * sr)) + 1
    mixer = Mixer(len(creatures), block_size=block)
    for i, creature in enumerate(creatures):
        mixer.set(i, gain=creature.spec.gain, pan=creature.spec.pan)
    voices = np.zeros((len(creatures), block), dtype=np.float64)
    air, room = settings.audio.air, np.zeros(0)
    wav = WavOutput(out / "out.wav", sr, 2) if settings.output.wav else None
    bodies = _Bodies(inst, out, clock, messages) if settings.output.frames else None
    steps = int(math.ceil(duration / tick - 1e-9))
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=steps, unit="tick", desc=settings.title, leave=False)
    done = 0
    try:
        for step in range(1, steps + 1):
            t0, t = (step - 1) * tick, min(step * tick, duration)
            clock.advance_to(t)
            world.deliver(t)
            a, b = int(round(t0 * sr)), int(round(t * sr))
            heard = _heard(samples, a, b, room if air else None)
            if heard is not None:
                for creature in creatures:
                    creature.listen(t, heard, sr)
            for creature in creatures:
                creature.tick(t)
            scheduler.pump()
            if wav is not None or air:
                for i, creature in enumerate(creatures):
                    creature.sound(voices[i, : b - a], sr)
                if air:
                    room = voices[:, : b - a].T @ mixer.gains
            if wav is not None:
                wav.write(mixer.mix(voices[:, : b - a]))
            if bodies is not None:
                bodies.draw(creatures)
            if bar is not None:
                bar.update(1)
            done = step
    except BaseException:
        if wav is not None:
            wav.abandon()
        raise
    finally:
        scheduler.all_notes_off()
        if bar is not None:
            bar.close()
        if bodies is not None:
            bodies.close()
        world.emit("end", ticks=done, notes=world.notes_played)
        log.close()

    files = {"events": out / "events.jsonl"}
    if wav is not None:
        wav.close()
        files["wav"] = out / "out.wav"
    if settings.output.midi:
        write_notes(out / "out.mid", sink.notes())
        files["midi"] = out / "out.mid"
    for creature in creatures:
        files.update(creature.finish(out))
    if bodies is not None and bodies.renderer is not None:
        files["frames"] = out / "frames"
        if settings.output.video:
            files["video"] = out / "out.mp4"
    summary = OfflineSummary(duration, time.perf_counter() - wall0, world.notes_played, files, messages)
    if settings.output.report:
        from creatures.runtime.report import write_report

        files["report"] = write_report(out / "events.jsonl", out / "report", title=settings.title)
    return summary
