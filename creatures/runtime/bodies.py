"""Frames of a colony's bodies, side by side, on their own clock (offline and live).

Each creature's figure (joint positions and parents) and its note objects are drawn into one
picture, creatures spaced along x, at the configured frame rate whatever the behaviour tick
(:class:`~creatures.body.frames.FrameClock`). Without an offscreen GL platform the run goes on
without pictures and says why.

Offline, frames are drawn in the run's own process (time waits for them). Live, drawing one
frame (pyrender on llvmpipe, a PNG encoded) took up to a second on a loaded machine, and on
the creature's thread it made most ticks late; so :class:`FramesBeside` only gathers each
due frame's figures (a few small arrays) and hands them to a process of its own, which draws
and writes them. A frame that finds that process still busy with earlier ones is dropped and
counted (:attr:`FramesBeside.dropped`): the creatures never wait for a picture.
"""

from __future__ import annotations

import multiprocessing
import os
import queue
import signal
from pathlib import Path

import numpy as np

from creatures.body.frames import FrameClock, FrameWriter, VideoUnavailable, video_encoder
from creatures.clock import Clock
from creatures.kinds.base import CreatureKind
from creatures.runtime.schema import OutputSection
from creatures.view.snapshot import place

Scene = tuple[np.ndarray, np.ndarray, list[tuple[tuple[float, float, float], float]]]
"""Joint positions (J, 3), their parents (J,) and note marks (position, pitch): one frame's content."""


def gather(creatures: list[CreatureKind]) -> Scene | None:
    """Every creature's figure and note objects as drawn (:meth:`~creatures.kinds.base.CreatureKind.shown`),
    each at its :func:`~creatures.view.snapshot.place` (as the live view and a replay place
    them), which in a room is the origin: there each stands where its vehicle is, and the
    room's own note objects lie on the floor. None if no one has a body."""
    positions, parents, marks = [], [], []
    offset = 0
    for i, creature in enumerate(creatures):
        shift = np.array(place(i, len(creatures), creature))
        figure = creature.shown()
        if figure is not None:
            p, par = figure
            positions.append(p + shift)
            parents.append(np.where(par >= 0, par + offset, -1))
            offset += len(p)
        marks += [(tuple(float(x) for x in np.asarray(position) + shift), pitch)
                  for position, pitch in creature.shown_marks()]
    if creatures and creatures[0].stage is not None:
        marks += creatures[0].stage.note_marks()
    if not positions:
        return None
    return np.concatenate(positions), np.concatenate(parents), marks


class BodyFrames:
    """Draws every creature's body into PNG frames (and a video), when a GL platform exists."""

    def __init__(self, output: OutputSection, out: Path, clock: Clock, messages: list[str]) -> None:
        from creatures.body.render import BodyRenderer, RenderUnavailable

        try:
            self.renderer = BodyRenderer(output.width, output.height, follow=output.follow)
        except RenderUnavailable as exc:
            messages.append(f"no frames: {exc}")
            self.renderer = None
            return
        video = out / "out.mp4" if output.video else None
        if video is not None:
            try:
                video_encoder(video)
            except VideoUnavailable as exc:  # as without GL: the run goes on, with the PNGs
                messages.append(f"no video: {exc}")
                video = None
        self.writer = FrameWriter(directory=out / "frames", video=video, fps=output.fps)
        self.clock = FrameClock(output.fps, clock)  # frames count from when drawing can start
        self._frame = np.empty((output.height, output.width, 3), np.uint8)  # drawn into, frame after frame
        self.painted = 0  # scenes drawn: none when no creature has a body

    def draw(self, creatures: list[CreatureKind]) -> None:
        if self.renderer is None:
            return
        due = self.clock.due()
        if due:
            scene = gather(creatures)
            if scene is not None:
                self.paint(scene, due)

    def paint(self, scene: Scene, repeat: int) -> None:
        """Render one gathered scene and write it ``repeat`` times (frames that fell due together)."""
        from creatures.body.render import NoteMark

        positions, parents, marks = scene
        frame = self.renderer.render(positions, parents, [NoteMark(p, pitch) for p, pitch in marks], out=self._frame)
        self.writer.write(frame, repeat=repeat)
        self.painted += 1

    def close(self) -> None:
        if self.renderer is not None:
            self.writer.close()
            self.renderer.close()


QUEUED_FRAMES = 32
"""Frames that may wait for the drawing process; more are dropped (and counted)."""

FRAMES_NICENESS = 10
"""How much lower the drawing process's priority is than the run's (``os.nice``)."""


def _draw_beside(output: dict, out: str, scenes: multiprocessing.Queue, ready: multiprocessing.Queue) -> None:
    """The drawing process: a :class:`BodyFrames` of its own, fed scenes until ``None``.

    It yields to the sound: niced, and software GL (llvmpipe) on one thread unless the user
    asked otherwise, so on a small machine a frame never takes the core the mix is made on
    (measured on 2 cores: drawing at 30 fps beside exchange on JACK put 1–3 gaps in the sound
    in the first seconds of one run in four)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the run's: it sends the last frames and None
    os.environ.setdefault("LP_NUM_THREADS", "1")  # before GL loads
    try:
        os.nice(FRAMES_NICENESS)
    except OSError:  # not permitted here: drawn at the run's priority
        pass
    messages: list[str] = []
    from creatures.clock import WallClock

    frames = BodyFrames(OutputSection(**output), Path(out), WallClock(), messages)
    ready.put((frames.renderer is not None, messages))  # drawing, and what to say (no GL, no video)
    if frames.renderer is None:
        return
    try:
        while (item := scenes.get()) is not None:
            frames.paint(*item)
    finally:
        frames.close()


class FramesBeside:
    """Live frames: due on the run's clock, drawn and written by a process of their own."""

    def __init__(self, output: OutputSection, out: Path, clock: Clock, messages: list[str]) -> None:
        context = multiprocessing.get_context("spawn")  # a fresh interpreter: no copy of the colony
        self.scenes = context.Queue(QUEUED_FRAMES)
        ready = context.Queue()
        self.process = context.Process(target=_draw_beside, args=(output.model_dump(), str(out), self.scenes, ready),
                                       name="creatures-frames", daemon=True)
        self.process.start()
        self.dropped = 0  # frames that found the drawing process busy
        # before the run starts: the process has its renderer or says why (and whether it has a video)
        self.drawing, said = ready.get(timeout=120)
        messages.extend(said)
        if not self.drawing:
            self.process.join(10)
        self.clock = FrameClock(output.fps, clock)

    def draw(self, creatures: list[CreatureKind]) -> None:
        if not self.drawing:
            return
        due = self.clock.due()
        if due:
            scene = gather(creatures)
            if scene is not None:
                try:
                    self.scenes.put_nowait((scene, due))
                except queue.Full:
                    self.dropped += due

    def close(self) -> None:
        """The last frames are drawn and the video finished (bounded wait), then the process ends."""
        if self.drawing:
            self.drawing = False
            try:
                self.scenes.put(None, timeout=10)
            except queue.Full:
                pass
        self.process.join(60)
        if self.process.is_alive():
            self.process.terminate()
