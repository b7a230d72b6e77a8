"""Several contributions, one degree of freedom: the per-frame blend of a body and a voice.

Thesis "blend-based motor systems" and "general layering"; DESIGN.md "Several actions, one
degree of freedom"; STYLE.md's OpenSteer note (contributions in, one named policy out). Where
a motor graph alone lets the last course win, here each active contributor adds to every
channel (a joint, or a scalar voice/synthesis parameter) either a value with a weight or an
offset, and named policies resolve them each frame, in this order:

``mean``
    ``(value, weight)``: the weighted mean of every ``mean`` contribution. On joints it is
    the weighted geodesic (Karcher) mean on the 3-sphere, started at the heaviest value and
    iterated in the tangent space (log/exp the short way round, so ``q`` and ``−q`` count
    as the same rotation); for two rotations its first step is already the exact weighted
    slerp (weights 3 and 1 on 0° and 45° give 11.25°). A single contributor is passed
    through untouched. Weights summing below 1 leave the rest to the blend's ``hold`` (so a
    lone contributor fading in eases from the hold rather than snapping to itself). The
    motor graph's course is one ``mean`` contributor among others.
``exclusive``
    Mutually exclusive layers: in rising priority, each is slerped over what is below by
    its weight, so fully in, the highest priority holds the channel outright.
``add``
    Offsets over the base (a rotation composed in the joint's frame, or a number added),
    scaled by their weights: breathing over a walk, jitter over a hold.
``budget``
    IViHumans' "weighted truncated running sum with prioritisation": offsets in falling
    priority, each truncated to what the channel's budget has left (an angle on a joint, an
    amount on a scalar), so budget 1.0 over 0.7, 0.6, 0.5 gives 0.7 + 0.3 + 0.

Each contributor's weight is ramped on clock time, not ticks: it eases in (smoothstep) over
``fade`` seconds when it starts and out over ``fade`` when it stops, then it is dropped, so a
channel returns exactly to what the others make of it. A per-channel ``mask`` (weights in
[0, 1]) confines a layer to some joints: a head layer over a walking body.

The resolution runs compiled (numba) over all channels at once, from the one-quaternion
helpers of :mod:`creatures.motor.quaternion`; :class:`Limits` then keeps every frame within
the source material's joint range and its fastest joint speed.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field
from typing import Callable

import numba
import numpy as np

from creatures.motor import quaternion as quat
from creatures.motor.pose import PoseSet
from creatures.motor.skeleton import Skeleton, _forward_kinematics


class Policy(enum.IntEnum):
    """How a contribution combines with the others (module docstring; resolved in this order)."""

    MEAN = 0
    EXCLUSIVE = 1
    ADD = 2
    BUDGET = 3


Source = Callable[[float], np.ndarray]
"""A contributor's value at clock time ``t``: rotations ``(J, 4)`` or scalars ``(P,)``."""


@dataclass(eq=False)
class Contribution:
    """One contributor to a :class:`Blend`: where its value comes from and how it counts.

    ``weight`` scales it (for ``add`` and ``budget`` offsets too), ``priority`` orders the
    ``exclusive`` and ``budget`` stages, ``mask`` (one weight per channel) confines it, and
    ``fade`` is the ease-in/ease-out time in seconds (0: switched, not faded).
    """

    name: str
    source: Source
    policy: Policy = Policy.MEAN
    weight: float = 1.0
    priority: float = 0.0
    mask: np.ndarray | None = None
    fade: float = 0.25
    started: float = field(default=-math.inf, init=False)
    stopped: float = field(default=math.inf, init=False)

    def __post_init__(self) -> None:
        self.policy = Policy(self.policy)
        if not self.fade >= 0.0 or not self.weight >= 0.0:
            raise ValueError(f"contribution {self.name!r}: fade and weight must be ≥ 0 (got {self.fade}, {self.weight})")

    def level(self, t: float) -> float:
        """The crossfade envelope at ``t`` (0..1): eased in from ``started``, out from ``stopped``."""
        return float(_level(self.started, self.stopped, self.fade, t))

    def gone(self, t: float) -> bool:
        """Faded out completely: the blend drops it."""
        return t >= self.stopped + self.fade


