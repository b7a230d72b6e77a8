"""Unit-quaternion maths for joint angles (thesis appendix "(quaternions)", p. 215).

Joint angles are not well expressed in vector spaces, so the motor system keeps every joint
as a unit quaternion ``(w, x, y, z)`` and interpolates on the 3-sphere. Every function takes
arrays whose last axis has length 4 (or 3 for vectors) and broadcasts over the leading axes,
so a whole pose ``(J, 4)`` or a whole animation ``(N, J, 4)`` is one call.

Plain numpy is used on purpose: ``bench/motor.py`` measures :func:`multiply` against
``scipy.spatial.transform.Rotation`` on the same data, and the per-call object construction
there costs more than it saves at the batch sizes the motor system uses.

Playback is the exception. Every course a creature sets out on runs squad over a few
segments of a few dozen joints, where numpy spends its time on call overhead for tiny
arrays (a course cost ~1.8 ms). So :func:`squad_rate`, :func:`squad_controls` and
:func:`squad_keys` run compiled (numba) kernels built from the one-quaternion functions at
the end of this module; they evaluate the same formulas as the numpy functions in the same
order, so results differ only by rounding (``tests/test_motor_kernels.py``).
"""

from __future__ import annotations

import functools
import math

import numba
import numpy as np

_EPS = 1e-12


def normalize(q: np.ndarray) -> np.ndarray:
    """Scale quaternions to unit norm; a zero quaternion becomes the identity.

    One copy divided in place, zeros fixed only where there are any: every pose set normalises
    its rotations, and the temporaries of a ``where`` over all of them were a second of a
    72,000-frame body's cached reload. C order whatever the input's: the compiled metric
    kernels read it node by node, and a strided copy here had every one of them copied again."""
    q = np.array(q, dtype=float, order="C")
    if q.ndim == 2 and q.shape[1] == 4:  # one pose, the per-tick case: compiled, no temporaries
        return _normalize_rows(q)
    norm = np.sqrt(np.einsum("...i,...i->...", q, q))[..., None]
    small = norm[..., 0] <= _EPS
    if small.any():
        q[small] = (1.0, 0.0, 0.0, 0.0)
        norm[small] = 1.0
    q /= norm
    return q


def identity(shape: tuple[int, ...] = ()) -> np.ndarray:
    """Identity rotations of the given leading shape."""
    q = np.zeros((*shape, 4))
    q[..., 0] = 1.0
    return q


