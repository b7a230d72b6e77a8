"""The rendered body: a creature's skeleton and its notes drawn offscreen.

The thesis' creatures are seen as well as heard (*soundcreatures*: "each creature has a
graphical representation"; *exchange*: notes as objects in space). Here a body is drawn
from what every BodyPose carries — world joint positions and the skeleton's parent
indices — as spheres at joints and cylinders along bones (together: capsules), under one
camera and one light, with NoteObjects as spheres coloured by pitch class.

Drawing is instanced plain OpenGL (:mod:`creatures.body.gl`: one buffer upload and two draw
calls a frame); pyrender, unmaintained upstream since 2021, only provides the offscreen
context and stays behind this module and that one. An offscreen OpenGL platform must be
chosen *before* PyOpenGL is first imported; :func:`gl_platform` respects
``PYOPENGL_PLATFORM`` if set, else tries EGL then OSMesa (each in a throw-away subprocess,
since a failed platform cannot be swapped in-process) and raises :class:`RenderUnavailable`
naming what was tried, so callers carry on without frames.
"""

from __future__ import annotations

import colorsys
import os
import subprocess
import sys
from dataclasses import dataclass
from functools import cache
from typing import Iterable

import numpy as np
from numpy.typing import ArrayLike

RGB = tuple[float, float, float]

PLATFORMS = ("egl", "osmesa")
_PROBE = "import pyrender; pyrender.OffscreenRenderer(8, 8).delete()"


class RenderUnavailable(RuntimeError):
    """No offscreen OpenGL platform: the caller continues without frames."""


@cache
def gl_platform() -> str:
    """The offscreen platform in use, chosen (and exported to ``PYOPENGL_PLATFORM``) once."""
    chosen = os.environ.get("PYOPENGL_PLATFORM")
    if chosen:
        return chosen
    failures = []
    for platform in PLATFORMS:
        try:
            probe = subprocess.run([sys.executable, "-c", _PROBE], capture_output=True, text=True,
                                   timeout=120, env={**os.environ, "PYOPENGL_PLATFORM": platform})
        except subprocess.TimeoutExpired:
            failures.append(f"{platform}: probe timed out")
            continue
        if probe.returncode == 0:
            os.environ["PYOPENGL_PLATFORM"] = platform
            return platform
        last = (probe.stderr.strip().splitlines() or ["no message"])[-1]
        failures.append(f"{platform}: {last}")
    raise RenderUnavailable(
        "no offscreen OpenGL platform for pyrender (" + "; ".join(failures) + "); install EGL "
        "(Debian: libegl1 libegl-mesa0 libgl1-mesa-dri) or OSMesa (libosmesa6), or set PYOPENGL_PLATFORM"
    )


def _context(width: int, height: int) -> object:
    """An offscreen GL context of the chosen platform (pyrender's), made current."""
    platform = gl_platform()
    try:
        if platform == "egl":
            from pyrender.platforms.egl import EGLPlatform as Platform
        elif platform == "osmesa":
            from pyrender.platforms.osmesa import OSMesaPlatform as Platform
        else:
            raise RenderUnavailable(f"PYOPENGL_PLATFORM={platform} is not an offscreen platform (use egl or osmesa)")
    except RenderUnavailable:
        raise
    except Exception as exc:  # PyOpenGL raises ImportError, AttributeError, … per platform
        raise RenderUnavailable(f"pyrender cannot load with PYOPENGL_PLATFORM={platform}: {exc!r}") from None
    try:
        context = Platform(width, height)
        context.init_context()
        context.make_current()
    except Exception as exc:  # EGL/OSMesa errors vary by driver
        raise RenderUnavailable(f"could not open a {platform} context: {exc}") from None
    return context


def _release(context: object) -> None:
    """Destroy a context from :func:`_context`. pyrender's ``delete_context`` also terminates
    the EGL display, which every renderer in the process shares, so on EGL only the context
    goes: another renderer keeps drawing."""
    if gl_platform() != "egl":
        context.delete_context()
        return
    from OpenGL.EGL import eglDestroyContext

    context.make_uncurrent()
    eglDestroyContext(context._egl_display, context._egl_context)


