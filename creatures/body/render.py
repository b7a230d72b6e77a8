"""The rendered body: a creature's skeleton and its notes drawn offscreen with pyrender.

The thesis' creatures are seen as well as heard (*soundcreatures*: "each creature has a
graphical representation"; *exchange*: notes as objects in space). Here a body is drawn
from what every BodyPose carries — world joint positions and the skeleton's parent
indices — as spheres at joints and cylinders along bones (together: capsules), under one
camera and one light, with NoteObjects as spheres coloured by pitch class.

pyrender is unmaintained upstream since 2021, so it stays behind this one module. It needs
an offscreen OpenGL platform chosen *before* PyOpenGL is first imported; :func:`gl_platform`
respects ``PYOPENGL_PLATFORM`` if set, else tries EGL then OSMesa (each in a throw-away
subprocess, since a failed platform cannot be swapped in-process) and raises
:class:`RenderUnavailable` naming what was tried, so callers carry on without frames.
"""

from __future__ import annotations

import colorsys
import os
import subprocess
import sys
from dataclasses import dataclass
from functools import cache
from types import ModuleType
from typing import TYPE_CHECKING, Iterable

import numpy as np
from numpy.typing import ArrayLike

if TYPE_CHECKING:  # imported for real only once a GL platform is chosen (see _pyrender)
    import pyrender
    import trimesh

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


def _pyrender() -> ModuleType:
    platform = gl_platform()
    try:
        import pyrender
    except Exception as exc:  # PyOpenGL raises ImportError, AttributeError, … per platform
        raise RenderUnavailable(f"pyrender cannot load with PYOPENGL_PLATFORM={platform}: {exc!r}") from None
    return pyrender


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


