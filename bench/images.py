"""ozymandias's image half: what building the graph of frames, walking it by an EDL, and
composing the blurred video cost (thesis, "off-line image processing – image creatures").

Rows (``python -m bench images``), CPU time of this process (ffmpeg's encoding runs in its
own process and is not counted):

* the image graph of the generated footage (60 s at 25 fps, 160×120: 1,500 frames), ms;
* the image creature walking a minute of EDL (reads of 0.15–1 s from anywhere in the
  recording, one every ~0.7 s), × real time (target ≥ 20, the runtime's goal for a piece
  without frames);
* composing the blurred frames of that minute, × real time.
"""

from __future__ import annotations

import time

import numpy as np

from bench import Row, best_of
from creatures.image.footage import cube_footage
from creatures.image.image_graph import ImageGraph
from creatures.image.video import write_video
from creatures.image.walker import Command, ImageCreature

FPS = 25.0


def reads(seconds: float, seed: int = 1) -> list[Command]:
    """An EDL's worth of commands: short parts of the recording read back out of time."""
    rng = np.random.default_rng(seed)
    commands, t = [], 0.3
    while t < seconds:
        length = float(rng.uniform(0.15, 1.0))
        source = float(rng.uniform(0, max(seconds - length, 0.1)))
        commands.append(Command(t, t + length, source, source + length))
        t += length + float(rng.exponential(0.4))
    return commands


def run(quick: bool) -> list[Row]:
    seconds = 20.0 if quick else 60.0
    footage = cube_footage(duration=seconds, fps=FPS, size=(160, 120))
    build = best_of(lambda: ImageGraph.build(footage), repeat=2, clock=time.process_time)
    graph = ImageGraph.build(footage)
    commands = reads(seconds)
    walk = best_of(lambda: ImageCreature(footage, graph, commands, fps=FPS).run(seconds), repeat=2,
                   clock=time.process_time)
    shots = ImageCreature(footage, graph, commands, fps=FPS).run(seconds)
    compose = best_of(lambda: write_video(footage, shots, fps=FPS, blur=1.5, max_blur=12, video=None, frames=None),
                      repeat=2, clock=time.process_time)
    return [
        Row(f"image graph of {len(footage)} frames (160×120, keys every 10)", build * 1e3, "ms CPU"),
        Row(f"image creature walking {seconds:.0f} s of EDL ({len(commands)} reads)", seconds / walk,
            "× real time", 20.0),
        Row(f"motion-blurred frames of {seconds:.0f} s composed", seconds / compose, "× real time"),
    ]