def perspective(yfov: float, aspect: float, znear: float) -> np.ndarray:
    """pyrender's PerspectiveCamera projection without a far plane (depth runs to infinity),
    upside down: GL's first framebuffer row is then the image's top row, so a frame is read
    out without flipping (nothing is culled, so the reversed winding changes nothing)."""
    t = np.tan(yfov / 2.0)
    projection = np.zeros((4, 4))
    projection[0, 0], projection[1, 1] = 1.0 / (aspect * t), -1.0 / t
    projection[2, 2], projection[2, 3], projection[3, 2] = -1.0, -2.0 * znear, -1.0
    return projection


def pitch_colour(pitch: float) -> RGB:
    """RGB for a MIDI pitch: hue walks the circle of pitch classes, octave sets brightness."""
    octave = min(max((pitch // 12 - 2) / 7.0, 0.0), 1.0)
    return colorsys.hsv_to_rgb((pitch % 12) / 12.0, 0.85, 0.45 + 0.55 * octave)


def look_at(eye: ArrayLike, target: ArrayLike, up: ArrayLike = (0.0, 1.0, 0.0)) -> np.ndarray:
    """Camera pose (4×4, OpenGL convention: the camera looks down its −z) from eye to target."""
    eye, target, up = (np.asarray(v, dtype=float) for v in (eye, target, up))
    back = eye - target
    back /= np.linalg.norm(back)
    right = np.cross(up, back)
    right /= np.linalg.norm(right)
    pose = np.eye(4)
    pose[:3, 0], pose[:3, 1], pose[:3, 2], pose[:3, 3] = right, np.cross(back, right), back, eye
    return pose


def _place_spheres(rows: np.ndarray, centres: np.ndarray, radius: float | np.ndarray) -> None:
    """Instance rows (:data:`creatures.body.gl.ROW`) whose transforms take the unit sphere onto
    spheres at ``centres``: scale on the diagonal, centre in the fourth column."""
    rows[:, :16] = 0.0
    for column in (0, 5, 10):
        rows[:, column] = radius
    rows[:, 12:15] = centres
    rows[:, 15] = 1.0


def _place_bones(rows: np.ndarray, a: np.ndarray, b: np.ndarray, radius: float) -> None:
    """Instance rows taking the unit cylinder (radius 1, height 1, along z) onto each bone
    ``a[i] → b[i]`` (columns of the column-major transform: x, y scaled by the radius, z along
    the bone, the midpoint)."""
    axis = b - a
    length = np.linalg.norm(axis, axis=1)
    z = np.where(length[:, None] > 1e-9, axis / np.maximum(length, 1e-9)[:, None], [0.0, 0.0, 1.0])
    helper = np.where(np.abs(z[:, :1]) < 0.9, [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    rows[:, 0:3] = x * radius
    rows[:, 4:7] = np.cross(z, x) * radius
    rows[:, 8:11] = z * length[:, None]
    rows[:, 12:15] = 0.5 * (a + b)
    rows[:, (3, 7, 11)] = 0.0
    rows[:, 15] = 1.0


@dataclass(frozen=True)
class NoteMark:
    """A note object drawn in space (thesis *exchange*): where, which pitch, how big."""

    position: tuple[float, float, float]
    pitch: float
    radius: float = 0.06


class BodyRenderer:
    """Offscreen renderer of skeletons (joint positions + parents) and note marks.

    The camera is framed on the first body drawn (or given as ``camera_pose``) and then
    stays put, so a moving body moves on screen; with ``follow`` it moves along the ground with
    the middle of the bodies' roots (a walking dog stays in the picture; a body with a fixed
    root sees no difference). Materials are pyrender's metallic-roughness
    ones as the first renderer had them: the body metallic with roughness 0.7, notes glowing
    in their pitch colour.

    Example
    -------
    >>> renderer = BodyRenderer(320, 240)          # raises RenderUnavailable without GL
    >>> rgb = renderer.render(pose.positions, skeleton.parents, [NoteMark((0, 1, 0), 60)])
    """

    SPHERE, CYLINDER = 0, 1
    YFOV, ZNEAR = np.pi / 3.5, 0.05
    LIGHT_INTENSITY, AMBIENT = 3.0, (0.25, 0.25, 0.25)
    FLAT = 4.0
    """How many times wider than high a first frame must be to be seen from above (a standing
    person is not; a dog walking 1 m is not; a crowd over a floor is)."""

    def __init__(self, width: int = 640, height: int = 480, *, joint_radius: float = 0.04,
                 bone_radius: float = 0.025, camera_pose: np.ndarray | None = None,
                 body_colour: RGB = (0.85, 0.82, 0.75), background: RGB = (0.08, 0.08, 0.1),
                 follow: bool = False) -> None:
        self._context = _context(width, height)
        import trimesh

        from creatures.body import gl

        self._gl = gl
        self.width, self.height = width, height
        self.joint_radius, self.bone_radius = joint_radius, bone_radius
        self.body_colour, self.background = np.array(body_colour), np.array(background)
        cylinder = trimesh.creation.cylinder(radius=1.0, height=1.0, sections=16)
        try:
            self._meshes = gl.InstancedMeshes(width, height, [gl.SQUARE, (cylinder.vertices, cylinder.vertex_normals,
                                                                          cylinder.faces)],
                                              spheres=frozenset({self.SPHERE}),
                                              framebuffer=self._context.supports_framebuffers())
        except Exception as exc:  # a context without GL 3.3 core, or a driver refusing the shaders
            _release(self._context)
            raise RenderUnavailable(f"OpenGL on {gl_platform()} cannot draw the bodies: {exc}") from None
        self._projection = perspective(self.YFOV, width / height, self.ZNEAR)
        self._camera = np.eye(4) if camera_pose is None else np.asarray(camera_pose, float)
        self._framed = camera_pose is not None
        self._thickness = 1.0  # joints, bones and notes drawn this many times their radii (frame_camera)
        self.follow = follow
        self._anchor: np.ndarray | None = None  # the roots' middle on the ground when first drawn

    @property
    def camera_pose(self) -> np.ndarray:
        """Where the camera (and the light with it) stands: 4×4, looking down its −z."""
        return self._camera.copy()

    def frame_camera(self, positions: np.ndarray) -> None:
        """Aim the camera at a body from the front, far enough to see all of it (and the light
        with it); at a crowd spread over a floor (wider than :data:`FLAT` times its height), from
        45° above: seen from the front, 10° up, fifteen singers across a 14 × 10 m room stood
        in one line. Joints that are not finite are not aimed at (none: the camera waits for a
        body): one NaN joint in the first frame made the camera NaN, and every frame after it blank."""
        positions = positions[np.isfinite(positions).all(axis=1)]
        if not len(positions):
            return
        low, high = positions.min(axis=0), positions.max(axis=0)
        spread = high - low
        centre, size = 0.5 * (low + high), max(float(np.max(spread)), 0.5)
        flat = max(spread[0], spread[2]) > self.FLAT * max(spread[1], 0.1)
        away = np.array([0.25, 1.2, 1.2] if flat else [0.25, 0.3, 1.7]) * size
        self._camera = look_at(centre + away, centre)
        # A bone at least a pixel either side of its axis where the camera aims: 2.5 cm bones
        # 20 m away (a room's crowd in a 320 × 240 frame) were under a pixel and hardly drawn.
        pixel = 2.0 * float(np.linalg.norm(away)) * np.tan(self.YFOV / 2.0) / self.height
        self._thickness = max(1.0, pixel / self.bone_radius)
        self._framed = True

    def _fill(self, positions: np.ndarray, parents: np.ndarray, notes: Iterable[NoteMark]) -> list[int]:
        """Write this frame's instances (joints and notes as spheres, bones as cylinders) into
        the instance rows; returns the count per mesh."""
        gl, meshes = self._gl, self._meshes
        notes = list(notes)
        child = np.flatnonzero(parents >= 0)
        counts = [len(positions) + len(notes), len(child)]
        if any(c > cap for c, cap in zip(counts, meshes.capacities)):
            meshes.reserve([max(c, cap) * 2 for c, cap in zip(counts, meshes.capacities)])
        spheres = meshes.instances[meshes.offsets[self.SPHERE]:][:counts[self.SPHERE]]
        joints, marks = spheres[:len(positions)], spheres[len(positions):]
        _place_spheres(joints, positions, self.joint_radius * self._thickness)
        joints[:, gl.BASE], joints[:, gl.EMISSIVE], joints[:, gl.ROUGHNESS] = self.body_colour, 0.0, 0.7
        if notes:
            _place_spheres(marks, [n.position for n in notes], self._thickness * np.array([n.radius for n in notes]))
            colours = np.array([pitch_colour(int(round(n.pitch))) for n in notes])
            marks[:, gl.BASE], marks[:, gl.EMISSIVE], marks[:, gl.ROUGHNESS] = colours, colours, 1.0
        spheres[:, gl.METALLIC] = 1.0
        if len(child):
            bones = meshes.instances[meshes.offsets[self.CYLINDER]:][:counts[self.CYLINDER]]
            _place_bones(bones, positions[parents[child]], positions[child], self.bone_radius * self._thickness)
            bones[:, gl.BASE], bones[:, gl.EMISSIVE] = self.body_colour, 0.0
            bones[:, gl.ROUGHNESS], bones[:, gl.METALLIC] = 0.7, 1.0
        return counts

    def _draw(self, positions: ArrayLike, parents: ArrayLike, notes: Iterable[NoteMark]) -> None:
        positions = np.asarray(positions, dtype=float)
        parents = np.asarray(parents)
        if positions.ndim != 2 or positions.shape[1] != 3 or len(parents) != len(positions):
            raise ValueError(f"need positions (J, 3) and parents (J,), got {positions.shape} and {parents.shape}")
        if not self._framed:
            self.frame_camera(positions)
        counts = self._fill(positions, parents, notes)
        self._context.make_current()  # another renderer's context may have been current
        camera = self._camera
        roots = positions[parents < 0]
        roots = roots[np.isfinite(roots).all(axis=1)]
        if self.follow and len(roots):  # a root not finite neither moves the camera nor anchors it
            middle = roots.mean(axis=0) * np.array([1.0, 0.0, 1.0])
            if self._anchor is None:
                self._anchor = middle
            camera = camera.copy()
            camera[:3, 3] += middle - self._anchor
        self._meshes.draw(counts, np.linalg.inv(camera), self._projection, camera[:3, 3],
                          -camera[:3, 2], np.full(3, self.LIGHT_INTENSITY), np.array(self.AMBIENT), self.background)

    def render(self, positions: ArrayLike, parents: ArrayLike, notes: Iterable[NoteMark] = (), *,
               out: np.ndarray | None = None) -> np.ndarray:
        """RGB image ``(height, width, 3)`` uint8 of the body and notes; into ``out`` if given
        (a frame loop that passes the same array allocates nothing per frame)."""
        self._draw(positions, parents, notes)
        return self._meshes.read_colour(np.empty((self.height, self.width, 3), np.uint8) if out is None else out)

    def render_with_depth(self, positions: ArrayLike, parents: ArrayLike,
                          notes: Iterable[NoteMark] = ()) -> tuple[np.ndarray, np.ndarray]:
        """RGB and depth (distance along the view axis, as pyrender gave it); ``depth > 0`` is
        the silhouette of everything drawn."""
        self._draw(positions, parents, notes)
        colour = self._meshes.read_colour(np.empty((self.height, self.width, 3), np.uint8))
        window = self._meshes.read_depth()
        drawn = window < 1.0
        depth = np.zeros(window.shape, np.float32)
        depth[drawn] = self.ZNEAR / (1.0 - window[drawn])  # the infinite projection's inverse
        return colour, depth

    def close(self) -> None:
        self._context.make_current()
        self._meshes.delete()
        _release(self._context)

    def __enter__(self) -> BodyRenderer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
