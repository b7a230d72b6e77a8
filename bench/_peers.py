"""Peers measured in the same run: what a user would use instead, timed beside ours.

A ratio to a peer only means something when both sides run on the same machine at the same
moment, so each peer is run by the benchmark itself; where it is not installed the row says
so (:func:`skipped`) instead of carrying a number from elsewhere.
"""

from __future__ import annotations

import re
import resource
import shutil
import subprocess
import tempfile
import time
from pathlib import Path
from typing import Callable

from bench import Row, best_of


def best_cpu_of(fn: Callable[[], object], *, repeat: int = 2) -> float:
    """Smallest CPU time (user + system, this process) of ``repeat`` calls of ``fn``.

    Where a row sets two single-threaded programs side by side (ours and a peer's), CPU time is
    what both are charged with on a shared machine: wall time would add whatever else waited
    for the core at that moment, differently for each side."""
    return best_of(fn, repeat=repeat, clock=time.process_time)


def skipped(name: str, reason: str) -> Row:
    """A row for a peer that could not be measured: no number (NaN), the reason in its name."""
    return Row(f"{name}: skipped ({reason})", float("nan"), "")


CSOUND_STRING = """<CsoundSynthesizer>
<CsOptions>
-n -d -m0
</CsOptions>
<CsInstruments>
sr = {sample_rate}
ksmps = {ksmps}
nchnls = 1
0dbfs = 1
gimass ftgen 0, 0, {masses}, -7, {mass}, {masses}, {mass}
gistiff ftgen 0, 0, {masses}, -7, {stiffness}, {masses}, {stiffness}
gidamp ftgen 0, 0, {masses}, -7, {damp}, {masses}, {damp}
instr 1
ipoint ftgentmp 0, 0, {masses}, 10, 1
ivel ftgentmp 0, 0, {masses}, -7, 0, {masses}, 0
a1 scantable 0.5, p4, ipoint, gimass, gistiff, gidamp, ivel
out a1
endin
</CsInstruments>
<CsScore>
{score}
</CsScore>
</CsoundSynthesizer>
"""
"""Csound's ``scantable`` (Matt Gilliard's opcode, Opcodes/wave-terrain.c): a ring of masses
updated once per k-cycle — ``v ← (v + stiffness·Δx/(mass·kr))·damp``, ``x ← x + v/kr`` — and
read without interpolation at audio rate. Each instance gets its own position and velocity
tables (``ftgentmp``), since the opcode writes them in place; mass, stiffness and damping
tables are shared and only read."""


def csound_string_seconds(*, voices: int, seconds: float, masses: int, sample_rate: int, haptic_rate: int,
                          mass: float, stiffness: float, damp: float, repeat: int = 2) -> float | None:
    """CPU time (user + system, as :func:`best_cpu_of` charges ours) Csound takes to render
    ``voices`` ``scantable`` strings for ``seconds`` (``csound -n``: no sound file written),
    less that of the same orchestra with an empty score of the same length (start-up, table
    set-up, the empty k-loop), best of ``repeat``. None when ``csound`` is not installed."""
    if shutil.which("csound") is None:
        return None
    ksmps = sample_rate // haptic_rate
    if ksmps * haptic_rate != sample_rate:
        raise ValueError(f"Csound updates the string once per k-cycle: {sample_rate} Hz / {haptic_rate} Hz must be whole")
    notes = "\n".join(f"i1 0 {seconds} {110.0 + 0.37 * k:.3f}" for k in range(voices))
    fields = dict(sample_rate=sample_rate, ksmps=ksmps, masses=masses, mass=mass, stiffness=stiffness, damp=damp)
    with tempfile.TemporaryDirectory() as tmp:
        full, empty = Path(tmp) / "strings.csd", Path(tmp) / "empty.csd"
        full.write_text(CSOUND_STRING.format(score=notes, **fields))
        empty.write_text(CSOUND_STRING.format(score=f"f0 {seconds}", **fields))
        return _best_run(full, repeat) - _best_run(empty, repeat)


def csound_version() -> str:
    """The installed Csound's version as it gives it (``csound --version``: "6.18"), for the
    rows that name the peer they measured."""
    done = subprocess.run(["csound", "--version"], capture_output=True, text=True)
    found = re.search(r"Csound version (\d+(?:\.\d+)*)", done.stdout + done.stderr)
    return found[1] if found else "(version unknown)"


def _best_run(csd: Path, repeat: int) -> float:
    best = float("inf")
    for _ in range(repeat):
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        done = subprocess.run(["csound", str(csd)], capture_output=True, text=True)
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        elapsed = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
        if done.returncode != 0:
            raise RuntimeError(f"csound failed on {csd.name}: {done.stderr.strip().splitlines()[-3:]}")
        best = min(best, elapsed)
    return best


class PyrenderBodies:
    """The bodies drawn with pyrender as :mod:`creatures.body.render` drew them before it
    drew instanced GL itself: per frame, one instanced pyrender mesh per kind (joints, bones,
    notes of one pitch) added to a scene and rendered offscreen (4× multisampled, colour and
    depth read back). Same meshes, camera, light and materials."""

    def __init__(self, width: int, height: int, camera_pose, *, joint_radius: float = 0.04,
                 bone_radius: float = 0.025) -> None:
        import pyrender
        import trimesh

        from creatures.body.render import BodyRenderer

        self._pr = pyrender
        self.joint_radius, self.bone_radius = joint_radius, bone_radius
        self._body = pyrender.MetallicRoughnessMaterial(baseColorFactor=(0.85, 0.82, 0.75, 1.0), roughnessFactor=0.7)
        self._sphere = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
        self._cylinder = trimesh.creation.cylinder(radius=1.0, height=1.0, sections=16)
        self.scene = pyrender.Scene(bg_color=(0.08, 0.08, 0.1, 1.0), ambient_light=(0.25, 0.25, 0.25))
        self.scene.add(pyrender.PerspectiveCamera(yfov=BodyRenderer.YFOV, aspectRatio=width / height), pose=camera_pose)
        self.scene.add(pyrender.DirectionalLight(intensity=3.0), pose=camera_pose)
        self._nodes: list = []
        self._renderer = pyrender.OffscreenRenderer(width, height)

    def render(self, positions, parents, notes):
        import numpy as np

        from creatures.body.render import _place_bones, _place_spheres, pitch_colour

        def matrices(place, *args):
            rows = np.zeros((len(args[0]), 24), np.float32)
            place(rows, *args)
            return rows[:, :16].reshape(-1, 4, 4).transpose(0, 2, 1)

        for node in self._nodes:
            self.scene.remove_node(node)
        meshes = [(self._sphere, self._body, matrices(_place_spheres, positions, self.joint_radius))]
        child = np.flatnonzero(parents >= 0)
        meshes.append((self._cylinder, self._body,
                       matrices(_place_bones, positions[parents[child]], positions[child], self.bone_radius)))
        by_pitch: dict[int, list] = {}
        for note in notes:
            by_pitch.setdefault(int(round(note.pitch)), []).append(note)
        for pitch, marks in by_pitch.items():
            colour = pitch_colour(pitch)
            material = self._pr.MetallicRoughnessMaterial(baseColorFactor=(*colour, 1.0), emissiveFactor=colour)
            meshes.append((self._sphere, material, matrices(_place_spheres, [m.position for m in marks],
                                                            np.array([m.radius for m in marks]))))
        self._nodes = [self.scene.add(self._pr.Mesh.from_trimesh(mesh, material=material, poses=poses))
                       for mesh, material, poses in meshes]
        return self._renderer.render(self.scene)[0]

    def close(self) -> None:
        self._renderer.delete()
