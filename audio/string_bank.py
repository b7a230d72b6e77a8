"""StringBank: many scanned strings with one parameter set, rendered by one compiled kernel.

A creature's voice is a pool of strings (:mod:`audio.voices`) that all share physics and
sample rate, so their state can live in ``(voices, masses)`` arrays and one numba call per
block renders, envelopes and mixes every sounding string. Each :class:`ScannedString` of
the bank keeps working as before (pluck, strike, push, silence, ``x[:] = …``): its arrays
are rows of the bank's, so what it writes is what the kernel reads.

Why a bank, measured in ``bench/voice.py`` against Csound's ``scantable`` at equal physics:
calling :meth:`ScannedString.render_raw` once per voice per block costs a few microseconds
of Python dispatch each time, a large part of the ~300 µs one voice may spend per second
if a core is to run thousands. The kernel also does per block what the reference
(:func:`audio.scanned._scan`) does per sample:

* each haptic frame, the shape and its change since the last frame are laid out along the
  trajectory once (``shape``, ``delta``, one entry longer so the wrap needs no modulo), so
  a sample reads four neighbouring floats instead of following the trajectory twice;
* the physics step reads the previous frame (which the scanner keeps anyway) and writes the
  new one in a single branch-free loop over the inner masses, which LLVM vectorises (AVX2 /
  AVX-512 where the CPU has them; the two ends are done apart).

The arithmetic is the reference's, term for term and in the same order, so the samples are
the reference integrator's (``tests/test_string_bank.py`` holds them within 1e-6; in
practice they are bitwise equal). float64 stays: the stability bound lets ``h²(4k + c)/m``
come within a hair of ``4 − 2γh``, where float32 rounding would decide stability, and the
per-sample scan is bound by its own recurrences (phase, DC blocker), not by SIMD width, so
float32 would buy little. ``fastmath`` stays off for the same reason: reassociation would
break the equality with the reference for no measured gain.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from audio.scanned import ScannedString, StringParameters, default_trajectory

#: Layout of a string's ``state`` row: scan phase, haptic fraction, DC blocker x₁ and y₁,
#: scan increment per sample (frequency / sample rate).
PHASE, FRACTION, DC_X, DC_Y, INCREMENT = range(5)


@numba.njit(cache=True, fastmath=False)
def _step(x, v, x_prev, force, ring, k, c, damp, inv_m, h):
    """One symplectic-Euler step (the reference's :func:`audio.scanned._haptic_step`), keeping
    the frame it starts from in ``x_prev``."""
    n = x.shape[0]
    for i in range(n):
        x_prev[i] = x[i]
    for i in range(1, n - 1):  # branch-free: vectorised
        accel = inv_m * (k * (x_prev[i - 1] - 2.0 * x_prev[i] + x_prev[i + 1]) - c * x_prev[i] + force[i])
        v[i] = damp * v[i] + h * accel
        x[i] = x_prev[i] + h * v[i]
    for i in (0, n - 1):
        left = x_prev[i - 1] if i > 0 else (x_prev[n - 1] if ring else 0.0)
        right = x_prev[i + 1] if i < n - 1 else (x_prev[0] if ring else 0.0)
        accel = inv_m * (k * (left - 2.0 * x_prev[i] + right) - c * x_prev[i] + force[i])
        v[i] = damp * v[i] + h * accel
        x[i] = x_prev[i] + h * v[i]


@numba.njit(cache=True, fastmath=False)
def _lay_out(shape, delta, x_prev, x, lead):
    """The previous frame and its change to the current one along the bank's trajectory
    (:func:`~audio.scanned.default_trajectory`: ``lead`` = 1 fixed end, reading 0, before the
    masses of a string; 0 for a ring), plus the first point again at the end. Contiguous
    copies, so they vectorise."""
    n = x.shape[0]
    if lead:
        shape[0] = 0.0
        delta[0] = 0.0
    for m in range(n):
        shape[lead + m] = x_prev[m]
        delta[lead + m] = x[m] - x_prev[m]
    shape[lead + n] = shape[0]
    delta[lead + n] = delta[0]


@numba.njit(cache=True, fastmath=False)
def _render(mix, voices, x, v, x_prev, force, state, level, slope, failed, trajectory, shape, delta,
            scratch, ring, k, c, gamma, inv_m, h, haptic_per_sample, dc_pole, interpolate):
    """Add every string in ``voices`` to ``mix``, each scaled by its envelope ``level`` moving
    by ``slope`` per sample (clipped to [0, 1]); a string whose state stops being finite is
    silenced, adds nothing, and is flagged in ``failed`` (the reference's reset)."""
    n_points = trajectory.shape[0]
    lead = n_points - x.shape[1]
    frames = mix.shape[0]
    damp = 1.0 - gamma * h
    for q in range(voices.shape[0]):
        i = voices[q]
        xi, vi, pi, fi = x[i], v[i], x_prev[i], force[i]
        phase, frac, dc_x1, dc_y1, increment = state[i, 0], state[i, 1], state[i, 2], state[i, 3], state[i, 4]
        _lay_out(shape, delta, pi, xi, lead)
        for s in range(frames):
            frac += haptic_per_sample  # accumulated as the reference does: it decides the frame's sample
            if frac >= 1.0:
                frac -= 1.0
                _step(xi, vi, pi, fi, ring, k, c, damp, inv_m, h)
                _lay_out(shape, delta, pi, xi, lead)
            pos = phase * n_points
            j = int(pos)
            if j >= n_points:  # phase just below 1 can round up to n_points
                j -= n_points
            if interpolate:
                a = pos - j
                y0 = shape[j] + frac * delta[j]
                y1 = shape[j + 1] + frac * delta[j + 1]
                y = y0 + a * (y1 - y0)
            else:  # the node under the scan, current frame (to rounding: shape + delta is x)
                y = shape[j] + delta[j]
            dc_y1 = y - dc_x1 + dc_pole * dc_y1
            dc_x1 = y
            scratch[s] = dc_y1
            phase += increment
            if phase >= 1.0:
                phase -= 1.0
        total = dc_y1
        for m in range(xi.shape[0]):
            total += xi[m]
        ok = math.isfinite(total)
        if not ok:
            failed[i] = True
            xi[:] = 0.0
            vi[:] = 0.0
            pi[:] = 0.0
            dc_x1 = dc_y1 = 0.0
        state[i, 0], state[i, 1], state[i, 2], state[i, 3] = phase, frac, dc_x1, dc_y1
        g, dg = level[i], slope[i]
        if dg == 0.0:
            if ok:
                for s in range(frames):
                    mix[s] += scratch[s]
        else:
            for s in range(frames):
                envelope = min(max(g + dg * (s + 1), 0.0), 1.0)
                if ok:
                    mix[s] += envelope * scratch[s]
            level[i] = min(max(g + dg * frames, 0.0), 1.0)


class StringBank:
    """``size`` scanned strings sharing :class:`StringParameters` and a sample rate.

    ``strings[i]`` is an ordinary :class:`ScannedString` whose arrays are row ``i`` of the
    bank's; :meth:`render` mixes any subset of them with envelopes in one kernel call.
    """

    def __init__(self, size: int, parameters: StringParameters | None = None, *,
                 sample_rate: float = 48000.0, block_size: int = 1024) -> None:
        if size < 1:
            raise ValueError(f"a string bank needs at least one string, got {size}")
        self.parameters = parameters or StringParameters()
        n = self.parameters.n_masses
        self.x, self.v, self.x_prev, self.force = (np.zeros((size, n)) for _ in range(4))
        self.state = np.zeros((size, 5))
        self.strings = [ScannedString(self.parameters, sample_rate=sample_rate) for _ in range(size)]
        for i, string in enumerate(self.strings):
            string.bind(self.x[i], self.v[i], self.x_prev[i], self.force[i], self.state[i])
        self.trajectory = default_trajectory(n, ring=self.parameters.ring)
        self._shape = np.zeros(len(self.trajectory) + 1)
        self._delta = np.zeros(len(self.trajectory) + 1)
        self.scratch = np.zeros(block_size)
        self._failed = np.zeros(size, dtype=np.bool_)
        self.sample_rate = float(sample_rate)

    def push(self, voices: np.ndarray, force: np.ndarray) -> None:
        """Set the per-node force of strings ``voices`` (the body's push, as
        :meth:`ScannedString.push`, for many strings in one step)."""
        force = np.asarray(force, dtype=float)
        if force.shape != (self.parameters.n_masses,):
            raise ValueError(f"force must have shape ({self.parameters.n_masses},), got {force.shape}")
        self.force[voices] = np.nan_to_num(force, nan=0.0, posinf=0.0, neginf=0.0)

    def render(self, mix: np.ndarray, voices: np.ndarray, level: np.ndarray, slope: np.ndarray) -> None:
        """Add strings ``voices`` (indices) to ``mix`` (at most ``block_size`` samples), each
        times its envelope: ``level[i]`` now, moving by ``slope[i]`` per sample, clipped to
        [0, 1]; ``level`` is advanced to the end of the block."""
        if len(mix) > len(self.scratch):
            raise ValueError(f"block of {len(mix)} samples exceeds the bank's block_size {len(self.scratch)}")
        p = self.parameters
        _render(mix, np.asarray(voices, dtype=np.int64), self.x, self.v, self.x_prev, self.force, self.state,
                level, slope, self._failed, self.trajectory, self._shape, self._delta, self.scratch,
                p.ring, p.stiffness, p.centring, p.damping / p.mass, 1.0 / p.mass, 1.0 / p.haptic_rate,
                p.haptic_rate / self.sample_rate, self.strings[0].dc_pole, p.interpolation == "linear")
        if self._failed.any():
            for i in np.flatnonzero(self._failed):
                self.strings[i].resets += 1
            self._failed[:] = False