class Blend:
    """The contributions to ``channels`` channels, resolved per frame by :meth:`resolve`.

    ``rotations`` says whether the channels are joints (values ``(J, 4)``) or scalars
    (``(P,)``); ``budget`` is the per-channel allowance of the ``budget`` stage (radians of
    rotation on a joint). ``hold`` is the value a channel keeps when no ``mean``
    contribution has weight there (the identity rotation or 0 unless given).
    """

    def __init__(self, channels: int, *, rotations: bool = True, budget: float | np.ndarray = math.inf,
                 hold: np.ndarray | None = None) -> None:
        self.channels = channels
        self.rotations = rotations
        self.budget = np.ascontiguousarray(np.broadcast_to(budget, (channels,)), dtype=float)
        shape = (channels, 4) if rotations else (channels,)
        self.hold = np.ascontiguousarray(quat.identity((channels,)) if rotations and hold is None
                                         else np.zeros(shape) if hold is None else hold, dtype=float)
        if self.hold.shape != shape:
            raise ValueError(f"blend hold has shape {self.hold.shape}, the channels need {shape}")
        self.contributions: list[Contribution] = []
        self._arrays: tuple[np.ndarray, ...] | None = None
        self._drop_at = math.inf  # when the next contributor has faded out (made with the arrays)

    def start(self, contribution: Contribution, t: float) -> Contribution:
        """Add a contributor that eases in from ``t``, replacing one of the same name (and
        going on from the level that one had at ``t``, so a layer restarted as it fades out
        does not dip)."""
        if contribution.mask is not None:
            contribution.mask = np.clip(np.asarray(contribution.mask, dtype=float), 0.0, 1.0)
            if contribution.mask.shape != (self.channels,):
                raise ValueError(f"contribution {contribution.name!r}: mask has shape {contribution.mask.shape},"
                                 f" the blend has {self.channels} channels")
        before = next((c.level(t) for c in self.contributions if c.name == contribution.name), 0.0)
        self.contributions = [c for c in self.contributions if c.name != contribution.name]
        # Restarted while still (partly) in, it goes on from the level it had: no dip to 0 and back.
        eased = 0.5 - math.sin(math.asin(1.0 - 2.0 * before) / 3.0) if 0.0 < before < 1.0 else float(before >= 1.0)
        contribution.started, contribution.stopped = t - eased * contribution.fade, math.inf
        self.contributions.append(contribution)
        self._arrays = None
        return contribution

    def stop(self, name: str, t: float) -> None:
        """Ease the named contributor out from ``t``; it is dropped once faded."""
        for c in self.contributions:
            if c.name == name and c.stopped > t:
                c.stopped = t
                self._arrays = None

    def contributors(self, t: float) -> dict[str, float]:
        """Each contributor's weight at ``t`` (its ``weight`` × crossfade level): what the
        events log records of a blend."""
        return {c.name: c.weight * c.level(t) for c in self.contributions}

    def channel_contributors(self, t: float) -> list[dict[str, float]]:
        """Per channel, each contributor's weight there at ``t`` (weight × mask × crossfade),
        those with none left out: who drives each joint or parameter, for the events log."""
        out: list[dict[str, float]] = [{} for _ in range(self.channels)]
        for c in self.contributions:
            w = c.weight * c.level(t)
            if w <= 0.0:
                continue
            for j in range(self.channels) if c.mask is None else np.flatnonzero(c.mask > 0.0):
                out[j][c.name] = w if c.mask is None else w * float(c.mask[j])
        return out

    def __contains__(self, name: str) -> bool:
        return any(c.name == name for c in self.contributions)

    def _order(self) -> tuple[np.ndarray, ...]:
        """Per-contributor arrays in resolution order: stage, then priority (rising for
        ``exclusive``, falling for ``budget``), remade only when the set changes."""
        if self._arrays is None:
            self.contributions.sort(key=lambda c: (c.policy, -c.priority if c.policy is Policy.BUDGET else c.priority))
            cs = self.contributions
            masks = np.ones((len(cs), self.channels))
            for i, c in enumerate(cs):
                if c.mask is not None:
                    masks[i] = c.mask
            self._drop_at = min((c.stopped + c.fade for c in cs), default=math.inf)
            # the contributors' values each frame, filled in place (one array per set, not per frame)
            self._values = np.empty((len(cs), self.channels, 4) if self.rotations else (len(cs), self.channels))
            self._arrays = (
                np.array([int(c.policy) for c in cs], dtype=np.int64),
                masks * np.array([c.weight for c in cs]).reshape(-1, 1),
                np.array([c.started for c in cs], dtype=float),
                np.array([c.stopped for c in cs], dtype=float),
                np.array([c.fade for c in cs], dtype=float),
            )
        return self._arrays

    def resolve(self, t: float) -> np.ndarray:
        """Every channel at clock time ``t``, all contributions resolved (faded-out ones dropped)."""
        self._order()
        if t >= self._drop_at:
            self.contributions = [c for c in self.contributions if not c.gone(t)]
            self._arrays = None
        policies, weights, started, stopped, fades = self._order()
        values = self._values
        for i, c in enumerate(self.contributions):
            value = c.source(t)
            if not isinstance(value, np.ndarray):
                value = np.asarray(value, dtype=float)
            if value.shape != values.shape[1:]:
                raise ValueError(f"contribution {c.name!r} gave a value of shape {value.shape}; the blend's"
                                 f" channels are {values.shape[1:]}")
            values[i] = value
        kernel = _blend_rotations if self.rotations else _blend_scalars
        return kernel(values, weights, policies, started, stopped, fades, float(t), self.budget, self.hold)


