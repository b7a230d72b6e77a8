"""The line renderer: bodies as line drawings in SVG or PostScript, beside the mesh renderer
(thesis, "curve (technology)": "three new renderers for displaying these splines – either in
the current 3 dimensional graphics system, a 2 dimensional Java 2D based system, or direct to
Postscript").

A body is its bones as 3-D splines (:class:`~creatures.motor.spline.SplinePose`: each chain a
Catmull-Rom spline through its joints, drawn as one stroke of cubic Béziers, SVG's ``C`` and
PostScript's ``curveto``), so a line creature is one unbroken, smoothly bending line, as it was
drawn. Note objects are small
circles in their pitch's colour (the mesh renderer's :func:`~creatures.body.render.pitch_colour`).
The projection is orthographic, as a drawing on paper is: looking along the camera's axis
(default the front, −z), framed once on every frame of the run so the drawing does not jump.
SVG opens in any browser and in Inkscape/Illustrator; PostScript (EPS) in any print chain.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np

from creatures.motor.spline import SplinePose

Format = Literal["svg", "ps"]
MARGIN = 0.06
"""Fraction of the page left clear around the bodies."""


@dataclass(frozen=True)
class Page:
    """Where world points land on a ``width`` × ``height`` page: a view rotation (world →
    camera, orthographic) and the scale and centre that frame the run."""

    width: int
    height: int
    view: np.ndarray  # (3, 3): rows are the camera's right, up and backward axes in the world
    scale: float
    centre: np.ndarray  # (2,) camera-plane point at the page's centre

    @classmethod
    def framing(cls, points: np.ndarray, width: int, height: int, *, yaw: float = 0.0,
                pitch: float = 0.0) -> "Page":
        """A page that shows every one of ``points`` (N, 3), seen from ``yaw``/``pitch`` degrees."""
        y, p = math.radians(yaw), math.radians(pitch)
        back = np.array([math.cos(p) * math.sin(y), math.sin(p), math.cos(p) * math.cos(y)])
        right = np.cross([0.0, 1.0, 0.0], back)
        right /= max(np.linalg.norm(right), 1e-12)
        up = np.cross(back, right)
        view = np.stack([right, up, back])
        plane = points @ view[:2].T if len(points) else np.zeros((1, 2))
        low, high = plane.min(axis=0), plane.max(axis=0)
        extent = np.maximum(high - low, 1e-6)
        scale = float(min(width / extent[0], height / extent[1]) * (1 - 2 * MARGIN))
        return cls(width, height, view, scale, (low + high) / 2)

    def project(self, points: np.ndarray) -> np.ndarray:
        """Page coordinates (x right, y down, pixels) of world ``points`` (N, 3)."""
        plane = (np.asarray(points, float) @ self.view[:2].T - self.centre) * self.scale
        return np.stack([self.width / 2 + plane[:, 0], self.height / 2 - plane[:, 1]], axis=1)


def draw(page: Page, positions: np.ndarray, parents: np.ndarray, marks: list[tuple[tuple, float]],
         fmt: Format) -> str:
    """One frame as an SVG document or an EPS file."""
    from creatures.body.render import pitch_colour

    splines = SplinePose.of(positions, parents).segments if len(positions) else ()
    lines = [page.project(seg.reshape(-1, 3)).reshape(-1, 4, 2) for seg in splines]  # a projected Bézier is one
    notes = [(page.project(np.array([m]))[0], pitch_colour(pitch)) for m, pitch in marks]
    radius = max(page.width, page.height) / 160
    return _svg(page, lines, notes, radius) if fmt == "svg" else _eps(page, lines, notes, radius)


def _svg(page: Page, lines: list[np.ndarray], notes: list, radius: float) -> str:
    body = [f'<path d="M {line[0, 0, 0]:.3f},{line[0, 0, 1]:.3f} '
            + " ".join("C " + " ".join(f"{x:.3f},{y:.3f}" for x, y in seg[1:]) for seg in line) + '"/>'
            for line in lines]
    dots = [f'<circle cx="{x:.3f}" cy="{y:.3f}" r="{radius:.2f}" fill="{_hex(colour)}"/>' for (x, y), colour in notes]
    width = max(page.width, page.height) / 320
    return (f'<svg xmlns="http://www.w3.org/2000/svg" width="{page.width}" height="{page.height}" '
            f'viewBox="0 0 {page.width} {page.height}">\n<rect width="100%" height="100%" fill="white"/>\n'
            f'<g fill="none" stroke="black" stroke-width="{width:.2f}" stroke-linecap="round" '
            f'stroke-linejoin="round">\n' + "\n".join(body) + "\n</g>\n" + "\n".join(dots) + "\n</svg>\n")


def _eps(page: Page, lines: list[np.ndarray], notes: list, radius: float) -> str:
    h = page.height  # PostScript's y points up
    out = ["%!PS-Adobe-3.0 EPSF-3.0", f"%%BoundingBox: 0 0 {page.width} {page.height}",
           "%%Creator: creature-music (creatures/body/lines.py)", "%%EndComments",
           f"1 setlinecap 1 setlinejoin {max(page.width, page.height) / 320:.2f} setlinewidth 0 setgray"]
    for line in lines:
        curves = " ".join(" ".join(f"{x:.3f} {h - y:.3f}" for x, y in seg[1:]) + " curveto" for seg in line)
        out.append(f"newpath {line[0, 0, 0]:.3f} {h - line[0, 0, 1]:.3f} moveto {curves} stroke")
    for (x, y), colour in notes:
        out.append(f"{colour[0]:.3f} {colour[1]:.3f} {colour[2]:.3f} setrgbcolor "
                   f"newpath {x:.3f} {h - y:.3f} {radius:.2f} 0 360 arc fill")
    out += ["showpage", "%%EOF", ""]
    return "\n".join(out)


def _hex(colour) -> str:
    return "#" + "".join(f"{int(round(255 * min(max(c, 0.0), 1.0))):02x}" for c in colour[:3])


def render_lines(run_dir: Path, out: Path, *, fmt: Format = "svg", width: int = 640, height: int = 480,
                 fps: float | None = None, yaw: float = 0.0, pitch: float = 0.0) -> int:
    """Draw a finished run's bodies (its log's poses) as ``out/lines/frame_NNNNNN.svg`` (or
    ``.eps``) at ``fps``; the count of files written (a frame that fills several output frames
    is written once per output frame, as the PNG frames are). ``out/lines`` is replaced whole
    once every file is written."""
    from creatures.runtime.outputs import publishing
    from creatures.view.rerender import load_replay, log_rate, sampled
    from creatures.view.snapshot import scene

    played = load_replay(run_dir)
    if not any(f["bodies"] for f in played.frames):
        raise ValueError(f"{run_dir}: the events log holds no body poses (`pose` events) to draw")
    fps = fps or log_rate(played.frames)
    scenes = [(scene(message, played.hello), repeat) for message, repeat in sampled(played.frames, fps)]
    everything = np.concatenate([s[0] for s, _ in scenes if len(s[0])])
    page = Page.framing(everything, width, height, yaw=yaw, pitch=pitch)
    suffix = "svg" if fmt == "svg" else "eps"
    count = 0
    with publishing(out, {"lines"}) as staged:  # whole or not at all, as the frames of render_run
        directory = staged / "lines"
        directory.mkdir()
        for (positions, parents, marks), repeat in scenes:
            text = draw(page, positions, parents, marks, fmt)
            for _ in range(repeat):
                (directory / f"frame_{count:06d}.{suffix}").write_text(text)
                count += 1
    return count
