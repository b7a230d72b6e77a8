"""Footage: the frames an image graph is made of, each tied to a time in the recording.

The thesis's ozymandias took "around 1200 frames taken from the *sand:stone* installation":
the colony's own renders. Footage here is any of

* a directory of numbered PNG frames (a run's ``frames/``, see :mod:`creatures.body.frames`),
* a video file (read through imageio's ffmpeg plugin),
* ``"cube"``: a generated rotating, textured cube that slowly loses its colour, the test
  footage of the thesis's own figures ("one of the structures present in a graph of the
  rotating cube footage") and the embedded default, so the piece runs with no files and no GL.

Frame ``f`` shows the recording's time ``f / fps``: the video and the audio share one time
line, which is what lets the EDL's *source* times choose frames.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from creatures.image.frame_store import FrameStore, NoRoom

MAX_FRAMES = 100_000
"""Frames one footage may hold (≈ an hour at 25 fps); more is refused, not truncated."""

VIDEO_SUFFIXES = (".mp4", ".mov", ".avi", ".mkv", ".webm", ".m4v")


class FootageError(ValueError):
    """Footage that cannot be used, with the file (or directory) and why."""


@dataclass(frozen=True)
class Footage:
    """Frames ``(N, H, W, 3)`` uint8 at ``fps`` frames per second of the recording."""

    frames: np.ndarray
    fps: float

    def __post_init__(self) -> None:
        if self.frames.ndim != 4 or self.frames.shape[-1] != 3 or self.frames.dtype != np.uint8:
            raise FootageError(f"footage must be (frames, height, width, 3) uint8, got {self.frames.shape} "
                               f"{self.frames.dtype}")
        if len(self.frames) < 2:
            raise FootageError(f"footage needs at least 2 frames, got {len(self.frames)}")

    def __len__(self) -> int:
        return len(self.frames)

    def frame_at(self, seconds: float) -> int:
        """The frame showing the recording's time ``seconds`` (clipped to the footage)."""
        return int(min(max(np.floor(seconds * self.fps + 1e-9), 0), len(self.frames) - 1))


def load_footage(source: str | Path, *, fps: float, duration: float, size: tuple[int, int],
                 scratch: Path | None = None) -> Footage:
    """Footage from ``source`` (``"cube"``, a PNG directory or a video file), ``fps`` frames a
    second; the generated cube lasts ``duration`` seconds at ``size`` (width, height). Frames
    past :data:`creatures.image.frame_store.IN_MEMORY` bytes are kept in ``scratch``."""
    try:
        if str(source) == "cube":
            return cube_footage(duration=duration, fps=fps, size=size, scratch=scratch)
        path = Path(source)
        if path.is_dir():
            return Footage(_read_pngs(path, scratch), fps)
        if path.is_file() and path.suffix.lower() in VIDEO_SUFFIXES:
            return Footage(_read_video(path, scratch), fps)
    except NoRoom as exc:  # in the scratch folder, for frames past IN_MEMORY
        raise FootageError(f"{source}: {exc.strerror}") from None
    if path.is_file():
        raise FootageError(f"{path}: footage is a directory of PNG frames or a video ({', '.join(VIDEO_SUFFIXES)})")
    raise FootageError(f"{path}: no such footage (a directory of PNG frames, a video file, or \"cube\")")


def _read_pngs(directory: Path, scratch: Path | None) -> np.ndarray:
    import imageio.v3 as iio

    files = sorted(directory.glob("*.png"))
    if not files:
        raise FootageError(f"{directory}: holds no PNG frames")
    if len(files) > MAX_FRAMES:
        raise FootageError(f"{directory}: {len(files)} frames, more than {MAX_FRAMES}")
    store = FrameStore(scratch, capacity=len(files))
    for file in files:
        try:
            image = np.asarray(iio.imread(file))
        except Exception as exc:  # imageio raises many types for a broken image
            raise FootageError(f"{file}: not a readable PNG ({type(exc).__name__}: {exc})") from None
        store.append(_rgb(image, file, store.shape))
    return store.frames()


def _read_video(path: Path, scratch: Path | None) -> np.ndarray:
    import imageio.v3 as iio

    store = FrameStore(scratch)
    try:
        for image in iio.imiter(path):
            store.append(_rgb(np.asarray(image), path, store.shape))
            if store.count > MAX_FRAMES:
                raise FootageError(f"{path}: more than {MAX_FRAMES} frames")
    except (FootageError, NoRoom):
        raise
    except Exception as exc:
        raise FootageError(f"{path}: not a readable video ({type(exc).__name__}: {exc})") from None
    if store.count == 0:
        raise FootageError(f"{path}: holds no frames")
    return store.frames()