def _bone_matrices(a: np.ndarray, b: np.ndarray, radius: float) -> np.ndarray:
    """Transforms ``(N, 4, 4)`` taking the unit cylinder (radius 1, height 1, along z) onto
    each bone ``a[i] → b[i]``."""
    axis = b - a
    length = np.linalg.norm(axis, axis=1)
    z = np.where(length[:, None] > 1e-9, axis / np.maximum(length, 1e-9)[:, None], [0.0, 0.0, 1.0])
    helper = np.where(np.abs(z[:, :1]) < 0.9, [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    matrices = np.zeros((len(a), 4, 4))
    matrices[:, :3, 0] = x * radius
    matrices[:, :3, 1] = np.cross(z, x) * radius
    matrices[:, :3, 2] = z * length[:, None]
    matrices[:, :3, 3] = 0.5 * (a + b)
    matrices[:, 3, 3] = 1.0
    return matrices


def _sphere_matrices(centres: np.ndarray, radius: float | np.ndarray) -> np.ndarray:
    """Transforms ``(N, 4, 4)`` taking the unit sphere onto spheres at ``centres``."""
    centres = np.asarray(centres, dtype=float).reshape(-1, 3)
    matrices = np.zeros((len(centres), 4, 4))
    matrices[:, [0, 1, 2], [0, 1, 2]] = np.broadcast_to(np.asarray(radius, float).reshape(-1, 1), (len(centres), 3))
    matrices[:, :3, 3] = centres
    matrices[:, 3, 3] = 1.0
    return matrices


@dataclass(frozen=True)
class NoteMark:
    """A note object drawn in space (thesis *exchange*): where, which pitch, how big."""

    position: tuple[float, float, float]
    pitch: float
    radius: float = 0.06


class BodyRenderer:
    """Offscreen renderer of skeletons (joint positions + parents) and note marks.

    The camera is framed on the first body drawn (or given as ``camera_pose``) and then
    stays put, so a moving body moves on screen.

    Example
    -------
    >>> renderer = BodyRenderer(320, 240)          # raises RenderUnavailable without GL
    >>> rgb = renderer.render(pose.positions, skeleton.parents, [NoteMark((0, 1, 0), 60)])
    """

    def __init__(self, width: int = 640, height: int = 480, *, joint_radius: float = 0.04,
                 bone_radius: float = 0.025, camera_pose: np.ndarray | None = None,
                 body_colour: RGB = (0.85, 0.82, 0.75), background: RGB = (0.08, 0.08, 0.1)) -> None:
        pyrender = _pyrender()
        import trimesh

        self._pr = pyrender
        self.joint_radius, self.bone_radius = joint_radius, bone_radius
        self._body = pyrender.MetallicRoughnessMaterial(baseColorFactor=(*body_colour, 1.0), roughnessFactor=0.7)
        self._sphere = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
        self._cylinder = trimesh.creation.cylinder(radius=1.0, height=1.0, sections=16)
        self._note_materials: dict[int, pyrender.MetallicRoughnessMaterial] = {}
        self.scene = pyrender.Scene(bg_color=(*background, 1.0), ambient_light=(0.25, 0.25, 0.25))
        self._camera = self.scene.add(pyrender.PerspectiveCamera(yfov=np.pi / 3.5, aspectRatio=width / height),
                                      pose=np.eye(4) if camera_pose is None else camera_pose)
        self._light = self.scene.add(pyrender.DirectionalLight(intensity=3.0), pose=np.eye(4))
        self._framed = camera_pose is not None
        if self._framed:
            self.scene.set_pose(self._light, camera_pose)
        self._frame_nodes: list[pyrender.Node] = []  # this frame's instanced meshes (joints, bones, notes by pitch)
        try:
            self._renderer = pyrender.OffscreenRenderer(width, height)
        except Exception as exc:  # pyglet/EGL errors vary by platform
            raise RenderUnavailable(f"pyrender could not open a {gl_platform()} context: {exc}") from None

    def frame_camera(self, positions: np.ndarray) -> None:
        """Aim the camera at a body from the front, far enough to see all of it (and the light with it)."""
        low, high = positions.min(axis=0), positions.max(axis=0)
        centre, size = 0.5 * (low + high), max(float(np.max(high - low)), 0.5)
        pose = look_at(centre + np.array([0.25, 0.3, 1.7]) * size, centre)
        self.scene.set_pose(self._camera, pose)
        self.scene.set_pose(self._light, pose)
        self._framed = True

    def _instanced(self, mesh: trimesh.Trimesh, material: pyrender.Material, matrices: np.ndarray) -> None:
        """One scene node drawing ``mesh`` at every transform: one draw call per frame
        instead of one per joint, bone or note (pyrender's per-node GL calls dominated,
        ~165 ms a frame for three bodies)."""
        node = self.scene.add(self._pr.Mesh.from_trimesh(mesh, material=material, poses=matrices))
        self._frame_nodes.append(node)

    def _note_material(self, pitch: int) -> pyrender.MetallicRoughnessMaterial:
        if pitch not in self._note_materials:
            self._note_materials[pitch] = self._pr.MetallicRoughnessMaterial(
                baseColorFactor=(*pitch_colour(pitch), 1.0), emissiveFactor=pitch_colour(pitch))
        return self._note_materials[pitch]

    def render(self, positions: ArrayLike, parents: ArrayLike, notes: Iterable[NoteMark] = ()) -> np.ndarray:
        """RGB image ``(height, width, 3)`` uint8 of the body and notes."""
        return self.render_with_depth(positions, parents, notes)[0]

    def render_with_depth(self, positions: ArrayLike, parents: ArrayLike,
                          notes: Iterable[NoteMark] = ()) -> tuple[np.ndarray, np.ndarray]:
        """RGB and depth; ``depth > 0`` is the silhouette of everything drawn."""
        positions = np.asarray(positions, dtype=float)
        parents = np.asarray(parents)
        if positions.ndim != 2 or positions.shape[1] != 3 or len(parents) != len(positions):
            raise ValueError(f"need positions (J, 3) and parents (J,), got {positions.shape} and {parents.shape}")
        if not self._framed:
            self.frame_camera(positions)
        for node in self._frame_nodes:
            self.scene.remove_node(node)
        self._frame_nodes = []
        self._instanced(self._sphere, self._body, _sphere_matrices(positions, self.joint_radius))
        child = np.flatnonzero(parents >= 0)
        if len(child):
            self._instanced(self._cylinder, self._body,
                            _bone_matrices(positions[parents[child]], positions[child], self.bone_radius))
        by_pitch: dict[int, list[NoteMark]] = {}
        for n in notes:
            by_pitch.setdefault(int(round(n.pitch)), []).append(n)
        for pitch, marks in by_pitch.items():
            self._instanced(self._sphere, self._note_material(pitch),
                            _sphere_matrices([m.position for m in marks], np.array([m.radius for m in marks])))
        return self._renderer.render(self.scene)

    def close(self) -> None:
        self._renderer.delete()

    def __enter__(self) -> BodyRenderer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