@dataclass(frozen=True)
class Limits:
    """What a blended frame may not exceed: each joint's range in the source material (the
    largest rotation from rest any source pose shows: a ball of rotation vectors about rest) and
    the source's fastest joint speed (``graph.timing.max_speed``, rad/s)."""

    range: np.ndarray  # (J,) radians
    max_speed: float

    @classmethod
    def of(cls, poses: PoseSet, max_speed: float) -> "Limits":
        rest = quat.identity(poses.rotations.shape[1:2])
        return cls(np.ascontiguousarray(quat.angle_between(poses.rotations, rest).max(axis=0)), float(max_speed))

    def apply(self, rotations: np.ndarray, previous: np.ndarray | None, dt: float) -> np.ndarray:
        """``rotations`` pulled into range, then no further from ``previous`` than ``dt``
        seconds at the top speed allows. Both are done on rotation vectors (``log``), where
        the range is a ball, which is convex, so the speed step keeps the range even where
        it exceeds a quarter turn (a slerp the short way between two in-range rotations can
        leave it); and ``exp`` never lengthens a step (the rotation group's curvature is
        positive), so the speed bound holds for the rotations themselves. Frames already
        within both pass through untouched."""
        prev = rotations if previous is None else previous
        return _limit(np.ascontiguousarray(rotations, dtype=float), np.ascontiguousarray(prev, dtype=float),
                      self.range, self.max_speed * max(dt, 0.0), previous is not None)

    def frame(self, rotations: np.ndarray, previous: np.ndarray, dt: float, skeleton: Skeleton,
              root: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """A body's shown frame from a blended pose and the frame before it, ``dt`` seconds
        earlier (> 0): :meth:`apply`, the angular velocities that carried the frame before to
        it, and its joint positions, in one compiled call (once a tick per body, where three
        calls' overhead was a tenth of what a layer costs the tick)."""
        return _frame(np.ascontiguousarray(rotations, dtype=float), np.ascontiguousarray(previous, dtype=float),
                      self.range, self.max_speed * dt, float(dt), skeleton.parents, skeleton.offsets,
                      np.asarray(root, dtype=float))


class Oscillator:
    """A sinusoidal offset over named joints (breathing, swaying): rotation about each joint's
    axis by ``depth × sin(2πt / period)`` radians, the identity on every other joint. Used as
    the source of an ``add`` contribution."""

    def __init__(self, names: tuple[str, ...] | list[str], axes: dict[str, tuple[float, float, float]],
                 *, period: float, depth: float, phase: float = 0.0) -> None:
        if not period > 0.0:
            raise ValueError(f"oscillator period must be positive (got {period!r})")
        self.axes = np.zeros((len(names), 3))
        for name, axis in axes.items():
            if name not in names:
                raise ValueError(f"oscillator names joint {name!r}, which the skeleton lacks (joints: {', '.join(names)})")
            vector = np.asarray(axis, dtype=float)
            self.axes[list(names).index(name)] = vector / max(float(np.linalg.norm(vector)), 1e-12)
        self.period, self.depth, self.phase = float(period), float(depth), float(phase)

    @property
    def mask(self) -> np.ndarray:
        """The joints it moves (1) and leaves alone (0)."""
        return (np.abs(self.axes).sum(axis=1) > 0.0).astype(float)

    def __call__(self, t: float) -> np.ndarray:
        return _turns(self.axes, self.depth * math.sin(2.0 * math.pi * t / self.period + self.phase))


def weighted_mean(rotations: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """The weighted geodesic mean of rotations ``(C, J, 4)`` with weights ``(C, J)`` or ``(C,)``
    (the ``mean`` stage alone, weights normalised per channel so no hold joins in); channels
    without weight get the identity."""
    rotations = np.ascontiguousarray(rotations, dtype=float)
    c, j = rotations.shape[:2]
    w = np.broadcast_to(np.asarray(weights, dtype=float).reshape(c, -1), (c, j))
    w = np.ascontiguousarray(w / np.maximum(w.sum(axis=0), 1e-300))
    zeros = np.zeros(c)
    return _blend_rotations(rotations, w, np.zeros(c, dtype=np.int64), zeros - math.inf, zeros + math.inf,
                            zeros, 0.0, np.full(j, math.inf), quat.identity((j,)))


# --- compiled kernels -------------------------------------------------------------------

@numba.njit(cache=True)
def _turns(axes, angle):  # pragma: no cover - compiled
    """``quat.exp(axes × angle)`` for unit (or zero) axes ``(J, 3)``: one pose per tick, where
    numpy's call overhead was most of an oscillator's cost."""
    out = np.empty((axes.shape[0], 4))
    for j in range(axes.shape[0]):
        q = quat.exp_one((angle * axes[j, 0], angle * axes[j, 1], angle * axes[j, 2]))
        for c in range(4):
            out[j, c] = q[c]
    return out


@numba.njit(cache=True)
def _ease(u):  # pragma: no cover - compiled
    u = min(max(u, 0.0), 1.0)
    return u * u * (3.0 - 2.0 * u)


@numba.njit(cache=True)
def _level(started, stopped, fade, t):  # pragma: no cover - compiled
    if fade <= 0.0:
        return 1.0 if started <= t < stopped else 0.0
    return _ease((t - started) / fade) * (1.0 - _ease((t - stopped) / fade))


@numba.njit(cache=True)
def _scaled(q, k):  # pragma: no cover - compiled
    """``exp(k log q)``: a fraction ``k`` of rotation ``q`` (the short way)."""
    v = quat.log_one(q)
    return quat.exp_one((k * v[0], k * v[1], k * v[2]))


@numba.njit(cache=True)
def _norm3(v):  # pragma: no cover - compiled
    return math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])


