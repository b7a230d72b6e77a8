"""Frames on their own clock, and where they go (PNG files, a video file).

The behaviour system ticks at whatever rate its work allows; pictures must come at a fixed
frame rate regardless (DESIGN.md "Time": elapsed clock time, never loop counts). A
:class:`FrameClock` says how many frames fell due since it was last asked, from elapsed
time alone: a slow tick repeats the latest picture, a fast one skips frames — so a video's
length always equals the run's length.
"""

from __future__ import annotations

import math
import os
import shutil
from pathlib import Path

import imageio.v2 as imageio_v2
import imageio.v3 as iio
import numpy as np

from creatures.clock import Clock, clock_gap


class FrameClock:
    """Frames at ``fps`` from a clock's elapsed time; frame 0 falls due at the first call.

    Across a clock gap (:func:`~creatures.clock.clock_gap`: a suspended machine, a stalled
    thread) the frames of the gap are skipped, counted in :attr:`skipped` (said at the end of a
    live run drawing frames; an offline run's clock steps a tick at a time, never a gap), and
    one falls due: the picture goes on from now, as the bodies and the score do. Counted as due, a live run's
    machine woken after a night had its drawing process write the last picture 345,600 times
    (8 h at 12 fps), gigabytes of PNGs, while it dropped every new frame."""

    def __init__(self, fps: float, clock: Clock) -> None:
        if not (math.isfinite(fps) and fps > 0):
            raise ValueError(f"fps must be a positive number, got {fps!r}")
        self.fps = float(fps)
        self.clock = clock
        self._start = self._asked = clock.now()
        self.emitted = 0
        self.skipped = 0

    def due(self) -> int:
        """How many frames fell due since the last call (0, 1, or more after a slow tick)."""
        now = self.clock.now()
        total = math.floor((now - self._start) * self.fps + 1e-9) + 1
        count = max(total - self.emitted, 0)
        if count > 1 and clock_gap(self._asked, now):
            self.skipped += count - 1
            count = 1
        self._asked = now
        self.emitted = max(total, self.emitted)
        return count


class VideoUnavailable(OSError):
    """No video encoder (ffmpeg) to write a video with; the message says what was looked for."""


def video_encoder(video: str | os.PathLike) -> str:
    """The ffmpeg imageio would encode ``video`` with, or :class:`VideoUnavailable` naming it.

    imageio looks for it only at the first frame: without one, a run asked for a video died at
    its first frame with a traceback (imageio-ffmpeg's RuntimeError), and ozymandias's, whose
    video is made when the run is over, lost the whole run. ``IMAGEIO_FFMPEG_EXE`` is taken as
    given by imageio, so it is checked here to be a program."""
    import imageio_ffmpeg

    try:
        exe = imageio_ffmpeg.get_ffmpeg_exe()
    except RuntimeError as exc:  # imageio-ffmpeg's "No ffmpeg exe could be found ..."
        raise VideoUnavailable(f"cannot write {Path(video).name}: no video encoder ({exc})") from None
    if shutil.which(exe) is None:
        raise VideoUnavailable(f"cannot write {Path(video).name}: no video encoder ({exe}, from IMAGEIO_FFMPEG_EXE, is not "
                               "a program: point it at ffmpeg or unset it)")
    return exe


class FrameWriter:
    """Writes RGB frames as numbered PNGs into ``directory`` and/or a ``video`` (imageio-ffmpeg).

    H.264 in yuv420p (what players play) needs even sizes: a frame of odd width or height goes
    into the video with its last column or row repeated (201×301 → 202×301 → 202×302), never
    rescaled; imageio's own fix scaled it up to a multiple of 8 (208×304), with a warning.
    Without an encoder for the video it raises :class:`VideoUnavailable` before writing anything."""

    def __init__(self, *, directory: str | os.PathLike | None = None, video: str | os.PathLike | None = None,
                 fps: float = 30.0) -> None:
        if directory is None and video is None:
            raise ValueError("FrameWriter needs a directory for PNGs, a video path, or both")
        if video is not None:
            video_encoder(video)
        self.directory = None if directory is None else Path(directory)
        if self.directory is not None:
            self.directory.mkdir(parents=True, exist_ok=True)
        if video is not None:
            Path(video).parent.mkdir(parents=True, exist_ok=True)  # a video alone (--no-pngs) has its folder too
        self.video = None if video is None else Path(video)
        self._video = None if video is None else imageio_v2.get_writer(
            video, fps=fps, codec="libx264", quality=7, macro_block_size=1)
        self.count = 0

    def write(self, frame: np.ndarray, *, repeat: int = 1) -> None:
        """Write ``frame`` ``repeat`` times (as :meth:`FrameClock.due` asks)."""
        video = None if self._video is None else _even(frame)  # padded once, however often repeated
        for _ in range(repeat):
            if self.directory is not None:
                iio.imwrite(self.directory / f"frame_{self.count:06d}.png", frame)
            if video is not None:
                self._video.append_data(video)
            self.count += 1

    def close(self) -> None:
        if self._video is not None:
            self._video.close()
            self._video = None

    def __enter__(self) -> FrameWriter:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def drop_stale(directory: Path, suffix: str, count: int) -> int:
    """Remove ``frame_NNNNNN.<suffix>`` files numbered ``count`` and up from ``directory``: what
    an earlier, longer render left. Drawn again into the same folder at a lower rate, a render
    of 30 frames left 271 of the last one's after them, and a sequence made of the folder
    showed both. Only files named as frames are touched; returns how many went."""
    gone = 0
    for path in directory.glob(f"frame_*.{suffix}"):
        number = path.name[len("frame_"):-len(suffix) - 1]
        if number.isdigit() and int(number) >= count and path.is_file():
            path.unlink(missing_ok=True)
            gone += 1
    return gone


def _even(frame: np.ndarray) -> np.ndarray:
    """``frame`` with its last row and/or column repeated to make both sizes even."""
    h, w = frame.shape[:2]
    if h % 2 == 0 and w % 2 == 0:
        return frame
    return np.pad(frame, ((0, h % 2), (0, w % 2)) + ((0, 0),) * (frame.ndim - 2), mode="edge")