def conjugate(q: np.ndarray) -> np.ndarray:
    """``q⁻¹`` for unit quaternions: ``{w, -x, -y, -z}``."""
    q = np.asarray(q, dtype=float)
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def multiply(q1: np.ndarray, q2: np.ndarray) -> np.ndarray:
    """Hamilton product ``q1 q2`` (apply ``q2`` first, then ``q1``)."""
    q1 = np.asarray(q1, dtype=float)
    q2 = np.asarray(q2, dtype=float)
    w1, x1, y1, z1 = q1[..., 0], q1[..., 1], q1[..., 2], q1[..., 3]
    w2, x2, y2, z2 = q2[..., 0], q2[..., 1], q2[..., 2], q2[..., 3]
    out = np.empty(np.broadcast_shapes(q1.shape, q2.shape))
    out[..., 0] = w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2
    out[..., 1] = w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2
    out[..., 2] = w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2
    out[..., 3] = w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2
    return out


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a × b`` over the last axis (np.cross's axis handling costs more than the maths)."""
    ax, ay, az = a[..., 0], a[..., 1], a[..., 2]
    bx, by, bz = b[..., 0], b[..., 1], b[..., 2]
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = ay * bz - az * by
    out[..., 1] = az * bx - ax * bz
    out[..., 2] = ax * by - ay * bx
    return out


def rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate vectors ``v`` by unit quaternions ``q`` (``q {0, v} q⁻¹``, expanded)."""
    q = np.asarray(q, dtype=float)
    v = np.asarray(v, dtype=float)
    u = q[..., 1:]
    t = 2.0 * _cross(u, v)
    return v + q[..., :1] * t + _cross(u, t)


def from_axis_angle(axis: np.ndarray, angle: np.ndarray | float) -> np.ndarray:
    """``{cos(θ/2), v̂ sin(θ/2)}`` for axes ``(..., 3)`` and angles ``(...)`` in radians."""
    axis = np.asarray(axis, dtype=float)
    angle = np.asarray(angle, dtype=float)
    norm = np.linalg.norm(axis, axis=-1, keepdims=True)
    unit = axis / np.maximum(norm, _EPS)
    half = 0.5 * angle[..., None]
    return np.concatenate((np.cos(half), unit * np.sin(half)), axis=-1)


def exp(v: np.ndarray) -> np.ndarray:
    """Exponential map: rotation vector ``v`` (axis × angle, radians) → unit quaternion."""
    v = np.asarray(v, dtype=float)
    angle = np.linalg.norm(v, axis=-1)
    return from_axis_angle(v, angle)


def log(q: np.ndarray) -> np.ndarray:
    """Logarithm map: unit quaternion → rotation vector (axis × angle), shortest way round."""
    q = np.asarray(q, dtype=float)
    q = np.where(q[..., :1] < 0.0, -q, q)
    vector = q[..., 1:]
    sin_half = np.linalg.norm(vector, axis=-1, keepdims=True)
    angle = 2.0 * np.arctan2(sin_half, q[..., :1])
    return vector * np.where(sin_half > _EPS, angle / np.maximum(sin_half, _EPS), 2.0)


def dot(q1: np.ndarray, q2: np.ndarray) -> np.ndarray:
    """Inner product ``q1 · q2`` over the last axis."""
    return np.einsum("...i,...i->...", np.asarray(q1, dtype=float), np.asarray(q2, dtype=float))


def distance(q1: np.ndarray, q2: np.ndarray) -> np.ndarray:
    """The appendix metric ``1 − |q1 · q2|``: zero for equal rotations, 1 at half a turn.

    The absolute value makes ``q`` and ``−q`` (the same rotation) distance zero, so the
    metric always measures the shortest path.
    """
    return 1.0 - np.minimum(np.abs(dot(q1, q2)), 1.0)


def angle_between(q1: np.ndarray, q2: np.ndarray) -> np.ndarray:
    """Rotation angle (radians, in [0, π]) taking ``q1`` to ``q2`` the short way.

    Broadcasts over the leading axes; each pair is :func:`angle_between_one`, compiled as a
    generalised ufunc so that broadcasting a pose against a whole set copies nothing.
    """
    return _angles(np.asarray(q1, dtype=float), np.asarray(q2, dtype=float))


def slerp(q1: np.ndarray, q2: np.ndarray, alpha: np.ndarray | float) -> np.ndarray:
    """Spherical linear interpolation along the shorter great arc (extrinsic form).

    ``alpha`` broadcasts against the leading axes of ``q1``/``q2``; values outside [0, 1]
    extrapolate along the same geodesic.
    """
    q1 = np.asarray(q1, dtype=float)
    q2 = np.asarray(q2, dtype=float)
    alpha = np.asarray(alpha, dtype=float)[..., None]
    c = dot(q1, q2)[..., None]
    q2 = np.where(c < 0.0, -q2, q2)
    c = np.abs(c)
    phi = np.arccos(np.minimum(c, 1.0))
    s = np.sin(phi)
    close = s < 1e-6
    safe_s = np.where(close, 1.0, s)
    a = np.where(close, 1.0 - alpha, np.sin((1.0 - alpha) * phi) / safe_s)
    b = np.where(close, alpha, np.sin(alpha * phi) / safe_s)
    return normalize(a * q1 + b * q2)


def slerp_rows(q1: np.ndarray, q2: np.ndarray, alpha: float) -> np.ndarray:
    """:func:`slerp` of two ``(J, 4)`` poses at one ``alpha``, compiled: a layer samples its
    frames once per tick, where numpy's temporaries cost more than the arithmetic."""
    return _slerp_rows(np.ascontiguousarray(q1, dtype=float), np.ascontiguousarray(q2, dtype=float), float(alpha))


def turns_about(count: int, joints: np.ndarray, axes: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """``count`` rotations, the identity except joint ``joints[k]`` turned ``angles[k]`` radians
    about unit ``axes[k]`` (a joint named twice has its rotation vectors summed): named joint
    variables as one pose, compiled (a skill's layer makes one per tick)."""
    return _turns_about(int(count), np.ascontiguousarray(joints, dtype=np.int64),
                        np.ascontiguousarray(axes, dtype=float), np.ascontiguousarray(angles, dtype=float))


def squad_controls(q: np.ndarray) -> np.ndarray:
    """Shoemake's inner control quaternions for a key-frame sequence ``q`` of shape (N, ..., 4).

    ``s_i = q_i exp(−(log(q_i⁻¹ q_{i+1}) + log(q_i⁻¹ q_{i−1})) / 4)``, with the ends clamped,
    so consecutive :func:`squad` segments join with continuous tangents (the "higher (third)
    order spline interpolant" of the appendix). The keys are hemisphere-aligned first
    (:func:`hemisphere_align`); compiled, it is :func:`squad_control` along the sequence.
    """
    q = np.asarray(q, dtype=float)
    flat = np.ascontiguousarray(q).reshape(len(q), math.prod(q.shape[1:-1]), 4)
    return _squad_controls(flat).reshape(q.shape)


def squad_control(prev: np.ndarray, q: np.ndarray, nxt: np.ndarray) -> np.ndarray:
    """The control quaternion of key ``q`` between keys ``prev`` and ``nxt`` (broadcast).

    For keys that are not one sequence, e.g. every source frame of a graph at once; pass
    ``q`` itself as ``prev`` or ``nxt`` at an end. :func:`squad` takes the short way
    everywhere, so the keys' signs do not matter.
    """
    inv = conjugate(q)
    tangent = log(multiply(inv, nxt)) + log(multiply(inv, prev))
    return multiply(q, exp(-0.25 * tangent))


def squad_control_at(q: np.ndarray, before: np.ndarray, after: np.ndarray) -> np.ndarray:
    """:func:`squad_control` of every key ``q[n]`` (``(N, J, 4)``) between ``q[before[n]]`` and
    ``q[after[n]]``, compiled: a whole pose set's controls without numpy's full-size temporaries."""
    keys = np.ascontiguousarray(q, dtype=float)
    return _controls_at(keys, np.ascontiguousarray(before, dtype=np.int64), np.ascontiguousarray(after, dtype=np.int64))


def squad(
    q1: np.ndarray, q2: np.ndarray, s1: np.ndarray, s2: np.ndarray, alpha: np.ndarray | float
) -> np.ndarray:
    """Spherical quadrangle interpolation between ``q1`` and ``q2`` with controls ``s1, s2``."""
    alpha = np.asarray(alpha, dtype=float)
    outer = slerp(q1, q2, alpha)
    inner = slerp(s1, s2, alpha)
    return slerp(outer, inner, 2.0 * alpha * (1.0 - alpha))


def squad_keys(keys: np.ndarray, controls: np.ndarray, segments: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """A key sequence's squad curve at many points: ``(T, ..., 4)`` for ``T`` segment indices.

    Point ``t`` is ``squad(keys[k], keys[k + 1], controls[k], controls[k + 1], alpha[t])``
    with ``k = segments[t]``, for keys and controls of shape (K, ..., 4); compiled, so
    sampling a whole course does not gather four copies of the keys first.
    """
    keys = np.asarray(keys, dtype=float)
    joints = math.prod(keys.shape[1:-1])
    flat_keys = np.ascontiguousarray(keys).reshape(len(keys), joints, 4)
    flat_controls = np.ascontiguousarray(controls, dtype=float).reshape(len(keys), joints, 4)
    segments = np.ascontiguousarray(segments, dtype=np.int64)
    alpha = np.ascontiguousarray(alpha, dtype=float)
    if len(segments) and not 0 <= segments.min() <= segments.max() < len(keys) - 1:
        raise IndexError(f"squad segments must lie in [0, {len(keys) - 2}] (got {segments.min()}..{segments.max()})")
    return _squad_keys(flat_keys, flat_controls, segments, alpha).reshape((len(segments), *keys.shape[1:]))


def squad_rate(
    q1: np.ndarray,
    q2: np.ndarray,
    s1: np.ndarray,
    s2: np.ndarray,
    samples: int = 16,
    *,
    above: np.ndarray | float | None = None,
) -> np.ndarray:
    """Peak turning rate (radians per unit ``alpha``) along each :func:`squad` segment.

    Squad bends a segment towards its neighbours, so near a sharp turn it moves faster
    than the straight ``angle_between(q1, q2)``; playback needs the true peak to keep
    to a speed limit. Measured over ``samples`` equal steps of ``alpha`` (the largest
    ``angle_between`` of consecutive points, times ``samples``), one segment at a time in a
    compiled loop, so memory stays flat however many segments (a whole graph's source
    steps) are asked for. One value per leading index (inputs broadcast).

    A caller that only cares whether a segment turns faster than some rate passes it as
    ``above`` (broadcast too): a segment whose :func:`squad_rate_bound` is at most that is
    not sampled (its rate cannot exceed it) and reports 0, which skips most segments of a
    course at the cost of four angles each.
    """
    arrays = np.broadcast_arrays(*(np.asarray(x, dtype=float) for x in (q1, q2, s1, s2)))
    shape = arrays[0].shape[:-1]
    flat = [np.ascontiguousarray(x).reshape(-1, 4) for x in arrays]
    alphas = _rate_alphas(samples)
    floor = np.ascontiguousarray(np.broadcast_to(-np.inf if above is None else above, shape), dtype=float).ravel()
    return _squad_rates(*flat, alphas, floor).reshape(shape)


@functools.lru_cache(maxsize=8)
def _rate_alphas(samples: int) -> np.ndarray:
    """The ``alpha`` of each :func:`squad_rate` step, made once per sample count (read-only)."""
    alphas = np.linspace(0.0, 1.0, samples + 1)[1:]
    alphas.flags.writeable = False
    return alphas


def squad_rate_bound(q1: np.ndarray, q2: np.ndarray, s1: np.ndarray, s2: np.ndarray) -> np.ndarray:
    """An upper bound on :func:`squad_rate`, from four angles instead of a sampled curve.

    On the unit sphere of quaternions (distance = half the rotation angle) squad is the
    point a fraction ``h = 2α(1 − α)`` along the short geodesic from ``A = slerp(q1, q2; α)``
    to ``B = slerp(s1, s2; α)``. That point moves no faster than ``|A'| + |B'| + |h'|·d(A, B)``
    (a moving end drags it by at most its own speed while ``d ≤ π/2``), with ``|h'| ≤ 2`` and
    ``d(A, B)`` at most half of ``(θ + θ_s)/2 + max(δ1, δ2)``, where ``θ, θ_s, δ1, δ2`` are
    the rotation angles ``q1→q2``, ``s1→s2``, ``q1→s1``, ``q2→s2``. In rotation angle per unit
    ``α`` that gives ``2(θ + θ_s + max(δ1, δ2))``. Where ``A`` and ``B`` may come half a turn
    apart (``(θ + θ_s)/2 + max(δ1, δ2)`` reaches π, less a margin for rounding) the short way
    between them can flip and squad jump, so the bound is infinite.
    """
    straight, inner = angle_between(q1, q2), angle_between(s1, s2)
    apart = np.maximum(angle_between(q1, s1), angle_between(q2, s2))
    return np.where(0.5 * (straight + inner) + apart < np.pi - 1e-6, 2.0 * (straight + inner + apart), np.inf)


def hemisphere_align(q: np.ndarray) -> np.ndarray:
    """Flip signs along axis 0 so each key-frame lies in the hemisphere of the one before."""
    q = np.asarray(q, dtype=float)
    flat = np.ascontiguousarray(q).reshape(len(q), math.prod(q.shape[1:-1]), 4)
    return _hemisphere_align(flat).reshape(q.shape)


def closest_approach(q1: np.ndarray, q2: np.ndarray, p: np.ndarray) -> np.ndarray:
    """The ``α̃`` taking the geodesic ``slerp(q1, q2; α)`` as close as possible to ``p``.

    Maximising ``slerp(q1, q2; α) · p`` with ``a = q1 · p``, ``b = q2 · p``, ``φ = acos(q1 · q2)``
    gives ``tan(αφ) = (b − a cos φ) / (a sin φ)``. The appendix prints
    ``atan(b / a − q1 · q2) / φ``, which drops the ``1 / sin φ`` factor; this is the exact
    stationary point. ``α̃`` is not clipped: values beyond 1 say the geodesic passes ``p``
    after reaching ``q2`` (used for the closest-transit term of the pose metric).
    Degenerate arcs (``q1 ≈ q2``) give ``α̃ = 0``.
    """
    q1 = np.asarray(q1, dtype=float)
    q2 = np.asarray(q2, dtype=float)
    p = np.asarray(p, dtype=float)
    c = dot(q1, q2)
    q2 = np.where((c < 0.0)[..., None], -q2, q2)
    c = np.abs(c)
    a = dot(q1, p)
    p = np.where((a < 0.0)[..., None], -p, p)
    a = np.abs(a)
    b = dot(q2, p)
    phi = np.arccos(np.minimum(c, 1.0))
    s = np.sin(phi)
    theta = np.arctan2(b - a * c, a * s)
    return np.where(phi > 1e-9, theta / np.maximum(phi, 1e-9), 0.0)


# --- compiled kernels -------------------------------------------------------------------
# One quaternion is a (w, x, y, z) tuple, one vector an (x, y, z) tuple: each function is
# the single-quaternion form of the numpy function of the same name above, written in the
# same order of operations so the two agree to rounding.


@numba.njit(cache=True)
def dot_one(p, q):  # pragma: no cover - compiled
    return p[0] * q[0] + p[1] * q[1] + p[2] * q[2] + p[3] * q[3]


@numba.njit(cache=True)
def normalize_one(w, x, y, z):  # pragma: no cover - compiled
    norm = math.sqrt(w * w + x * x + y * y + z * z)
    if norm > _EPS:
        return (w / norm, x / norm, y / norm, z / norm)
    return (1.0, 0.0, 0.0, 0.0)


@numba.njit(cache=True)
def multiply_one(p, q):  # pragma: no cover - compiled
    w1, x1, y1, z1 = p
    w2, x2, y2, z2 = q
    return (
        w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
        w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
        w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
        w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
    )


@numba.njit(cache=True)
def _cross_one(a, b):  # pragma: no cover - compiled
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@numba.njit(cache=True)
def rotate_one(q, v):  # pragma: no cover - compiled
    u = (q[1], q[2], q[3])
    c = _cross_one(u, v)
    t = (2.0 * c[0], 2.0 * c[1], 2.0 * c[2])
    r = _cross_one(u, t)
    return (v[0] + q[0] * t[0] + r[0], v[1] + q[0] * t[1] + r[1], v[2] + q[0] * t[2] + r[2])


@numba.njit(cache=True)
def log_one(q):  # pragma: no cover - compiled
    sign = -1.0 if q[0] < 0.0 else 1.0
    w, x, y, z = sign * q[0], sign * q[1], sign * q[2], sign * q[3]
    sin_half = math.sqrt(x * x + y * y + z * z)
    scale = 2.0 * math.atan2(sin_half, w) / max(sin_half, _EPS) if sin_half > _EPS else 2.0
    return (x * scale, y * scale, z * scale)


@numba.njit(cache=True)
def exp_one(v):  # pragma: no cover - compiled
    angle = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    norm = max(angle, _EPS)
    s = math.sin(0.5 * angle)
    return (math.cos(0.5 * angle), v[0] / norm * s, v[1] / norm * s, v[2] / norm * s)


@numba.njit(cache=True)
def angle_between_one(p, q):  # pragma: no cover - compiled
    """The rotation angle from the chord, ``4·asin(|p − s·q| / 2)`` with ``s`` the sign of ``p · q``.

    Not ``2·acos(|p · q|)``: the arc cosine is flat at 1, so one ulp of the dot product is
    ≈ 1.5e-8 rad there, and two equal rotations came out that far apart. The chord keeps full
    precision near zero, and its arc sine is cheaper than the arc cosine.
    """
    s = -1.0 if dot_one(p, q) < 0.0 else 1.0
    chord = 0.0
    for i in range(4):
        chord += (p[i] - s * q[i]) ** 2
    return 4.0 * math.asin(min(0.5 * math.sqrt(chord), 1.0))


# Not cached: numba's cache of this generalised ufunc, written while two processes compiled
# the functions it calls, loaded as a call through a null pointer, and every later process
# that drew a motor graph crashed (a CI run's fresh cache, 14 tests). Compiled per process it
# costs ~90 ms once, what it calls coming from the cache.
@numba.guvectorize(["void(float64[:], float64[:], float64[:])"], "(n),(n)->()")
def _angles(p, q, out):  # pragma: no cover - compiled
    out[0] = angle_between_one(p, q)


@numba.njit(cache=True)
def slerp_one(p, q, alpha):  # pragma: no cover - compiled
    c = dot_one(p, q)
    sign = -1.0 if c < 0.0 else 1.0
    phi = math.acos(min(abs(c), 1.0))
    s = math.sin(phi)
    if s < 1e-6:
        a, b = 1.0 - alpha, alpha
    else:
        a, b = math.sin((1.0 - alpha) * phi) / s, math.sin(alpha * phi) / s
    return normalize_one(
        a * p[0] + b * (sign * q[0]), a * p[1] + b * (sign * q[1]), a * p[2] + b * (sign * q[2]), a * p[3] + b * (sign * q[3])
    )


@numba.njit(cache=True)
def closest_approach_one(q1, q2, p):  # pragma: no cover - compiled
    c = dot_one(q1, q2)
    if c < 0.0:
        q2 = (-q2[0], -q2[1], -q2[2], -q2[3])
    c = abs(c)
    a = dot_one(q1, p)
    if a < 0.0:
        p = (-p[0], -p[1], -p[2], -p[3])
    a = abs(a)
    b = dot_one(q2, p)
    phi = math.acos(min(c, 1.0))
    theta = math.atan2(b - a * c, a * math.sin(phi))
    return theta / max(phi, 1e-9) if phi > 1e-9 else 0.0


@numba.njit(cache=True)
def squad_one(q1, q2, s1, s2, alpha):  # pragma: no cover - compiled
    return slerp_one(slerp_one(q1, q2, alpha), slerp_one(s1, s2, alpha), 2.0 * alpha * (1.0 - alpha))


@numba.njit(cache=True)
def _at(q, i):  # pragma: no cover - compiled
    return (q[i, 0], q[i, 1], q[i, 2], q[i, 3])


@numba.njit(cache=True)
def _control_one(prev, q, nxt):  # pragma: no cover - compiled
    inv = (q[0], -q[1], -q[2], -q[3])
    ahead = log_one(multiply_one(inv, nxt))
    behind = log_one(multiply_one(inv, prev))
    return multiply_one(q, exp_one((-0.25 * (ahead[0] + behind[0]), -0.25 * (ahead[1] + behind[1]), -0.25 * (ahead[2] + behind[2]))))


@numba.njit(cache=True)
def _hemisphere_align(q):  # pragma: no cover - compiled
    """:func:`hemisphere_align` of ``(N, M, 4)``: each key's sign from the original dot products."""
    aligned = q.copy()
    for j in range(q.shape[1]):
        sign = 1.0
        for i in range(1, q.shape[0]):
            if dot_one(_at(q[:, j], i), _at(q[:, j], i - 1)) < 0.0:
                sign = -sign
            for c in range(4):
                aligned[i, j, c] = sign * q[i, j, c]
    return aligned


@numba.njit(cache=True)
def _squad_controls(q):  # pragma: no cover - compiled
    """:func:`squad_controls` of keys ``(N, M, 4)``: align each of the M tracks, then control it."""
    n = q.shape[0]
    aligned = _hemisphere_align(q)
    out = np.empty_like(q)
    for j in range(q.shape[1]):
        track = aligned[:, j]
        for i in range(n):
            control = _control_one(_at(track, max(i - 1, 0)), _at(track, i), _at(track, min(i + 1, n - 1)))
            for c in range(4):
                out[i, j, c] = control[c]
    return out


@numba.njit(cache=True)
def _controls_at(q, before, after):  # pragma: no cover - compiled
    """:func:`squad_control_at` of keys ``(N, J, 4)``."""
    out = np.empty_like(q)
    for n in range(q.shape[0]):
        for j in range(q.shape[1]):
            control = _control_one(_at(q[before[n]], j), _at(q[n], j), _at(q[after[n]], j))
            for c in range(4):
                out[n, j, c] = control[c]
    return out


@numba.njit(cache=True)
def _squad_keys(keys, controls, segments, alpha):  # pragma: no cover - compiled
    """:func:`squad_keys` over keys and controls ``(K, M, 4)``."""
    out = np.empty((segments.shape[0], keys.shape[1], 4))
    for t in range(segments.shape[0]):
        k = segments[t]
        for j in range(keys.shape[1]):
            point = squad_one(_at(keys[k], j), _at(keys[k + 1], j), _at(controls[k], j), _at(controls[k + 1], j), alpha[t])
            for c in range(4):
                out[t, j, c] = point[c]
    return out


@numba.njit(cache=True)
def _squad_rate_bound_one(q1, q2, s1, s2):  # pragma: no cover - compiled
    straight, inner = angle_between_one(q1, q2), angle_between_one(s1, s2)
    apart = max(angle_between_one(q1, s1), angle_between_one(q2, s2))
    return 2.0 * (straight + inner + apart) if 0.5 * (straight + inner) + apart < np.pi - 1e-6 else np.inf


@numba.njit(cache=True)
def _squad_rates(q1, q2, s1, s2, alphas, above):  # pragma: no cover - compiled
    """:func:`squad_rate` of ``(M, 4)`` segments at the given ``alphas`` (0 where the bound is ≤ ``above``)."""
    out = np.zeros(q1.shape[0])
    for m in range(q1.shape[0]):
        a, b, c, d = _at(q1, m), _at(q2, m), _at(s1, m), _at(s2, m)
        if above[m] > -np.inf and _squad_rate_bound_one(a, b, c, d) <= above[m]:
            continue
        # The two inner arcs are fixed along the segment: their angles are taken once, not at
        # every sample (squad_one's result, to rounding, at half the arc cosines).
        # The widest step is the one whose ends are least aligned, so the steps' |cos| are
        # compared and one arccos is taken, of the smallest.
        first, second = _arc(a, b), _arc(c, d)
        previous = a
        closest = 1.0
        for alpha in alphas:
            point = slerp_one(_on_arc(first, alpha), _on_arc(second, alpha), 2.0 * alpha * (1.0 - alpha))
            closest = min(closest, abs(dot_one(point, previous)))
            previous = point
        out[m] = 2.0 * math.acos(closest) * alphas.shape[0]
    return out


@numba.njit(cache=True)
def _arc(p, q):  # pragma: no cover - compiled
    """What :func:`slerp_one` from ``p`` to ``q`` needs whatever its ``alpha``: ``q`` turned into
    ``p``'s hemisphere, the arc's angle and its sine."""
    c = dot_one(p, q)
    sign = -1.0 if c < 0.0 else 1.0
    phi = math.acos(min(abs(c), 1.0))
    return p, (sign * q[0], sign * q[1], sign * q[2], sign * q[3]), phi, math.sin(phi)


@numba.njit(cache=True)
def _on_arc(arc, alpha):  # pragma: no cover - compiled
    """The point ``alpha`` along an :func:`_arc` (:func:`slerp_one`'s arithmetic)."""
    p, q, phi, s = arc
    if s < 1e-6:
        a, b = 1.0 - alpha, alpha
    else:
        a, b = math.sin((1.0 - alpha) * phi) / s, math.sin(alpha * phi) / s
    return normalize_one(a * p[0] + b * q[0], a * p[1] + b * q[1], a * p[2] + b * q[2], a * p[3] + b * q[3])


@numba.njit(cache=True)
def _slerp_rows(q1, q2, alpha):  # pragma: no cover - compiled
    out = np.empty_like(q1)
    for j in range(q1.shape[0]):
        point = slerp_one(_at(q1, j), _at(q2, j), alpha)
        for c in range(4):
            out[j, c] = point[c]
    return out


@numba.njit(cache=True)
def _turn_rates(q, previous, dt):  # pragma: no cover - compiled
    """``log(q · previous⁻¹) / dt`` of two ``(J, 4)`` poses: the angular velocities ``(J, 3)``
    that carried ``previous`` to ``q`` in ``dt`` seconds, the short way (a shown frame's,
    :meth:`creatures.motor.blend.Limits.frame`)."""
    out = np.empty((q.shape[0], 3))
    for j in range(q.shape[0]):
        p = _at(previous, j)
        v = log_one(multiply_one(_at(q, j), (p[0], -p[1], -p[2], -p[3])))
        for c in range(3):
            out[j, c] = v[c] / dt
    return out


@numba.njit(cache=True)
def _turns_about(count, joints, axes, angles):  # pragma: no cover - compiled
    vectors = np.zeros((count, 3))
    for k in range(joints.shape[0]):
        for c in range(3):
            vectors[joints[k], c] += axes[k, c] * angles[k]
    out = np.empty((count, 4))
    for j in range(count):
        q = exp_one((vectors[j, 0], vectors[j, 1], vectors[j, 2]))
        for c in range(4):
            out[j, c] = q[c]
    return out


@numba.njit(cache=True)
def _normalize_rows(q):  # pragma: no cover - compiled
    """:func:`normalize` of ``(N, 4)`` in place (the copy ``normalize`` made)."""
    for i in range(q.shape[0]):
        norm = math.sqrt(q[i, 0] * q[i, 0] + q[i, 1] * q[i, 1] + q[i, 2] * q[i, 2] + q[i, 3] * q[i, 3])
        if norm <= _EPS:
            q[i, 0], q[i, 1], q[i, 2], q[i, 3] = 1.0, 0.0, 0.0, 0.0
        else:
            for c in range(4):
                q[i, c] /= norm
    return q
