"""``[creature.images]``: an ozymandias creature's image half, and the step that makes its
video from the EDL when the run is over (thesis: "off-line image processing")."""

from __future__ import annotations

import functools
import os
from pathlib import Path
from typing import Annotated, Any

from pydantic import BaseModel, Field, PrivateAttr

from creatures.body.frames import video_encoder
from creatures.bounds import FINITE, LONGEST_OFFLINE
from creatures.image.footage import Footage, load_footage
from creatures.image.image_graph import ImageGraph
from creatures.image.video import write_video
from creatures.image.walker import Command, ImageCreature
from creatures.persist import save_json

IMAGES_KIND = "creature-music images"


class ImagesSpec(BaseModel):
    """Video walked out of a graph of frames by the creature's EDL."""

    model_config = FINITE
    footage: str = Field("cube", max_length=4096, description='"cube" (generated), a directory of PNG frames '
                                                              "(e.g. a run's frames/) or a video file, relative to "
                                                              "the config; frame f shows the recording's time f / fps")
    fps: float = Field(25.0, gt=0, le=120, description="frames a second, of the footage and of the video")
    size: tuple[Annotated[int, Field(ge=16, le=4096)], Annotated[int, Field(ge=16, le=4096)]] = Field(
        (160, 120), description="width and height of the generated cube footage, pixels (16…4096)")
    subsample: int = Field(10, ge=1, le=1000, description="every n-th frame is a key of the graph; the rest are "
                                                          "spokes between keys")
    jumps: int = Field(3, ge=0, le=32, description="jump edges kept from each key to the keys that look like its "
                                                   "next one")
    max_step: int = Field(64, ge=1, le=1000, description="graph nodes the walk may pass in one output frame (a far "
                                                       "target is reached in one frame of blurred travel)")
    blur: float = Field(1.5, ge=0, le=100, description="motion blur: nodes of tail per doubling of a node's "
                                                       "traversals")
    max_blur: int = Field(12, ge=0, le=200, description="longest tail of blur, nodes")
    video: bool = Field(True, description="encode <creature>.mp4 (else only <creature>.images.json)")
    png: bool = Field(False, description="also write the frames as PNGs in <creature>.frames/")
    _base: Path | None = PrivateAttr(None)

    def resolve(self, base: Path) -> str | None:
        """Tie ``footage`` to the config's directory; a problem as a message (None if fine)."""
        self._base = base
        if self.footage == "cube":
            return None
        path = base / self.footage
        if not path.exists():
            return f"no footage at {path} (a directory of PNG frames, a video file, or \"cube\")"
        return None

    def source(self) -> str | Path:
        return self.footage if self.footage == "cube" or self._base is None else self._base / self.footage


@functools.lru_cache(maxsize=1)
def _footage(source: str, fps: float, duration: float, size: tuple[int, int], scratch: Path) -> Footage:
    """One footage for every creature of a run that names the same (frames are large; past
    :data:`creatures.image.frame_store.IN_MEMORY` they wait in ``scratch``, the run's folder)."""
    return load_footage(source, fps=fps, duration=duration, size=size, scratch=scratch)


@functools.lru_cache(maxsize=1)
def _graph(source: str, fps: float, duration: float, size: tuple[int, int], scratch: Path, subsample: int,
           jumps: int) -> ImageGraph:
    return ImageGraph.build(_footage(source, fps, duration, size, scratch), subsample=subsample, jumps=jumps)


def make_video(spec: ImagesSpec, name: str, entries: list[dict[str, Any]], sample_rate: int, duration: float,
               out: Path) -> dict[str, Path]:
    """Walk the graph as ``entries`` command and write ``<name>.mp4`` (and PNGs) and
    ``<name>.images.json`` into ``out``; the files by name."""
    if spec.video:
        video_encoder(out / f"{name}.mp4")  # VideoUnavailable before the footage is read and walked
    duration = min(max(duration, 1.0 / spec.fps), LONGEST_OFFLINE)
    key = (str(spec.source()), spec.fps, round(duration, 3), tuple(spec.size), out)
    footage = _footage(*key)
    graph = _graph(*key, spec.subsample, spec.jumps)
    commands = [Command.from_entry(e, sample_rate) for e in entries] if sample_rate else []
    shots = ImageCreature(footage, graph, commands, fps=spec.fps, max_step=spec.max_step).run(duration)
    files: dict[str, Path] = {}
    video = out / f"{name}.mp4" if spec.video else None
    frames = out / f"{name}.frames" if spec.png else None
    # Encoded beside it and renamed over it once whole: ``creatures images`` writes into a
    # finished run, and one stopped (Ctrl-C, a full disk) left the run's video cut short.
    partial = out / f".{name}.part.mp4"
    try:
        record = write_video(footage, shots, fps=spec.fps, blur=spec.blur, max_blur=spec.max_blur,
                             video=partial if video is not None else None, frames=frames)
        if video is not None:
            os.replace(partial, video)
    finally:
        partial.unlink(missing_ok=True)
    images = out / f"{name}.images.json"
    save_json(images, {"creature": name, "fps": spec.fps, "footage": str(spec.footage),
                       "footage_frames": len(footage), "graph": {"keys": len(graph.keys), "jumps": graph.jumps},
                       "frames": record}, kind=IMAGES_KIND)
    files[f"images {name}"] = images
    if video is not None:
        files[f"video {name}"] = video
    if frames is not None:
        files[f"frames {name}"] = frames
    return files
