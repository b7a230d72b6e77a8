"""Voices: how many scanned strings one core runs in real time, beside Csound, and render speed.

Rows (``python -m bench voice``):

* strings in real time at 48 kHz with 1 kHz physics (a :class:`~audio.voices.VoicePool`, the
  path a creature's voice takes), beside Csound's ``scantable`` (6.18 here) rendering the same
  strings in the same run (:mod:`bench._peers`): 128 masses, then 1, 3, 64 and 1,024, each
  with the target ≥ 1.5× Csound; at 128 masses also with ours' default linear interpolation,
  which does more per sample than ``scantable`` (none of its notes, MIDI 40–87 at 48 kHz, has a
  band of fewer than 16 harmonics, so none is band-limited: :mod:`audio.bandlimit`). One mass on a ring is its own neighbour in
  both (its spring pulls on nothing; Csound's 1-point table reads one word before each table
  for that neighbour, which holds no stiffness here) and the scan reads the same point every
  sample: no pitch, but the same work per sample as any string, which is what the row times;
* one string rendered alone (``ScannedString.render``, the reference kernel), a plain numpy
  sine-table oscillator (the cheapest possible voice), and the same string vectorised in numpy
  over the masses (a Python loop over haptic frames) — the measurement behind numba;
* body frames per second at 640×480, one body and three (target ≥ 120 frames/s), drawn by
  :mod:`creatures.body.render` (instanced GL) beside pyrender drawing the same scene the way
  the renderer used to (:class:`bench._peers.PyrenderBodies`), when a GL platform exists.

Equal physics with ``scantable``: the same masses on a ring, one update per millisecond
(``ksmps`` 48 at 48 kHz), ``stiffness``/``mass``/damping giving the same step (its ``damp``
factor is our ``1 − γh``), output at 48 kHz, and the same reading of the shape
(``interpolation = "none"``: the nearest mass of the latest frame). Ours still does more per
sample and per step: centring, a DC blocker and an envelope, pushes from a moving body
(:class:`~audio.coupling.BodyCoupling`, forces recomputed every 40 ms tick), and a stability
check when the string was built.

The voice rows run under :func:`one_core` (the target is per core; Csound inherits the pin),
and the rows beside Csound compare CPU time (:func:`bench._peers.best_cpu_of`; Csound's from
its process's rusage), which a loaded machine charges both sides alike. The render rows are
wall time and not pinned, since the GL driver's own threads are part of what a frame costs.
"""

from __future__ import annotations

import contextlib
import os
from types import SimpleNamespace
from typing import Iterator

import numpy as np
from threadpoolctl import threadpool_limits

from audio.coupling import BodyCoupling
from audio.scanned import ScannedString, StringParameters
from audio.voices import VoicePool
from bench import Row, best_of
from bench._peers import best_cpu_of, csound_string_seconds, csound_version, skipped

SR = 48000
BLOCK = 512


@contextlib.contextmanager
def one_core() -> Iterator[None]:
    """Run the block pinned to one CPU with one BLAS/OpenMP thread, then restore both.

    Targets say "on one core", and a ratio only means something when both sides get the same
    machine: unpinned, a baseline that reaches threaded BLAS (librosa's mel projection, in
    ``bench/hearing.py``) would use every core while the measured path uses one. Where the OS
    cannot pin (macOS, Windows) the thread pools are still limited.
    """
    with threadpool_limits(limits=1):
        if not hasattr(os, "sched_setaffinity"):
            yield
            return
        cpus = os.sched_getaffinity(0)
        os.sched_setaffinity(0, {min(cpus)})
        try:
            yield
        finally:
            os.sched_setaffinity(0, cpus)


def _plucked() -> ScannedString:
    string = ScannedString(StringParameters(n_masses=128), sample_rate=SR, frequency=220.0)
    string.pluck(amplitude=0.5)
    return string