def _rgb(image: np.ndarray, file: Path, shape: tuple[int, ...] | None) -> np.ndarray:
    """``image`` as (H, W, 3) uint8; every frame must share the first one's size."""
    if image.ndim == 2:
        image = np.repeat(image[..., None], 3, axis=2)
    if image.ndim != 3 or image.shape[2] not in (3, 4):
        raise FootageError(f"{file}: not an RGB image (shape {image.shape})")
    image = image[..., :3]
    if image.dtype != np.uint8:
        image = np.clip(image.astype(np.float64) / max(np.iinfo(image.dtype).max, 1) * 255, 0, 255).astype(np.uint8) \
            if np.issubdtype(image.dtype, np.integer) else np.clip(image * 255, 0, 255).astype(np.uint8)
    if shape is not None and image.shape != shape:
        raise FootageError(f"{file}: frame is {image.shape[1]}×{image.shape[0]}, the first was {shape[1]}×{shape[0]}")
    return image


# -- the generated cube -------------------------------------------------------------------------

_CORNERS = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=np.float64)
_FACES = ((0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3))
_COLOURS = np.array([[200, 60, 50], [60, 170, 80], [60, 90, 200], [220, 190, 60], [170, 70, 190], [70, 190, 200]],
                    dtype=np.float64)


def cube_footage(*, duration: float, fps: float, size: tuple[int, int], scratch: Path | None = None) -> Footage:
    """A cube turning about two axes (one turn every 4 s about y, every 11 s about x), each
    face a colour with a stripe texture that breaks the cube's symmetry (as the thesis's
    textured faces did), fading to grey over the footage: loops and near-loops for the graph
    to find, and a direction of time it cannot fake."""
    width, height = size
    count = max(int(np.ceil(duration * fps)), 2)
    unit = 0.32 * min(width, height)
    store = FrameStore(scratch, capacity=count)
    frame = np.empty((height, width, 3), np.uint8)
    for f in range(count):
        t = f / fps
        frame.fill(24)
        _draw_cube(frame, t, t / max(duration, 1e-9), unit)
        store.append(frame)
    return Footage(store.frames(), fps)


def _draw_cube(image: np.ndarray, t: float, age: float, unit: float) -> None:
    """Draw the cube at time ``t`` into ``image`` (orthographic, looking down -z); each visible
    face is filled over its own bounding box only (the faces of a convex solid never overlap
    once back faces are culled, so no depth test is needed)."""
    height, width, _ = image.shape
    a, b = 2 * np.pi * t / 4.0, 2 * np.pi * t / 11.0
    ry = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
    rx = np.array([[1, 0, 0], [0, np.cos(b), -np.sin(b)], [0, np.sin(b), np.cos(b)]])
    corners = _CORNERS @ (rx @ ry).T * 0.9
    grey = np.array([128.0, 128.0, 128.0])
    for face, colour in zip(_FACES, _COLOURS):
        quad = corners[list(face)]
        u, v = quad[1] - quad[0], quad[3] - quad[0]
        normal = np.cross(u, v)
        det = u[0] * v[1] - u[1] * v[0]
        if normal[2] <= 0 or abs(det) < 1e-12:  # facing away, or edge on
            continue
        cols = quad[:, 0] * unit + width / 2
        rows = height / 2 - quad[:, 1] * unit
        c0, c1 = max(int(cols.min()), 0), min(int(np.ceil(cols.max())) + 1, width)
        r0, r1 = max(int(rows.min()), 0), min(int(np.ceil(rows.max())) + 1, height)
        ys, xs = np.mgrid[r0:r1, c0:c1]
        dx = (xs - width / 2) / unit - quad[0, 0]
        dy = (height / 2 - ys) / unit - quad[0, 1]
        s = (dx * v[1] - dy * v[0]) / det
        r = (u[0] * dy - u[1] * dx) / det
        inside = (s >= 0) & (s <= 1) & (r >= 0) & (r <= 1)
        stripes = 0.65 + 0.35 * (np.floor(s[inside] * 4) % 2)  # four stripes across the face
        shade = (0.45 + 0.55 * normal[2] / np.linalg.norm(normal)) * stripes
        tint = (1 - age) * colour + age * grey
        image[r0:r1, c0:c1][inside] = np.clip(shade[:, None] * tint, 0, 255).astype(np.uint8)
