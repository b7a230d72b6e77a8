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
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

from audio.scanned import ScannedString, StringParameters

#: Layout of a string's ``state`` row: scan phase, haptic fraction, DC blocker x₁ and y₁,
#: scan increment per sample (frequency / sample rate).
PHASE, FRACTION, DC_X, DC_Y, INCREMENT = range(5)

STACK = 8192
LANES = 8
MAX_GROUP = 64
PER_VOICE = 8 * MAX_GROUP


@intrinsic
def _stack_doubles(typingctx, count):
    if not isinstance(count, types.IntegerLiteral):
        return None
    size = count.literal_value

    def codegen(context, builder, signature, args):
        return cgutils.alloca_once(builder, context.get_value_type(types.float64), size=size)

    return types.CPointer(types.float64)(count), codegen


@numba.njit(cache=True, fastmath=False, inline="always")
def _step(x, v, x_prev, force, ring, k, c, damp, inv_m, h):
    n = x.shape[0]
    for i in range(n):
        x_prev[i] = x[i]
    for i in range(1, n - 1):
        accel = inv_m * (k * (x_prev[i - 1] - 2.0 * x_prev[i] + x_prev[i + 1]) - c * x_prev[i] + force[i])
        v[i] = damp * v[i] + h * accel
        x[i] = x_prev[i] + h * v[i]
    for i in range(0, n, max(n - 1, 1)):
        left = x_prev[i - 1] if i > 0 else (x_prev[n - 1] if ring else 0.0)
        right = x_prev[i + 1] if i < n - 1 else (x_prev[0] if ring else 0.0)
        accel = inv_m * (k * (left - 2.0 * x_prev[i] + right) - c * x_prev[i] + force[i])
        v[i] = damp * v[i] + h * accel
        x[i] = x_prev[i] + h * v[i]


@numba.njit(cache=True, fastmath=False, inline="always")
def _lay_out(shape, delta, x_prev, x, lead, interpolate):
    n = x.shape[0]
    if interpolate:
        if lead:
            shape[0] = 0.0
            delta[0] = 0.0
        for m in range(n):
            shape[lead + m] = x_prev[m]
            delta[lead + m] = x[m] - x_prev[m]
        shape[lead + n] = shape[0]
        delta[lead + n] = delta[0]
    else:
        if lead:
            shape[0] = 0.0
        for m in range(n):
            shape[lead + m] = x[m]
        shape[lead + n] = shape[0]


@numba.njit(cache=True, fastmath=False)
def _render(mix, voices, x, v, x_prev, force, state, level, slope, failed, out, ring, k, c, gamma, inv_m, h,
            haptic_per_sample, dc_pole, interpolate):
    n = x.shape[1]
    lead = 0 if ring else 1
    n_points = n + lead
    width = n_points + 1
    frames = mix.shape[0]
    damp = 1.0 - gamma * h
    layers = 2 if interpolate else 1
    group = max(1, min(out.shape[1], STACK // (width * layers)))
    stack = numba.carray(_stack_doubles(STACK), STACK)
    shapes = stack[:group * width]
    deltas = stack[group * width:2 * group * width] if interpolate else stack[:0]
    per_voice = numba.carray(_stack_doubles(PER_VOICE), (8, MAX_GROUP))
    phase, frac, dc_x, dc_y, increment, due, gain, fade = (per_voice[0], per_voice[1], per_voice[2], per_voice[3],
                                                           per_voice[4], per_voice[5], per_voice[6], per_voice[7])
    lane = numba.carray(_stack_doubles(LANES), LANES)
    for first in range(0, voices.shape[0], group):
        size = min(group, voices.shape[0] - first)
        for q in range(size):
            i = voices[first + q]
            phase[q], frac[q], dc_x[q], dc_y[q], increment[q] = state[i, 0], state[i, 1], state[i, 2], state[i, 3], state[i, 4]
            gain[q], fade[q] = level[i], slope[i]
            _lay_out(shapes[q * width:(q + 1) * width], deltas[q * width:(q + 1) * width] if interpolate else deltas,
                     x_prev[i], x[i], lead, interpolate)
        for s in range(frames):
            stepping = False
            for q in range(size):
                f = frac[q] + haptic_per_sample
                d = f >= 1.0
                frac[q] = f - 1.0 if d else f
                due[q] = 1.0 if d else 0.0
                stepping |= d
            if stepping:
                for q in range(size):
                    if due[q] != 0.0:
                        i = voices[first + q]
                        _step(x[i], v[i], x_prev[i], force[i], ring, k, c, damp, inv_m, h)
                        _lay_out(shapes[q * width:(q + 1) * width],
                                 deltas[q * width:(q + 1) * width] if interpolate else deltas,
                                 x_prev[i], x[i], lead, interpolate)
            row = out[s]
            for q in range(size):
                pos = phase[q] * n_points
                j = int(pos)
                if j >= n_points:
                    j -= n_points
                b = q * width + j
                if interpolate:
                    a = pos - j
                    y0 = shapes[b] + frac[q] * deltas[b]
                    y1 = shapes[b + 1] + frac[q] * deltas[b + 1]
                    y = y0 + a * (y1 - y0)
                else:
                    y = shapes[b]
                blocked = y - dc_x[q] + dc_pole * dc_y[q]
                dc_x[q] = y
                dc_y[q] = blocked
                row[q] = blocked * min(max(gain[q] + fade[q] * (s + 1), 0.0), 1.0)
                p = phase[q] + increment[q]
                phase[q] = p - 1.0 if p >= 1.0 else p
        for q in range(size):
            i = voices[first + q]
            total = dc_y[q]
            for m in range(n):
                total += x[i, m]
            if not math.isfinite(total):
                failed[i] = True
                out[:frames, q] = 0.0
                x[i, :] = 0.0
                v[i, :] = 0.0
                x_prev[i, :] = 0.0
                dc_x[q] = dc_y[q] = 0.0
            state[i, 0], state[i, 1], state[i, 2], state[i, 3] = phase[q], frac[q], dc_x[q], dc_y[q]
        for s in range(frames):
            row = out[s]
            for l in range(LANES):
                lane[l] = 0.0
            q = 0
            while q + LANES <= size:
                for l in range(LANES):
                    lane[l] += row[q + l]
                q += LANES
            total = 0.0
            for l in range(LANES):
                total += lane[l]
            while q < size:
                total += row[q]
                q += 1
            mix[s] += total
        for q in range(size):
            level[voices[first + q]] = min(max(gain[q] + fade[q] * frames, 0.0), 1.0)


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
        self.block_size = int(block_size)
        self._out = np.zeros((self.block_size, MAX_GROUP))
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
        if len(mix) > self.block_size:
            raise ValueError(f"block of {len(mix)} samples exceeds the bank's block_size {self.block_size}")
        p = self.parameters
        _render(mix, np.asarray(voices, dtype=np.int64), self.x, self.v, self.x_prev, self.force, self.state,
                level, slope, self._failed, self._out, p.ring, p.stiffness, p.centring, p.damping / p.mass, 1.0 / p.mass, 1.0 / p.haptic_rate,
                p.haptic_rate / self.sample_rate, self.strings[0].dc_pole, p.interpolation == "linear")
        if self._failed.any():
            for i in np.flatnonzero(self._failed):
                self.strings[i].resets += 1
            self._failed[:] = False
