"""Voices: how many scanned strings one core runs in real time, beside Csound, and render speed.

Rows (``python -m bench voice``):

* strings in real time at 48 kHz with 1 kHz physics (a :class:`~audio.voices.VoicePool`, the
  path a creature's voice takes), beside Csound 6.18's ``scantable`` rendering the same
  strings in the same run (:mod:`bench._peers`): 128 masses (target ≥ 1.5× Csound), then 3
  (the fewest a string may have), 64 and 1,024;
* one string rendered alone (``ScannedString.render``, the reference kernel), a plain numpy
  sine-table oscillator (the cheapest possible voice), and the same string vectorised in numpy
  over the masses (a Python loop over haptic frames) — the measurement behind numba;
* body frames per second at 640×480 (pyrender offscreen), when a GL platform exists.

Equal physics with ``scantable``: the same masses on a ring, one update per millisecond
(``ksmps`` 48 at 48 kHz), ``stiffness``/``mass``/damping giving the same step (its ``damp``
factor is our ``1 − γh``), output at 48 kHz. Ours does more per sample and per step: it
interpolates linearly along the string and between haptic frames (``scantable`` reads the
nearest mass of the current frame), applies centring, a DC blocker and an envelope, is pushed
by a moving body (:class:`~audio.coupling.BodyCoupling`, forces recomputed every 40 ms tick)
and was checked against the stability bound when built.

The voice rows run under :func:`one_core` (the target is per core; Csound inherits the pin);
the render row does not, since the GL driver's own threads are part of what a frame costs.
"""

from __future__ import annotations

import contextlib
import os
import sys
from types import SimpleNamespace
from typing import Iterator

import numpy as np
from threadpoolctl import threadpool_limits

from audio.coupling import BodyCoupling
from audio.scanned import ScannedString, StringParameters
from audio.voices import VoicePool
from bench import Row, best_of
from bench._peers import csound_string_seconds, skipped

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


def _render_fps(quick: bool) -> Row | None:
    from creatures.body.render import BodyRenderer, NoteMark, RenderUnavailable

    parents = np.array([-1, 0, 1, 1, 3, 1, 5, 0, 7, 0, 9])
    body = np.array([[0, 1, 0], [0, 1.5, 0], [0, 1.8, 0], [-0.3, 1.45, 0], [-0.6, 1.2, 0], [0.3, 1.45, 0],
                     [0.6, 1.2, 0], [-0.15, 0.5, 0], [-0.15, 0, 0], [0.15, 0.5, 0], [0.15, 0, 0]], float)
    notes = [NoteMark((0.8, 1.6, 0.0), 60 + i) for i in range(4)]
    try:
        renderer = BodyRenderer(640, 480)
    except RenderUnavailable as exc:
        print(f"voice: render row skipped: {exc}", file=sys.stderr)
        return None
    frames = 10 if quick else 40
    with renderer:
        renderer.render(body, parents, notes)  # warm: uploads meshes
        seconds = best_of(lambda: [renderer.render(body + 0.01 * i, parents, notes) for i in range(frames)], repeat=2)
    return Row("body frames at 640x480 (11 joints, 4 notes)", frames / seconds, "frames/s")


PEER_PHYSICS = dict(mass=1.0, stiffness=800.0, damping=0.5, centring=4.0, haptic_rate=1000.0, ring=True)
"""The defaults of :class:`StringParameters` on Csound's topology (a ring) and update rate (1 kHz)."""

TICK = 40e-3
"""How often the body pushes the strings (a behaviour tick)."""


def _pool_seconds(masses: int, voices: int, seconds: float, repeat: int) -> float:
    """Wall time a VoicePool of ``voices`` sounding strings takes to render ``seconds`` at 48 kHz
    in 512-sample blocks, a moving arm pushing every string once per :data:`TICK`."""
    parameters = StringParameters(n_masses=masses, **PEER_PHYSICS)
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
                hand = SimpleNamespace(positions=np.array([[0.5 + 0.3 * np.sin(3.0 * t), 0.1, 0.0]]), time=t)
                pool.bank.push(sounding, coupling.forces(hand))
            pool.render(out)

    return best_of(play, repeat=repeat)


def _peer_rows(quick: bool) -> list[Row]:
    """Ours beside Csound's scantable, at equal physics, for each string size."""
    rows: list[Row] = []
    damp = 1.0 - PEER_PHYSICS["damping"] / PEER_PHYSICS["mass"] / PEER_PHYSICS["haptic_rate"]
    seconds = 2.0 if quick else 10.0
    for masses, voices in ((128, 512), (3, 512), (64, 512), (1024, 64)):
        voices = voices // 4 if quick else voices
        what = f"{masses}-mass strings in real time @48 kHz, 1 kHz physics"
        theirs = csound_string_seconds(voices=voices, seconds=seconds, masses=masses, sample_rate=SR,
                                       haptic_rate=int(PEER_PHYSICS["haptic_rate"]), mass=PEER_PHYSICS["mass"],
                                       stiffness=PEER_PHYSICS["stiffness"], damp=damp, repeat=2)
        ours = voices * seconds / _pool_seconds(masses, voices, seconds, repeat=2)
        if theirs is None:
            rows += [Row(f"{what} (VoicePool)", ours, "voices"),
                     skipped(f"{what}, Csound scantable", "csound not installed")]
            continue
        peer = voices * seconds / theirs
        rows += [Row(f"{what} (VoicePool)", ours, "voices", target=1.5 * peer if masses == 128 else None,
                     baseline="Csound scantable", ratio=ours / peer),
                 Row(f"{what} (Csound 6.18 scantable, same run)", peer, "voices")]
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
    frame_row = _render_fps(quick)
    return rows + ([frame_row] if frame_row else [])
