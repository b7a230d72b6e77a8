"""StringBank: many scanned strings with one parameter set, rendered by one compiled kernel.

A creature's voice is a pool of strings (:mod:`audio.voices`) that all share physics and
sample rate, so their state can live in ``(voices, masses)`` arrays and one numba call per
block renders, envelopes and mixes every sounding string. Each :class:`ScannedString` of
the bank keeps working as before (pluck, strike, push, silence, ``x[:] = …``): its arrays
are rows of the bank's, so what it writes is what the kernel reads.

Why a bank, measured in ``bench/voice.py`` against Csound's ``scantable`` at equal physics:
calling :meth:`ScannedString.render_raw` once per voice per block costs a few microseconds
of Python dispatch each time, and a string rendered alone is bound by its own per-sample
recurrences (scan phase, haptic clock, DC blocker: ~6 cycles a sample, whatever the size).
So the kernel renders up to :data:`MAX_GROUP` strings side by side, a sample at a time across
the group: the recurrences of different strings are independent, and the loop over voices is
vectorised (AVX2 / AVX-512), each string's shape read at its own scan position by a gather
(:func:`_read`, a loop of its own: its index vectorises with AVX-512 only).
LLVM vectorises that loop only when it can tell the shapes alias nothing the loop writes, which
numba cannot say about arrays passed in; so a group's shapes live on the stack
(:func:`_stack_doubles`), ``masses + 2`` rows a string (a row beyond each end: 0 for fixed ends,
the far mass on a ring), and the trajectory's fixed end and wrap cost no branch.

Where the physics steps depends on the size (:data:`ACROSS`): a short string's whole state is
on the stack too, voice-minor, and one step updates every string of the group mass by mass
across the voices (at 3 masses, stepping a string alone cost more than scanning it); a long
string steps along its own masses in the bank's rows, as the reference does, and copies each
new frame over. Each string keeps its own haptic clock, so strings whose frames fall due apart
step apart.

A note with harmonics above the band and fewer than 16 in it (:mod:`audio.bandlimit`) is scanned band-limited, as the
reference does it: its frames are projected when they step and the scan reads the projections,
laid out as the shapes are. Such strings render in a kernel of their own (:func:`_render_kernel`),
so the others' costs nothing more; each of theirs costs its projection, which is most of it.

The arithmetic is the reference's, term for term and in the same order, so the samples are
the reference integrator's (``tests/test_string_bank.py`` holds them within 1e-6 at 1 to 1,024
masses; only the mix adds the strings in another order). float64 stays: the stability bound
lets ``h²(4k + c)/m`` come within a hair of ``4 − 2γh``, where float32 rounding would decide
stability. ``fastmath`` stays off: reassociation would break the equality with the reference,
and the one reduction (the mix) is written as eight running sums instead.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

from audio.bandlimit import NO_BASIS, above_band, band_limit, dft_basis, harmonics, kept_harmonics
from audio.scanned import ScannedString, StringParameters

#: Layout of a string's ``state`` row: scan phase, haptic fraction, DC blocker x₁ and y₁,
#: scan increment per sample (frequency / sample rate).
PHASE, FRACTION, DC_X, DC_Y, INCREMENT = range(5)

ACROSS = 32
"""Strings of up to this many masses step across voices (:func:`_step_across`, the group's
physics on the stack); longer ones step along their own masses (:func:`_step_along`, in the
bank's rows), which fill the vector by themselves. Measured crossover: at 16 masses across is
1.4× along, at 32 even, at 64 along is 1.1× across, at 1,024 six times."""

STACK = 8192
"""Doubles in each of a group's four stack arrays (64 KiB): positions and previous frame, and
for short strings velocities and forces, ``masses + 2`` rows a string. The kernel takes about
260 KiB of stack in all; it runs on a creature's thread (8 MiB), never on the audio callback."""

MAX_GROUP = 64
"""Most strings rendered side by side: eight AVX-512 vectors across; a block's per-voice output
(``block_size × MAX_GROUP``) stays in L2."""

SCALARS = 8 * MAX_GROUP
"""Per-string scan state of a group on the stack: phase, clock, DC blocker, increment, envelope."""

LANES = 8
"""Running sums the group's mix keeps (one AVX-512 vector), so its adds vectorise without
``fastmath``."""


@intrinsic
def _stack_doubles(typingctx, count):
    """A pointer to ``count`` (a compile-time constant) float64s on the kernel's stack. Arrays
    there alias neither each other nor anything the caller passed, and LLVM knows it: only then
    does it vectorise a loop that reads the strings' shapes at per-voice positions (a gather)."""
    if not isinstance(count, types.IntegerLiteral):
        return None
    size = count.literal_value

    def codegen(context, builder, signature, args):
        return cgutils.alloca_once(builder, context.get_value_type(types.float64), size=size)

    return types.CPointer(types.float64)(count), codegen


@numba.njit(cache=True, fastmath=False, inline="always")
def _step_along(x, v, x_prev, force, ring, k, c, damp, inv_m, h):
    """One symplectic-Euler step of one string (:func:`audio.scanned._haptic_step`, same terms
    in the same order), keeping the frame it starts from in ``x_prev``: one branch-free loop
    over the inner masses, which LLVM vectorises, and the ends apart."""
    n = x.shape[0]
    for i in range(n):
        x_prev[i] = x[i]
    for i in range(1, n - 1):
        accel = inv_m * (k * (x_prev[i - 1] - 2.0 * x_prev[i] + x_prev[i + 1]) - c * x_prev[i] + force[i])
        v[i] = damp * v[i] + h * accel
        x[i] = x_prev[i] + h * v[i]
    for i in range(0, n, max(n - 1, 1)):  # the two ends, or the one mass
        left = x_prev[i - 1] if i > 0 else (x_prev[n - 1] if ring else 0.0)
        right = x_prev[i + 1] if i < n - 1 else (x_prev[0] if ring else 0.0)
        accel = inv_m * (k * (left - 2.0 * x_prev[i] + right) - c * x_prev[i] + force[i])
        v[i] = damp * v[i] + h * accel
        x[i] = x_prev[i] + h * v[i]


@numba.njit(cache=True, fastmath=False, inline="always")
def _ends(stack, start, step, rows, ring):
    """The rows beyond a string's ends (its masses at ``stack[start + (m + 1)·step]``): 0 for
    fixed ends, on a ring copies of the far mass, so neighbours, the trajectory's fixed end and
    its wrap need no branch."""
    last = start + (rows - 1) * step
    if ring:
        stack[start] = stack[last - step]
        stack[last] = stack[start + step]
    else:
        stack[start] = 0.0
        stack[last] = 0.0


@numba.njit(cache=True, fastmath=False, inline="always")
def _to_stack(stack, values, start, step, rows, ring):
    """A string's masses into rows 1…n of its place in a stack array, and its ends."""
    for m in range(values.shape[0]):
        stack[start + (m + 1) * step] = values[m]
    _ends(stack, start, step, rows, ring)


@numba.njit(cache=True, fastmath=False, inline="always")
def _from_stack(values, stack, start, step):
    for m in range(values.shape[0]):
        values[m] = stack[start + (m + 1) * step]


@numba.njit(cache=True, fastmath=False, inline="always")
def _table_to_stack(stack, table, start, step, offset):
    """A projected table into a string's read rows (point ``p`` in row ``p + offset``), and its
    point 0 again after the last, where the scan wraps."""
    n = table.shape[0]
    for t in range(n):
        stack[start + (t + offset) * step] = table[t]
    stack[start + (n + offset) * step] = table[0]


@numba.njit(cache=True, fastmath=False, inline="always")
def _next_table(read, read_prev, shape, start, step, offset, trajectory, basis, low, high, keep, table, scratch):
    """A band-limited string's new frame: its read rows become the previous frame's, and
    ``shape`` projected (:func:`audio.bandlimit.band_limit`) takes their place."""
    for t in range(offset, offset + table.shape[0] + 1):
        read_prev[start + t * step] = read[start + t * step]
    band_limit(table, shape, trajectory, basis, low, high, keep, scratch)
    _table_to_stack(read, table, start, step, offset)


@numba.njit(cache=True, fastmath=False, inline="always")
def _step_mass(x, v, x_prev, x_left, x_right, force, size, k, c, damp, inv_m, h):
    """The step of one mass of the first ``size`` strings of a group, across the voices. Each
    index is the loop's own, from 0, so numba adds no negative-index test and LLVM vectorises."""
    for q in range(size):
        accel = inv_m * (k * (x_left[q] - 2.0 * x_prev[q] + x_right[q]) - c * x_prev[q] + force[q])
        v[q] = damp * v[q] + h * accel
        x[q] = x_prev[q] + h * v[q]


@numba.njit(cache=True, fastmath=False, inline="always")
def _step_across(x, v, x_prev, force, only, size, rows, group, ring, k, c, damp, inv_m, h):
    """The same step for the group's first ``size`` strings at once (their physics on the stack),
    or with ``only`` ≥ 0 for that string alone, whose haptic frame came due apart from the others'."""
    first, count = (0, size) if only < 0 else (only, 1)
    for m in range(rows):
        x_prev[m * group + first:m * group + first + count] = x[m * group + first:m * group + first + count]
    for m in range(1, rows - 1):
        at = m * group + first
        _step_mass(x[at:at + count], v[at:at + count], x_prev[at:at + count], x_prev[at - group:at - group + count],
                   x_prev[at + group:at + group + count], force[at:at + count], count, k, c, damp, inv_m, h)
    for q in range(first, first + count):
        _ends(x, q, group, rows, ring)


@numba.njit(cache=True, fastmath=False, inline="always")
def _tick(frac, q, haptic_per_sample):
    """Advance string ``q``'s haptic clock by a sample as the reference does; 1 when a frame
    falls due (the clock wrapped), else 0."""
    f = frac[q] + haptic_per_sample
    stepping = f >= 1.0
    frac[q] = f - 1.0 if stepping else f
    return 1 if stepping else 0


@numba.njit(cache=True, fastmath=False, inline="always")
def _read(shown, sx, sp, phase, frac, size, n_points, offset, point_step, voice_step, interpolate):
    """What each of the group's first ``size`` strings reads at its scan position, into
    ``shown``: the reference's arithmetic, its point found by an index and its value gathered.

    A loop of its own, apart from the rest of the sample: a scan position becomes an index
    through a double-to-64-bit-integer conversion, which vectorises only with AVX-512. In one
    loop with the DC blocker, envelope and clocks, that conversion kept the whole loop a string
    at a time on AVX2 (an AMD EPYC here: 1-mass strings 0.67× Csound's ``scantable``); apart,
    the rest is vectorised everywhere (measured 1.15× at 128 masses to 1.9× at 1, that machine)."""
    for q in range(size):
        pos = phase[q] * n_points
        j = int(pos)
        a = pos - j
        if j >= n_points:  # a phase of 1.0 (the wrap below keeps it under 1) reads point 0, not past the table
            j -= n_points
        # unsigned: numba then adds no negative-index test to the gather
        r = np.uint64((j + offset) * point_step + q * voice_step)
        if interpolate:
            r1 = np.uint64((j + offset + 1) * point_step + q * voice_step)
            y0 = sp[r] + frac[q] * (sx[r] - sp[r])
            y1 = sp[r1] + frac[q] * (sx[r1] - sp[r1])
            shown[q] = y0 + a * (y1 - y0)
        else:  # the node under the scan, current frame
            shown[q] = sx[r]


def _render_kernel(limited: bool):
    """The group kernel, compiled apart for band-limited strings (``limited``) and the others:
    a constant there, so each version holds none of the other's branches (in one kernel, the
    band-limited steps alone cost the others' scan 20 %: measured 2,636 against 3,358 voices)."""

    @numba.njit(cache=True, fastmath=False)
    def render(mix, voices, x, v, x_prev, force, state, level, slope, failed, out, ring, k, c, gamma, inv_m, h,
               haptic_per_sample, dc_pole, interpolate, trajectory, basis, low, high, keep, table, shape, scratch):
        """Add every string in ``voices`` to ``mix``, each scaled by its envelope ``level`` moving
        by ``slope`` per sample (clipped to [0, 1]); a string whose state stops being finite is
        silenced, adds nothing this block, and is flagged in ``failed`` (the reference's reset).

        Strings go in groups of up to :data:`MAX_GROUP`, a sample at a time across the group. The
        group's shapes (and previous frames) live on the stack, ``masses + 2`` rows per string,
        trajectory point ``p`` in row ``p`` of a string (its fixed end in row 0) or ``p + 1`` of a
        ring. Short strings keep their whole physics there, voice-minor so a step runs across the
        voices (:data:`ACROSS`); long ones step in the bank's rows and copy each new frame over,
        string-major so the copy is contiguous.

        With ``limited`` every string in ``voices`` is band-limited (:mod:`audio.bandlimit`), on
        harmonics ``low[q]…high[q]`` (``keep[q]``): the scan reads each frame projected, as the
        reference's does, from rows laid out as the shapes' (a long string's instead of its copied
        frame; a short one's in two arrays of their own, its physics being in the others)."""
        n = x.shape[1]
        rows = n + 2
        offset = 1 if ring else 0
        n_points = n + 1 - offset
        frames = mix.shape[0]
        damp = 1.0 - gamma * h
        across = n <= ACROSS
        group = max(1, min(out.shape[1], STACK // rows))  # out is at most MAX_GROUP wide
        point_step, voice_step = (group, 1) if across else (1, rows)  # where row r of string q lives: r·point + q·voice
        # separate allocations, not one cut in four: LLVM then knows they never overlap
        sx, sp = numba.carray(_stack_doubles(STACK), STACK), numba.carray(_stack_doubles(STACK), STACK)
        sv, sf = numba.carray(_stack_doubles(STACK), STACK), numba.carray(_stack_doubles(STACK), STACK)
        scalars = numba.carray(_stack_doubles(SCALARS), (8, MAX_GROUP))
        phase, frac, dc_x, dc_y, increment, gain, fade = (scalars[0], scalars[1], scalars[2], scalars[3],
                                                          scalars[4], scalars[5], scalars[6])
        lane = numba.carray(_stack_doubles(LANES), LANES)
        shown = numba.carray(_stack_doubles(MAX_GROUP), MAX_GROUP)  # what each string of the group read
        tx, tp = numba.carray(_stack_doubles(STACK), STACK), numba.carray(_stack_doubles(STACK), STACK)
        apart = limited and across  # the scan reads tx, tp (projections) instead of sx, sp (shapes)
        for first in range(0, voices.shape[0], group):
            size = min(group, voices.shape[0] - first)
            for q in range(size):
                i = voices[first + q]
                at = q * voice_step
                _to_stack(sx, x[i], at, point_step, rows, ring)
                _to_stack(sp, x_prev[i], at, point_step, rows, ring)
                if across:
                    _to_stack(sv, v[i], at, point_step, rows, ring)
                    _to_stack(sf, force[i], at, point_step, rows, ring)
                if limited:  # the frames as they are now, projected
                    band_limit(table, x_prev[i], trajectory, basis, low[first + q], high[first + q], keep[first + q],
                               scratch)
                    _table_to_stack(tp if apart else sp, table, at, point_step, offset)
                    band_limit(table, x[i], trajectory, basis, low[first + q], high[first + q], keep[first + q], scratch)
                    _table_to_stack(tx if apart else sx, table, at, point_step, offset)
                phase[q], frac[q], dc_x[q], dc_y[q], increment[q] = (state[i, 0], state[i, 1], state[i, 2], state[i, 3],
                                                                     state[i, 4])
                gain[q], fade[q] = level[i], slope[i]
            enveloped = False
            due = 0
            for q in range(size):
                enveloped |= fade[q] != 0.0 or gain[q] != 1.0
                due += _tick(frac, q, haptic_per_sample)
            for s in range(frames):
                if across and due == size:
                    _step_across(sx, sv, sp, sf, -1, size, rows, group, ring, k, c, damp, inv_m, h)
                elif due:
                    for q in range(size):
                        if frac[q] < haptic_per_sample:  # it just wrapped: f − 1 < haptic_per_sample ≤ f
                            if across:
                                _step_across(sx, sv, sp, sf, q, size, rows, group, ring, k, c, damp, inv_m, h)
                            else:
                                i = voices[first + q]
                                _step_along(x[i], v[i], x_prev[i], force[i], ring, k, c, damp, inv_m, h)
                                if limited:
                                    _next_table(sx, sp, x[i], q * voice_step, point_step, offset, trajectory, basis,
                                                low[first + q], high[first + q], keep[first + q], table, scratch)
                                    continue
                                _to_stack(sx, x[i], q * voice_step, point_step, rows, ring)
                                if interpolate:
                                    _to_stack(sp, x_prev[i], q * voice_step, point_step, rows, ring)
                if apart and due:  # each short string stepped just now: its new frame projected
                    for q in range(size):
                        if frac[q] < haptic_per_sample:
                            _from_stack(shape, sx, q, group)
                            _next_table(tx, tp, shape, q, group, offset, trajectory, basis, low[first + q],
                                        high[first + q], keep[first + q], table, scratch)
                row = out[s]
                ticking = s + 1 < frames
                if apart:  # two calls, not one on a choice of arrays: LLVM then still knows what each reads
                    _read(shown, tx, tp, phase, frac, size, n_points, offset, point_step, voice_step, interpolate)
                else:
                    _read(shown, sx, sp, phase, frac, size, n_points, offset, point_step, voice_step, interpolate)
                due = 0
                for q in range(size):  # the rest of the sample, across the group
                    y = shown[q]
                    blocked = y - dc_x[q] + dc_pole * dc_y[q]  # the reference's DC blocker
                    dc_x[q] = y
                    dc_y[q] = blocked
                    row[q] = blocked * min(max(gain[q] + fade[q] * (s + 1), 0.0), 1.0) if enveloped else blocked
                    p = phase[q] + increment[q]
                    phase[q] = p - 1.0 if p >= 1.0 else p
                    if ticking:  # the next sample's haptic clock, in the same pass
                        due += _tick(frac, q, haptic_per_sample)
            for q in range(size):
                i = voices[first + q]
                if across:
                    _from_stack(x[i], sx, q, group)
                    _from_stack(v[i], sv, q, group)
                    _from_stack(x_prev[i], sp, q, group)
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
                level[i] = min(max(gain[q] + fade[q] * frames, 0.0), 1.0)
            for s in range(frames):  # the group's mix: eight running sums, so the adds vectorise
                row = out[s]
                for lane_ in range(LANES):
                    lane[lane_] = 0.0
                whole = size - size % LANES
                for chunk in range(0, whole, LANES):  # range loops: indices known ≥ 0, no negative-index test
                    for lane_ in range(LANES):
                        lane[lane_] += row[chunk + lane_]
                total = 0.0
                for lane_ in range(LANES):
                    total += lane[lane_]
                for q in range(whole, size):
                    total += row[q]
                mix[s] += total

    return render


_render = _render_kernel(False)
_render_band_limited = _render_kernel(True)


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
        self._out = np.zeros((self.block_size, min(size, MAX_GROUP)))  # a group's samples, one column a string
        self._failed = np.zeros(size, dtype=np.bool_)
        self.sample_rate = float(sample_rate)
        self.trajectory = self.strings[0].trajectory
        self._table = np.zeros(len(self.trajectory))  # a band-limited string's projected frame
        self._shape = np.zeros(n)  # a short one's shape, off the stack to be projected
        self._scratch = np.zeros((5, len(self.trajectory)))  # the projection's work space
        self._no_band = (np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.bool_))  # for the others

    def push(self, voices: np.ndarray, force: np.ndarray) -> None:
        """Set the per-node force of strings ``voices`` (the body's push, as
        :meth:`ScannedString.push`, for many strings in one step)."""
        force = np.asarray(force, dtype=float)
        if force.shape != (self.parameters.n_masses,):
            raise ValueError(f"force must have shape ({self.parameters.n_masses},), got {force.shape}")
        if not np.isfinite(force).all():
            force = np.nan_to_num(force, nan=0.0, posinf=0.0, neginf=0.0)
        self.force[voices] = force

    def render(self, mix: np.ndarray, voices: np.ndarray, level: np.ndarray, slope: np.ndarray) -> None:
        """Add strings ``voices`` (indices) to ``mix`` (at most ``block_size`` samples), each
        times its envelope: ``level[i]`` now, moving by ``slope[i]`` per sample, clipped to
        [0, 1]; ``level`` is advanced to the end of the block."""
        if len(mix) > self.block_size:
            raise ValueError(f"block of {len(mix)} samples exceeds the bank's block_size {self.block_size}")
        p = self.parameters
        voices = np.asarray(voices, dtype=np.int64)
        args = (self.x, self.v, self.x_prev, self.force, self.state, level, slope, self._failed, self._out, p.ring,
                p.stiffness, p.centring, p.damping / p.mass, 1.0 / p.mass, 1.0 / p.haptic_rate,
                p.haptic_rate / self.sample_rate, self.strings[0].dc_pole, p.interpolation == "linear")
        scratch = (self._table, self._shape, self._scratch)
        increments = self.state[voices, INCREMENT]
        if p.interpolation == "linear" and len(voices) and above_band(kept_harmonics(increments.max()),
                                                                      len(self.trajectory)):
            low, high, keep = harmonics(kept_harmonics(increments), len(self.trajectory))
            limited = low < high
            if limited.any():  # notes with harmonics above the band: their scans read projected frames
                _render_band_limited(mix, voices[limited], *args, self.trajectory, dft_basis(len(self.trajectory)),
                                     low[limited], high[limited], keep[limited], *scratch)
                voices = voices[~limited]
        _render(mix, voices, *args, self.trajectory, NO_BASIS, *self._no_band, *scratch)
        if self._failed.any():
            for i in np.flatnonzero(self._failed):
                self.strings[i].resets += 1
            self._failed[:] = False


def prepare(sample_rate: float) -> None:
    """Compile (or load from numba's cache) the kernels a band-limited note takes, now: a live
    run's rehearsal (:func:`creatures.runtime.live.rehearse`) plays what a second of the colony
    plays, which may be no note high enough to be band-limited, and the first one played in the
    show then compiled them on the creature's thread (a fresh install's first live run: one
    tick 13 s late, a thousand audio underruns). A one-string bank and a lone string each play
    a note whose band holds two harmonics; their kernels' argument types are every string's."""
    parameters = StringParameters(n_masses=16)
    bank = StringBank(1, parameters, sample_rate=sample_rate, block_size=64)
    bank.strings[0].note_on(0.2 * sample_rate)
    bank.render(np.zeros(64), np.zeros(1, dtype=np.int64), np.ones(1), np.zeros(1))
    lone = ScannedString(parameters, sample_rate=sample_rate)
    lone.note_on(0.2 * sample_rate)
    lone.render_raw(np.empty(64))