@numba.njit(cache=True)
def _levels(started, stopped, fades, t):  # pragma: no cover - compiled
    """Every contributor's crossfade envelope at ``t``."""
    levels = np.empty(started.shape[0])
    for i in range(started.shape[0]):
        levels[i] = _level(started[i], stopped[i], fades[i], t)
    return levels


@numba.njit(cache=True)
def _karcher(values, weights, levels, policies, j, hold, ws, qs):  # pragma: no cover - compiled
    """The ``mean`` stage on joint ``j``: the weighted geodesic mean (see module docstring).

    Started from the normalised weighted sum of the values (each turned into the heaviest
    one's hemisphere, the chordal mean: within a hair of the geodesic one, and on the great
    circle of two), then Karcher steps until one moves it less than ``1e-10`` rad (at most
    8). Two values lie on one geodesic, so one step lands on their weighted slerp exactly.
    ``ws`` and ``qs`` are scratch space for the terms (the hold last, with the weight the
    contributors leave below 1).
    """
    total, heaviest, top, n = 0.0, -1, 0.0, 0
    for i in range(values.shape[0]):
        w = weights[i, j] * levels[i]
        if policies[i] == 0 and w > 0.0:
            total += w
            ws[n] = w
            for c in range(4):
                qs[n, c] = values[i, j, c]
            n += 1
            if w > top:
                top, heaviest = w, n - 1
    if n == 0:
        return (hold[j, 0], hold[j, 1], hold[j, 2], hold[j, 3])
    h = quat._at(qs, heaviest)
    if n == 1 and total >= 1.0:
        return h
    if total < 1.0:
        ws[n] = 1.0 - total
        for c in range(4):
            qs[n, c] = hold[j, c]
        n += 1
        total = 1.0
    cw, cx, cy, cz = 0.0, 0.0, 0.0, 0.0
    for i in range(n):
        w = ws[i] if quat.dot_one(quat._at(qs, i), h) >= 0.0 else -ws[i]
        cw += w * qs[i, 0]
        cx += w * qs[i, 1]
        cy += w * qs[i, 2]
        cz += w * qs[i, 3]
    m = quat.normalize_one(cw, cx, cy, cz)
    for _ in range(8):
        inv = (m[0], -m[1], -m[2], -m[3])
        sx, sy, sz = 0.0, 0.0, 0.0
        for i in range(n):
            v = quat.log_one(quat.multiply_one(inv, quat._at(qs, i)))
            sx += ws[i] * v[0]
            sy += ws[i] * v[1]
            sz += ws[i] * v[2]
        step = (sx / total, sy / total, sz / total)
        size = _norm3(step)
        if size < 1e-15:
            break
        m = quat.normalize_one(*quat.multiply_one(m, quat.exp_one(step)))
        if size < 1e-10:
            break
    return m


