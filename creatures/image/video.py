"""Output frames with motion blur along the path, and the video written from them (thesis,
"ozymandias (video)": "Instead of generating material by interpolating (by weighted sum)
between nodes in the graph, we can take weighted sums of groups of nodes along the path").

Each frame is the weighted sum of the nodes the image creature passed to reach it (the last
``max_blur`` of them: older ones would weigh under 1 %) plus a tail of the nodes it passed
before; the tail is ``blur · log2(1 + visits)`` nodes long for the node shown, so material read again and again smears more and more: the piece "deals
with the destruction of material over time". Newer nodes weigh more (``decay`` per node).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from creatures.body.frames import FrameWriter, drop_stale
from creatures.image.footage import Footage
from creatures.image.walker import Shot

DECAY = 0.7
"""Weight of each older node in a blurred frame, relative to the next newer one."""


class Blur:
    """Composes shots into frames, keeping the recent path for the tail."""

    def __init__(self, footage: Footage, *, blur: float, max_blur: int) -> None:
        self.footage = footage
        self.blur = float(blur)
        self.max_blur = int(max_blur)
        self.visits = np.zeros(len(footage), np.int64)
        self.history: list[int] = []

    def tail(self, node: int) -> int:
        """Extra nodes of blur for a frame showing ``node``."""
        return min(self.max_blur, int(self.blur * math.log2(1 + self.visits[node])))

    def compose(self, shot: Shot) -> tuple[np.ndarray, int, int]:
        """The frame for ``shot``, how many nodes it sums, and how many of them are the tail of
        earlier travel (the wear of traversal, not this frame's own travel)."""
        np.add.at(self.visits, shot.nodes, 1)
        self.history.extend(shot.nodes)
        del self.history[: max(0, len(self.history) - 4 * self.max_blur - 64)]
        travel = min(len(shot.nodes), max(self.max_blur, 1))
        group = self.history[-(travel + self.tail(shot.nodes[-1])):]
        if len(group) == 1:
            return self.footage.frames[group[0]], 1, 0
        weights = DECAY ** np.arange(len(group) - 1, -1, -1, dtype=np.float32)
        frames = self.footage.frames[group].astype(np.float32)
        image = np.tensordot(weights / weights.sum(), frames, axes=1)
        return np.clip(image + 0.5, 0, 255).astype(np.uint8), len(group), len(group) - travel


def write_video(footage: Footage, shots: list[Shot], *, fps: float, blur: float, max_blur: int,
                video: Path | None, frames: Path | None) -> list[dict[str, Any]]:
    """Compose and write every shot (to ``video`` and/or PNGs in ``frames``); the per-frame
    record the images file keeps (time, node shown, nodes passed, nodes summed and of them the
    tail of wear, the shown node's traversals so far, a cut, the command answered)."""
    composer = Blur(footage, blur=blur, max_blur=max_blur)
    writer = FrameWriter(directory=frames, video=video, fps=fps) if (video or frames) else None
    record = []
    try:
        for shot in shots:
            image, summed, tail = composer.compose(shot)
            if writer is not None:
                writer.write(image)
            record.append({"time": round(shot.time, 6), "node": shot.nodes[-1], "passed": len(shot.nodes),
                           "blur": summed, "tail": tail,
                           "visits": int(composer.visits[shot.nodes[-1]]), "cut": shot.cut,
                           "source": None if shot.command is None else round(shot.command.source, 6),
                           "source_end": None if shot.command is None else round(shot.command.source_end, 6)})
    finally:
        if writer is not None:
            writer.close()
    if frames is not None:  # a shorter video made again into the folder (``creatures images --fps``) left the rest
        drop_stale(frames, "png", len(record))
    return record
