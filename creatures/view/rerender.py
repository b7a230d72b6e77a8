"""``creatures render RUN_DIR``: a finished offline run's bodies drawn again, at any size and
from any camera, from the poses its events log keeps (:mod:`creatures.view.poses`).

Frames come from the log's ``pose`` events through the same :func:`~creatures.view.snapshot.replay`
the browser's replay uses, placed by the same :func:`~creatures.view.snapshot.scene`, and drawn
by the instanced offscreen renderer (:class:`~creatures.body.render.BodyRenderer`). The camera is
an orbit — yaw and pitch around a target, at a distance — as the page's camera is, and by
default frames the first frame as both frame it, so a replay in the browser and a rendered
frame show the bodies from one place.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Iterator

import numpy as np

from creatures.events import iter_events
from creatures.view.snapshot import Replay, replay, scene, trees

if TYPE_CHECKING:
    from creatures.body.render import BodyRenderer


@dataclass(frozen=True)
class Orbit:
    """A camera ``distance`` metres from ``target``, turned ``yaw`` about the vertical from
    the front (+z) and raised ``pitch`` above the horizontal (degrees)."""

    yaw: float
    pitch: float
    distance: float
    target: tuple[float, float, float] = (0.0, 1.0, 0.0)

    def pose(self) -> np.ndarray:
        from creatures.body.render import look_at

        yaw, pitch = math.radians(self.yaw), math.radians(self.pitch)
        offset = self.distance * np.array([math.cos(pitch) * math.sin(yaw), math.sin(pitch),
                                           math.cos(pitch) * math.cos(yaw)])
        return look_at(np.asarray(self.target) + offset, self.target)


def parse_orbit(text: str) -> Orbit:
    """``YAW,PITCH,DISTANCE[,X,Y,Z]`` (degrees, metres) as an :class:`Orbit`; ValueError otherwise."""
    try:
        numbers = [float(part) for part in text.split(",")]
    except ValueError:
        numbers = []
    if len(numbers) not in (3, 6) or not all(math.isfinite(n) for n in numbers) or not numbers[2] > 0 \
            or abs(numbers[1]) >= 90:
        raise ValueError(f"{text!r}: a camera is YAW,PITCH,DISTANCE[,X,Y,Z] (degrees, |pitch| < 90, metres, "
                         "distance > 0)")
    return Orbit(*numbers[:3], target=tuple(numbers[3:]) if len(numbers) == 6 else (0.0, 1.0, 0.0))


def learned(run_dir: Path) -> dict | None:
    """A ``trees`` message of what the run's creatures knew at its end (``run_dir/state``), or None."""
    from creatures.runtime.inspect import read_state

    state = run_dir / "state"
    return trees(None, read_state(state)) if state.is_dir() else None


def load_replay(run_dir: Path) -> Replay:
    """The replay of ``run_dir/events.jsonl`` (or of the log file given): ValueError names what is missing."""
    log = run_dir / "events.jsonl" if run_dir.is_dir() else run_dir
    if not log.exists():
        raise ValueError(f"{log}: no events log (an offline run's output directory holds events.jsonl)")
    return replay(iter_events(log))


def sampled(frames: list[dict], fps: float) -> list[tuple[dict, int]]:
    """The frames to draw at ``fps`` from the first pose's time: each with how many output
    frames it fills (the latest pose at or before each output frame's time)."""
    t0, t1 = frames[0]["t"], frames[-1]["t"]
    count = int(math.floor((t1 - t0) * fps + 1e-9)) + 1
    times = [f["t"] for f in frames]
    chosen = np.searchsorted(times, t0 + np.arange(count) / fps + 1e-9, side="right") - 1
    runs: list[tuple[dict, int]] = []
    for index in chosen:
        if runs and runs[-1][0] is frames[index]:
            runs[-1] = (frames[index], runs[-1][1] + 1)
        else:
            runs.append((frames[index], 1))
    return runs


def log_rate(frames: list[dict]) -> float:
    """The rate the poses were logged at, over the whole run (each pose falls on the tick
    nearest its frame time, so neighbouring spacings vary by a tick): one output frame each."""
    if len(frames) < 2 or frames[-1]["t"] <= frames[0]["t"]:
        return 1.0
    return (len(frames) - 1) / (frames[-1]["t"] - frames[0]["t"])


def frames(played: Replay, renderer: "BodyRenderer", fps: float) -> Iterator[tuple[np.ndarray, int]]:
    """Each frame of ``played`` at ``fps`` drawn by ``renderer`` (into one image, reused: copy
    it to keep it), with how many output frames it fills."""
    from creatures.body.render import NoteMark

    image = np.empty((renderer.height, renderer.width, 3), np.uint8)
    for message, repeat in sampled(played.frames, fps):
        positions, parents, marks = scene(message, played.hello)
        renderer.render(positions, parents, [NoteMark(p, pitch) for p, pitch in marks], out=image)
        yield image, repeat


def render_run(run_dir: Path, out: Path, *, width: int = 640, height: int = 480, fps: float | None = None,
               camera: Orbit | None = None, pngs: bool = True, video: bool = False) -> int:
    """Draw the run's frames into ``out/frames`` (PNGs) and/or ``out/out.mp4``; the count drawn.
    Raises :class:`~creatures.body.render.RenderUnavailable` without an offscreen GL platform.

    Both are drawn aside and published together once whole (:func:`~creatures.runtime.outputs.publishing`):
    a render stopped part way (Ctrl-C, a full disk) wrote into ``out`` directly, leaving a
    short ``out.mp4`` that played as if whole and its frames over the start of the last
    render's, which stayed after them. Now it leaves ``out`` as it was."""
    from creatures.body.frames import FrameWriter
    from creatures.body.render import BodyRenderer
    from creatures.runtime.outputs import publishing

    played = load_replay(run_dir)
    if not any(f["bodies"] for f in played.frames):
        raise ValueError(f"{run_dir}: the events log holds no body poses (`pose` events) to draw: its creatures "
                         "have no bodies, or it was run with [view] log_fps = 0")
    fps = fps or log_rate(played.frames)
    drawn = 0
    with publishing(out, {"frames", "out.mp4"}) as staged, \
            BodyRenderer(width, height, camera_pose=None if camera is None else camera.pose()) as renderer, \
            FrameWriter(directory=staged / "frames" if pngs else None, video=staged / "out.mp4" if video else None,
                        fps=fps) as writer:
        for image, repeat in frames(played, renderer, fps):
            writer.write(image, repeat=repeat)
            drawn += repeat
    return drawn
