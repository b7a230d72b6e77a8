"""Voices: how many 128-mass scanned strings one core runs in real time, and render speed.

Rows (``python -m bench voice``):

* scanned strings in real time at 48 kHz (target ≥ 50), beside a plain numpy sine-table
  oscillator measured in the same process (the ratio says what a scanned voice costs
  relative to the cheapest possible voice on this machine);
* the same string model vectorised in numpy over the masses (a Python loop over haptic
  frames) — the measurement behind choosing numba for :mod:`audio.scanned`;
* body frames per second at 640×480 (pyrender offscreen), when a GL platform exists.

The voice rows run under :func:`one_core` (the target is per core); the render row does not,
since the GL driver's own threads are part of what a frame costs.
"""

from __future__ import annotations

import contextlib
import os
import sys
from typing import Iterator

import numpy as np
from threadpoolctl import threadpool_limits

from bench import Row, best_of
from audio.scanned import ScannedString, StringParameters

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


def run(quick: bool) -> list[Row]:
    string, out = _plucked(), np.empty(BLOCK)
    string.render(BLOCK, out=out)  # JIT (or load the numba cache) before timing
    repeat = 2 if quick else 5
    table = np.sin(2 * np.pi * np.arange(4096) / 4096)
    with one_core():
        scanned = 1.0 / best_of(lambda: _scanned_second(string, out), repeat=repeat)
        sine = 1.0 / best_of(lambda: _sine_table_second(table, out), repeat=repeat)
        vectorised = 1.0 / best_of(lambda: _numpy_scanned_second(string.parameters), repeat=1 if quick else 2)
    rows = [
        Row("128-mass scanned strings in real time @48 kHz (numba)", scanned, "voices", target=50.0,
            baseline="numpy sine-table voices", ratio=scanned / sine),
        Row("numpy sine-table oscillators in real time @48 kHz", sine, "voices"),
        Row("same string vectorised in numpy (not used)", vectorised, "voices",
            baseline="numba kernel", ratio=vectorised / scanned),
    ]
    frame_row = _render_fps(quick)
    return rows + ([frame_row] if frame_row else [])
