"""Skills over named parameters: servos, the current→min→max→current sweep, and looking.

WavesWorld's skill agents ("Reflex, Oscillator, or Servo-Mechanism", after Gallistel) measure
and manipulate a character's *articulated variables* by name; the thesis's blend-based motor
system ("in joint representation blending & processing") lets such skills each add their part
to a joint instead of overwriting it. Here a skill is plain state over a vector of named
scalar variables (joint angles about an axis, or voice parameters), advanced on clock time:

* :class:`Servo` — negative feedback toward a target at a bounded rate, with *patience*: if
  the error has not fallen within ``tolerance`` after ``patience`` seconds it gives up
  (WavesWorld: "it might 'give up', i.e. just stop the servomechanism and exit").
* :class:`Sweep` — WavesWorld's ``currentMinMaxCurrent`` over a list of variables at constant
  velocity (its second, initial-condition-insensitive version): each variable goes from where
  it is down to its min, up to its max and back, its own phases proportioned by its own
  distances, all ending together after ``duration``.
* :func:`look_turns` — looking is eyes first, then the head within its limits, then the body:
  the turn toward a bearing (taken the short way round) is shared along a chain of joints,
  each taking what its limit allows of what is left (a prioritised budget, as IViHumans' sum).
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np



def shortest(degrees: float) -> float:
    """An angle wrapped into [−180, 180): the short way round to it."""
    return (float(degrees) + 180.0) % 360.0 - 180.0


def look_turns(bearing: float, limits: Sequence[float], stages: Sequence[int] | None = None) -> np.ndarray:
    """Each chain joint's turn (degrees) toward ``bearing`` (degrees, positive to the left):
    the first stage (the eyes) takes what its limit allows, the next (the head) what is left
    within its own, and so on to the body; the bearing is first taken the short way round.

    ``stages`` (one number per joint, default each its own) puts joints that move as one in
    one stage: both eyes turn by the same angle, within the smaller of their limits, and take
    their share of the bearing once (see :func:`paired_stages`)."""
    left = shortest(bearing)
    stages = range(len(limits)) if stages is None else stages
    tightest: dict[int, float] = {}
    for stage, limit in zip(stages, limits):
        tightest[stage] = min(tightest.get(stage, math.inf), float(limit))
    taken: dict[int, float] = {}
    turns = []
    for stage in stages:
        if stage not in taken:
            limit = tightest[stage]
            taken[stage] = min(max(left, -limit), limit)
            left -= taken[stage]
        turns.append(taken[stage])
    return np.array(turns)


def paired_stages(names: Sequence[str]) -> list[int]:
    """A stage per joint of a look chain, a left/right pair (``eye_l`` and ``eye_r``) sharing
    one: a pair turns together, as eyes do."""
    stems = [name[:-2] if name.endswith(("_l", "_r")) else name for name in names]
    first = {stem: i for i, stem in reversed(list(enumerate(stems)))}
    return [first[stem] for stem in stems]


class Servo:
    """Follows a target vector at up to ``rate`` units per second (per variable), measuring the
    error. Patience: once any variable has been further than ``tolerance`` from its target for
    ``patience`` seconds on end (a target moving away faster than it can follow, or out of
    reach), it gives up (``gave_up``) and stops; a new :meth:`aim` after that starts it again.
    ``patience`` ∞: it never gives up."""

    def __init__(self, size: int, *, rate: float, tolerance: float = 1e-6, patience: float = math.inf) -> None:
        if not rate > 0.0:
            raise ValueError(f"a servo needs a positive rate (got {rate!r})")
        self.value = np.zeros(size)
        self.target = np.zeros(size)
        self.rate, self.tolerance, self.patience = float(rate), float(tolerance), float(patience)
        self.within_at = -math.inf  # the last time the error was within tolerance
        self.time: float | None = None
        self.gave_up = False

    def aim(self, target: np.ndarray, t: float) -> None:
        """Follow ``target`` from ``t`` (a servo that was on target, or had given up, starts
        counting its patience now)."""
        if self.reached or self.gave_up:
            self.within_at, self.gave_up = t, False
        self.target = np.asarray(target, dtype=float).copy()

    @property
    def error(self) -> float:
        # plain floats: a servo has a handful of variables and is asked every tick
        return max(map(abs, (self.target - self.value).tolist()), default=0.0)

    @property
    def reached(self) -> bool:
        return self.error <= self.tolerance

    def eta(self, t: float) -> float:
        """When, at the full rate, the value will be at the target (``t`` if it is)."""
        return t + self.error / self.rate

    def step(self, t: float) -> np.ndarray:
        """The value at clock time ``t`` (moved at most ``rate × dt`` toward the target)."""
        if self.time is not None and t > self.time and not self.gave_up:
            most = self.rate * (t - self.time)
            self.value += np.minimum(np.maximum(self.target - self.value, -most), most)
            if self.reached:
                self.within_at = t
            elif t - self.within_at > self.patience:
                self.gave_up = True
        self.time = t if self.time is None else max(self.time, t)
        return self.value


class Sweep:
    """``currentMinMaxCurrent`` (WavesWorld, constant velocity) over ``len(minima)`` variables
    from their values at :meth:`start`, lasting ``duration`` seconds."""

    def __init__(self, minima: Sequence[float], maxima: Sequence[float], duration: float) -> None:
        self.minima, self.maxima = np.asarray(minima, dtype=float), np.asarray(maxima, dtype=float)
        if self.minima.shape != self.maxima.shape:
            raise ValueError(f"list length mismatch: {len(self.minima)} minima, {len(self.maxima)} maxima")
        if np.any(self.minima > self.maxima):
            raise ValueError("every minimum must be at most its maximum")
        if not duration > 0.0:
            raise ValueError(f"a sweep needs a positive duration (got {duration!r})")
        self.duration = float(duration)
        self.started = -math.inf
        self.initial = np.zeros_like(self.minima)

    def start(self, initial: np.ndarray, t: float) -> None:
        """Begin from the variables' current values (clipped into [min, max], as the sweep
        passes through both ends)."""
        self.initial = np.clip(np.asarray(initial, dtype=float), self.minima, self.maxima)
        self.started = t
        down, span = self.initial - self.minima, self.maxima - self.minima
        distance = np.maximum(down + span + (self.maxima - self.initial), 1e-300)
        self._ua, self._ub = down / distance, (down + span) / distance

    def done(self, t: float) -> bool:
        return t >= self.started + self.duration

    def value(self, t: float) -> np.ndarray:
        """The variables at ``t``: current→min over ``[0, uA]``, min→max over ``[uA, uB]``,
        max→current over ``[uB, 1]`` of the normalised time; the initial values after."""
        u = max((t - self.started) / self.duration, 0.0)
        if u >= 1.0:
            return self.initial.copy()
        ua, ub = self._ua, self._ub
        down = np.where(ua > 0, u / np.where(ua > 0, ua, 1.0), 1.0)
        up = np.where(ub > ua, (u - ua) / np.where(ub > ua, ub - ua, 1.0), 1.0)
        back = np.where(ub < 1, (u - ub) / np.where(ub < 1, 1.0 - ub, 1.0), 1.0)
        return np.where(u <= ua, self.initial + down * (self.minima - self.initial),
                        np.where(u <= ub, self.minima + up * (self.maxima - self.minima),
                                 self.maxima + back * (self.initial - self.maxima)))
