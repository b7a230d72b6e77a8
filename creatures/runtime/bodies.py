"""Frames of a colony's bodies, side by side, on their own clock (offline and live).

Each creature's figure (joint positions and parents) and its note objects are drawn into one
picture, creatures spaced along x, at the configured frame rate whatever the behaviour tick
(:class:`~creatures.body.frames.FrameClock`). Without an offscreen GL platform the run goes on
without pictures and says why.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from creatures.body.frames import FrameClock, FrameWriter
from creatures.clock import Clock
from creatures.kinds.base import CreatureKind
from creatures.runtime.schema import OutputSection

SPACING = 1.5
"""Metres between neighbouring creatures in the picture."""


class BodyFrames:
    """Draws every creature's body into PNG frames (and a video), when a GL platform exists."""

    def __init__(self, output: OutputSection, out: Path, clock: Clock, messages: list[str]) -> None:
        from creatures.body.render import BodyRenderer, RenderUnavailable

        try:
            self.renderer = BodyRenderer(output.width, output.height)
        except RenderUnavailable as exc:
            messages.append(f"no frames: {exc}")
            self.renderer = None
            return
        self.writer = FrameWriter(directory=out / "frames", video=out / "out.mp4" if output.video else None,
                                  fps=output.fps)
        self.clock = FrameClock(output.fps, clock)  # frames count from when drawing can start
        self._frame = np.empty((output.height, output.width, 3), np.uint8)  # drawn into, frame after frame

    def draw(self, creatures: list[CreatureKind]) -> None:
        if self.renderer is None:
            return
        due = self.clock.due()
        if not due:
            return
        from creatures.body.render import NoteMark

        positions, parents, marks = [], [], []
        offset = 0
        for i, creature in enumerate(creatures):
            shift = np.array([(i - (len(creatures) - 1) / 2) * SPACING, 0.0, 0.0])
            figure = creature.figure()
            if figure is not None:
                p, par = figure
                positions.append(p + shift)
                parents.append(np.where(par >= 0, par + offset, -1))
                offset += len(p)
            marks += [NoteMark(tuple(np.asarray(position) + shift), pitch) for position, pitch in creature.marks()]
        if positions:
            frame = self.renderer.render(np.concatenate(positions), np.concatenate(parents), marks, out=self._frame)
            self.writer.write(frame, repeat=due)

    def close(self) -> None:
        if self.renderer is not None:
            self.writer.close()
            self.renderer.close()