def _scanned_second(string: ScannedString, out: np.ndarray) -> None:
    for _ in range(SR // BLOCK):
        string.render(BLOCK, out=out)


def _sine_table_second(table: np.ndarray, out: np.ndarray) -> None:
    phase = 0.0
    step = 220.0 * len(table) / SR
    ramp = np.arange(BLOCK) * step
    for _ in range(SR // BLOCK):
        np.take(table, (phase + ramp).astype(np.int64) % len(table), out=out)
        phase = (phase + BLOCK * step) % len(table)


def _numpy_scanned_second(p: StringParameters) -> None:
    """The ScannedString model vectorised over masses and samples, looping over haptic frames."""
    x, v = _plucked().x.copy(), np.zeros(p.n_masses)
    h, gamma = 1.0 / p.haptic_rate, p.damping / p.mass
    per_frame = int(SR / p.haptic_rate)
    alpha = (np.arange(per_frame) / per_frame)[:, None]
    positions = (np.arange(per_frame) * 220.0 / SR % 1.0) * (p.n_masses + 1)
    j = positions.astype(np.int64)
    a = positions - j
    for _ in range(int(p.haptic_rate)):
        x_prev = x.copy()
        padded = np.concatenate([[0.0], x, [0.0]])
        v = (1.0 - gamma * h) * v + h / p.mass * (p.stiffness * (padded[:-2] - 2 * x + padded[2:]) - p.centring * x)
        x = x + h * v
        shape = np.concatenate([np.zeros((per_frame, 1)), x_prev + alpha * (x - x_prev)], axis=1)
        rows = np.arange(per_frame)
        y0 = shape[rows, j % (p.n_masses + 1)]
        y1 = shape[rows, (j + 1) % (p.n_masses + 1)]
        np.tanh(y0 + a * (y1 - y0))


def _figures(count: int) -> tuple[np.ndarray, np.ndarray, list]:
    """``count`` 11-joint stick figures 1.5 m apart, and two notes per figure."""
    from creatures.body.render import NoteMark

    parents = np.array([-1, 0, 1, 1, 3, 1, 5, 0, 7, 0, 9])
    body = np.array([[0, 1, 0], [0, 1.5, 0], [0, 1.8, 0], [-0.3, 1.45, 0], [-0.6, 1.2, 0], [0.3, 1.45, 0],
                     [0.6, 1.2, 0], [-0.15, 0.5, 0], [-0.15, 0, 0], [0.15, 0.5, 0], [0.15, 0, 0]], float)
    shifts = (np.arange(count) - (count - 1) / 2) * 1.5
    positions = np.concatenate([body + [dx, 0.0, 0.0] for dx in shifts])
    all_parents = np.concatenate([np.where(parents >= 0, parents + len(body) * k, -1) for k in range(count)])
    notes = [NoteMark((dx + 0.4 * side, 2.1, 0.0), 60 + 2 * k + (side > 0)) for k, dx in enumerate(shifts)
             for side in (-1, 1)]
    return positions, all_parents, notes


def _render_rows(quick: bool) -> list[Row]:
    """Frames per second at 640×480, ours beside pyrender drawing the same scene in this run."""
    from creatures.body.render import BodyRenderer, RenderUnavailable

    from bench._peers import PyrenderBodies

    frames = 20 if quick else 100
    rows: list[Row] = []
    for count in (1, 3):
        positions, parents, notes = _figures(count)
        what = f"{'one body' if count == 1 else f'{count} bodies'} at 640x480 ({len(positions)} joints, {len(notes)} notes)"
        try:
            renderer = BodyRenderer(640, 480)
        except RenderUnavailable as exc:
            return [skipped("body frames", str(exc))]
        out = np.empty((480, 640, 3), np.uint8)
        with renderer:
            renderer.render(positions, parents, notes, out=out)  # frames the camera, compiles shaders
            camera = renderer.camera_pose
            ours = frames / best_of(lambda: [renderer.render(positions + 0.01 * i, parents, notes, out=out)
                                             for i in range(frames)], repeat=2)
        row = Row(f"{what}, instanced GL", ours, "frames/s", target=120.0 if count == 3 else None)
        try:
            peer = PyrenderBodies(640, 480, camera)
        except (ImportError, OSError, RuntimeError, ValueError) as exc:  # not installed, or no GL platform for it
            rows += [row, skipped(f"{what}, pyrender", f"{type(exc).__name__}: {exc}")]
            continue
        slow_frames = max(frames // 4, 5)  # pyrender is slower
        peer.render(positions, parents, notes)
        theirs = slow_frames / best_of(lambda: [peer.render(positions + 0.01 * i, parents, notes)
                                                for i in range(slow_frames)], repeat=2)
        peer.close()
        row.baseline, row.ratio = "pyrender", ours / theirs
        rows += [row, Row(f"{what}, pyrender (peer, same run)", theirs, "frames/s")]
    return rows


PEER_PHYSICS = dict(mass=1.0, stiffness=800.0, damping=0.5, centring=4.0, haptic_rate=1000.0, ring=True)
"""The defaults of :class:`StringParameters` on Csound's topology (a ring) and update rate (1 kHz)."""

TICK = 40e-3
"""How often the body pushes the strings (a behaviour tick)."""


def _pool_seconds(masses: int, voices: int, seconds: float, repeat: int, interpolation: str) -> float:
    """CPU time a VoicePool of ``voices`` sounding strings takes to render ``seconds`` at 48 kHz
    in 512-sample blocks, a moving arm pushing every string once per :data:`TICK`."""
    parameters = StringParameters(n_masses=masses, interpolation=interpolation, **PEER_PHYSICS)
    pool = VoicePool(voices, parameters, sample_rate=SR, block_size=BLOCK)
    for k in range(voices):
        pool.note_on(40 + k % 48, 0.5)
    coupling = BodyCoupling.along((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), masses, radius=0.2, gain=50.0)
    out = np.empty(BLOCK)
    pool.render(out)  # JIT (or load the numba cache) before timing
    blocks = int(seconds * SR / BLOCK)
    per_tick = max(int(TICK * SR / BLOCK), 1)
    sounding = np.arange(voices)

    def play() -> None:
        for b in range(blocks):
            if b % per_tick == 0:
                t = b * BLOCK / SR
                hand = SimpleNamespace(positions=np.array([[0.5 + 0.3 * np.sin(3.0 * t), 0.1 + 0.1 * np.cos(5.0 * t), 0.0]]),
                                       time=t)
                pool.bank.push(sounding, coupling.forces(hand))
            pool.render(out)

    return best_cpu_of(play, repeat=repeat)


REPEAT = 3
"""Best of three for both sides of a row beside Csound: on a shared machine one run in two was
disturbed (the same kernel measured 0.9 and 1.4 ns a string-sample minutes apart)."""


def _peer_rows(quick: bool) -> list[Row]:
    """Ours beside Csound's scantable for each string size: at equal physics (no interpolation,
    as scantable), and at 128 masses also with ours' default linear interpolation."""
    rows: list[Row] = []
    damp = 1.0 - PEER_PHYSICS["damping"] / PEER_PHYSICS["mass"] / PEER_PHYSICS["haptic_rate"]
    seconds = 2.0 if quick else 10.0
    for masses, voices in ((128, 512), (1, 512), (3, 512), (64, 512), (1024, 64)):
        voices = voices // 4 if quick else voices
        what = f"{masses}-mass strings in real time @48 kHz, 1 kHz physics"
        why = "csound not installed"
        try:
            theirs = csound_string_seconds(voices=voices, seconds=seconds, masses=masses, sample_rate=SR,
                                           haptic_rate=int(PEER_PHYSICS["haptic_rate"]), mass=PEER_PHYSICS["mass"],
                                           stiffness=PEER_PHYSICS["stiffness"], damp=damp, repeat=REPEAT)
        except RuntimeError as exc:  # installed, but it would not render the orchestra
            theirs, why = None, str(exc)
        peer = None if theirs is None else voices * seconds / theirs
        for interpolation in ("none", "linear") if masses == 128 else ("none",):
            ours = voices * seconds / _pool_seconds(masses, voices, seconds, REPEAT, interpolation)
            label = f"{what}, interpolation {interpolation} (VoicePool)"
            if peer is None:
                rows.append(Row(label, ours, "voices"))
                continue
            equal = interpolation == "none"  # scantable reads the nearest mass of the latest frame
            rows.append(Row(label, ours, "voices", target=1.5 * peer if equal else None,
                            baseline="Csound scantable" + ("" if equal else " (no interp.)"), ratio=ours / peer))
        rows.append(skipped(f"{what}, Csound scantable", why) if peer is None else
                    Row(f"{what} (Csound {csound_version()} scantable, same run)", peer, "voices"))
    return rows


def run(quick: bool) -> list[Row]:
    string, out = _plucked(), np.empty(BLOCK)
    string.render(BLOCK, out=out)  # JIT (or load the numba cache) before timing
    repeat = 2 if quick else 5
    table = np.sin(2 * np.pi * np.arange(4096) / 4096)
    with one_core():
        peers = _peer_rows(quick)
        scanned = 1.0 / best_of(lambda: _scanned_second(string, out), repeat=repeat)
        sine = 1.0 / best_of(lambda: _sine_table_second(table, out), repeat=repeat)
        vectorised = 1.0 / best_of(lambda: _numpy_scanned_second(string.parameters), repeat=1 if quick else 2)
    rows = [
        *peers,
        Row("128-mass string rendered alone (ScannedString, 500 Hz physics)", scanned, "voices", target=50.0,
            baseline="numpy sine-table voices", ratio=scanned / sine),
        Row("numpy sine-table oscillators in real time @48 kHz", sine, "voices"),
        Row("same string vectorised in numpy (not used)", vectorised, "voices",
            baseline="numba kernel", ratio=vectorised / scanned),
    ]
    return rows + _render_rows(quick)