@numba.njit(cache=True)
def _blend_rotations(values, weights, policies, started, stopped, fades, t, budget, hold):  # pragma: no cover - compiled
    """:meth:`Blend.resolve` on joints: values ``(C, J, 4)`` in resolution order."""
    c_count, j_count = values.shape[0], values.shape[1]
    levels = _levels(started, stopped, fades, t)
    out = np.empty((j_count, 4))
    ws, qs = np.empty(c_count + 1), np.empty((c_count + 1, 4))
    for j in range(j_count):
        q = _karcher(values, weights, levels, policies, j, hold, ws, qs)
        left = budget[j]
        for i in range(c_count):
            w = weights[i, j] * levels[i]
            if policies[i] == 0 or w <= 0.0:
                continue
            v = quat._at(values[i], j)
            if policies[i] == 1:
                q = quat.slerp_one(q, v, min(w, 1.0))
            elif policies[i] == 2:
                q = quat.normalize_one(*quat.multiply_one(q, _scaled(v, w)))
            else:
                angle = w * _norm3(quat.log_one(v))
                take = min(angle, max(left, 0.0))
                if take > 0.0:
                    q = quat.normalize_one(*quat.multiply_one(q, _scaled(v, w * take / angle)))
                left -= take
        for k in range(4):
            out[j, k] = q[k]
    return out


@numba.njit(cache=True)
def _blend_scalars(values, weights, policies, started, stopped, fades, t, budget, hold):  # pragma: no cover - compiled
    """:meth:`Blend.resolve` on scalars: values ``(C, P)`` in resolution order."""
    c_count, p_count = values.shape[0], values.shape[1]
    levels = _levels(started, stopped, fades, t)
    out = np.empty(p_count)
    for p in range(p_count):
        total, acc = 0.0, 0.0
        for i in range(c_count):
            w = weights[i, p] * levels[i]
            if policies[i] == 0 and w > 0.0:
                total += w
                acc += w * values[i, p]
        rest = max(1.0 - total, 0.0)
        x = (acc + rest * hold[p]) / (total + rest)
        left = budget[p]
        for i in range(c_count):
            w = weights[i, p] * levels[i]
            if policies[i] == 0 or w <= 0.0:
                continue
            if policies[i] == 1:
                k = min(w, 1.0)
                x = (1.0 - k) * x + k * values[i, p]
            elif policies[i] == 2:
                x += w * values[i, p]
            else:
                amount = w * values[i, p]
                take = min(abs(amount), max(left, 0.0))
                x += take if amount >= 0.0 else -take
                left -= take
        out[p] = x
    return out


@numba.njit(cache=True)
def _limit(rotations, previous, limits, max_step, moving):  # pragma: no cover - compiled
    """:meth:`Limits.apply`: each joint's rotation into the ball of its range (as a rotation
    vector), then no further than ``max_step`` from the previous frame's (untouched when
    within both).

    The step goes along the short arc toward the frame when that arc's end keeps the range,
    and along the straight line between rotation vectors (which the convex ball always keeps)
    only when it does not. Rotation vectors alone misled near a half turn: two rotations either
    side of π lie 2π apart as vectors but a hair apart as turns, and the step went the long
    way round (measured: the dog's folded hock, 179°, shown 3 rad behind its course and its
    paws 4 cm through the floor)."""
    out = rotations.copy()
    for j in range(rotations.shape[0]):
        a = quat.log_one(quat._at(rotations, j))
        angle = _norm3(a)
        clamped = angle > limits[j]
        if clamped:
            k = limits[j] / angle
            a = (k * a[0], k * a[1], k * a[2])
        q = quat.exp_one(a) if clamped else quat._at(rotations, j)
        if moving:
            p = quat._at(previous, j)
            gap = quat.angle_between_one(p, q)
            if gap > max_step:
                clamped = True
                q = quat.slerp_one(p, q, max_step / gap)
                if _norm3(quat.log_one(q)) > limits[j]:
                    b = quat.log_one(p)
                    d = (a[0] - b[0], a[1] - b[1], a[2] - b[2])
                    k = max_step / max(_norm3(d), 1e-300)
                    q = quat.exp_one((b[0] + k * d[0], b[1] + k * d[1], b[2] + k * d[2]))
        if clamped:
            for c in range(4):
                out[j, c] = q[c]
    return out


@numba.njit(cache=True)
def _frame(rotations, previous, limits, max_step, dt, parents, offsets, root):  # pragma: no cover - compiled
    """:meth:`Limits.frame`."""
    shown = _limit(rotations, previous, limits, max_step, True)
    velocities = quat._turn_rates(shown, previous, dt)
    positions = _forward_kinematics(shown.reshape(1, shown.shape[0], 4), root.reshape(1, 3), parents, offsets)[0]
    return shown, velocities, positions
