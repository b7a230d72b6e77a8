"""State objects: data flows with history and saliency (thesis: "state objects and decaying
memory traces").

A StateObject wraps one flow of data a percept needs (a level, a pitch, a cepstral frame) and
keeps a bounded history of ``(time, data, saliency)`` so credit assignment can look back at
what *led up to* an action. Saliency is a low-level measure of how stimulating the flow is;
this is where habituation, sensitisation and inhibition (not hearing while singing) live; a
drive reaches perception through percepts of its own (a ``drive`` percept, ramped or combined).
Because the history is kept,
saliency can also be filtered *acausally*: a salient event masks less salient ones both
before and after it (thesis: "percept updating – model building").

Times and saliencies live in preallocated numpy arrays twice the history length; the live
window slides along and is copied back to the front only when it reaches the end, so a push
is amortised O(1) and every query sees one contiguous, chronological slice.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np


@dataclass
class Habituation:
    """Dual-process habituation and sensitisation of a flow's saliency gain.

    Two leaky integrators driven by the stimulus (the saliency that got through inhibition),
    held constant between pushes so the result depends on elapsed time, not on how often the
    flow is sampled:

    - habituation ``h`` ∈ [0, 1): dh/dt = rate·|s|·(1 − h) − h/recovery. Repeated
      stimulation drives it up; rest lets it decay back with time constant ``recovery`` seconds.
    - sensitisation ``z`` ≥ 0: dz/dt = sensitise·max(0, |s| − threshold) − z/calm. Only
      strong stimuli (the startling click) raise it; with the defaults it fades faster.

    The gain applied to a new sample is (1 − h)·(1 + z). Both ODEs are linear over a hold
    interval and are integrated exactly.
    """

    rate: float = 1.0
    recovery: float = 10.0
    sensitise: float = 0.0
    threshold: float = 1.0
    calm: float = 2.0
    h: float = 0.0
    z: float = 0.0

    def __post_init__(self) -> None:
        for name in ("rate", "sensitise"):
            if getattr(self, name) < 0:
                raise ValueError(f"habituation {name} must be non-negative")
        for name in ("recovery", "calm"):
            if not getattr(self, name) > 0:
                raise ValueError(f"habituation {name} must be a positive time in seconds")

    @property
    def gain(self) -> float:
        return (1.0 - self.h) * (1.0 + self.z)

    def advance(self, dt: float, stimulus: float) -> None:
        """Integrate both traces over ``dt`` seconds of constant ``stimulus``."""
        if dt <= 0:
            return
        s = abs(stimulus)
        k = self.rate * s + 1.0 / self.recovery  # total relaxation rate of h
        h_eq = self.rate * s / k
        self.h = h_eq + (self.h - h_eq) * math.exp(-k * dt)
        z_eq = self.sensitise * max(0.0, s - self.threshold) * self.calm
        self.z = z_eq + (self.z - z_eq) * math.exp(-dt / self.calm)


def magnitude(datum: Any) -> float:
    """A flow's default raw saliency: the size of its datum, whatever its sign."""
    return abs(float(datum))


class StateObject:
    """A bounded history of samples of one data flow, with a computed saliency.

    ``saliency_fn`` maps a pushed datum to raw saliency (default: ``abs(float(datum))``).
    The stored saliency is raw × inhibition × habituation gain:

    - inhibitors scale it by (1 − strength·s_other) while they are salient themselves, e.g.
      the creature's own "singing" flow inhibits its "hearing" flow;
    - ``habituation`` (optional) lowers the gain under repeated stimulation.
    """

    def __init__(
        self,
        name: str,
        *,
        history: int = 1024,
        saliency_fn: Callable[[Any], float] | None = None,
        habituation: Habituation | None = None,
    ) -> None:
        if history < 1:
            raise ValueError(f"history must hold at least one sample (got {history})")
        self.name = name
        self.history = int(history)
        self.saliency_fn = saliency_fn or magnitude
        self.habituation = habituation
        self.inhibitors: list[tuple[StateObject, float]] = []
        self._capacity = 2 * self.history
        self._times = np.empty(self._capacity)
        self._saliencies = np.empty(self._capacity)
        self._data: list[Any] = [None] * self._capacity
        self._start = 0
        self._end = 0
        self._last = -math.inf  # the newest sample's time (valid while the history holds one)
        self._stimulus = 0.0  # last stimulus, held until the next push (for habituation)

    # -- the history, oldest first ------------------------------------------------------------
    # ``times``/``saliencies``/``data`` are plain lists, as the deques they replaced were (so
    # ``if state.times:`` still works); the ``*_array`` views are for vectorised readers.
    def __len__(self) -> int:
        return self._end - self._start

    @property
    def times_array(self) -> np.ndarray:
        """Read-only view of the sample times."""
        view = self._times[self._start : self._end]
        view.flags.writeable = False
        return view

    @property
    def saliencies_array(self) -> np.ndarray:
        """Read-only view of the stored saliencies."""
        view = self._saliencies[self._start : self._end]
        view.flags.writeable = False
        return view

    @property
    def times(self) -> list[float]:
        return self.times_array.tolist()

    @property
    def saliencies(self) -> list[float]:
        return self.saliencies_array.tolist()

    @property
    def data(self) -> list[Any]:
        return self._data[self._start : self._end]

    # -- input --------------------------------------------------------------------------------
    def inhibit_by(self, other: "StateObject", strength: float = 1.0) -> None:
        """While ``other`` is salient, this flow's saliency is scaled by (1 − strength·s)."""
        self.inhibitors.append((other, float(strength)))

    def push(self, t: float, datum: Any) -> float:
        """Record a datum at time ``t``; returns the saliency stored with it.

        Hot path (every heard note pushes five flows at every ear): a flow with no
        inhibitors or habituation skips their factors, each of which would be
        exactly 1.0 (x·1.0 is x, bit for bit), and the newest time is kept as a float."""
        t = float(t)
        if self._end > self._start and t < self._last:
            raise ValueError(f"{self.name}: time went backwards ({t} < {self._last})")
        fn = self.saliency_fn
        stimulus = abs(float(datum)) if fn is magnitude else float(fn(datum))  # the default, without a call
        if self.inhibitors:
            stimulus *= self._inhibition(t)
        saliency = stimulus
        if self.habituation is not None:
            if self._end > self._start:
                self.habituation.advance(t - self._last, self._stimulus)
            saliency = stimulus * self.habituation.gain
        self._stimulus = stimulus
        self._append(t, datum, saliency)
        return saliency

    def _inhibition(self, t: float) -> float:
        gain = 1.0
        for other, strength in self.inhibitors:
            gain *= max(0.0, 1.0 - strength * max(0.0, other.saliency_at(t)))
        return gain

    def _append(self, t: float, datum: Any, saliency: float) -> None:
        end = self._end
        if end == self._capacity:  # slide the live window back to the front
            start = self._start
            n = end - start
            self._times[:n] = self._times[start:end]
            self._saliencies[:n] = self._saliencies[start:end]
            self._data[:n] = self._data[start:end]
            self._data[n:] = [None] * (self._capacity - n)
            self._start, end = 0, n
        self._times[end] = t
        self._saliencies[end] = saliency
        self._data[end] = datum
        self._last = t
        self._end = end = end + 1
        if end - self._start > self.history:
            self._data[self._start] = None
            self._start += 1

    # -- recall -------------------------------------------------------------------------------
    def _index_at(self, t: float) -> int | None:
        i = int(np.searchsorted(self.times_array, t, side="right")) - 1
        return None if i < 0 else self._start + i

    def saliency_at(self, t: float) -> float:
        """Saliency of the newest sample at or before ``t`` (0 before any sample)."""
        i = self._index_at(t)
        return 0.0 if i is None else float(self._saliencies[i])

    def datum_at(self, t: float) -> Any:
        """The datum the flow held at ``t`` (newest at or before ``t``; None before any)."""
        i = self._index_at(t)
        return None if i is None else self._data[i]

    def latest(self) -> Any:
        return self._data[self._end - 1] if len(self) else None

    def _span(self, start: float, end: float) -> slice:
        times = self.times_array
        lo = int(np.searchsorted(times, start, side="left"))
        hi = int(np.searchsorted(times, end, side="right"))
        return slice(self._start + lo, self._start + max(lo, hi))

    def window(self, start: float, end: float) -> list[tuple[float, Any, float]]:
        """Samples with ``start <= time <= end`` as ``(time, datum, saliency)``."""
        s = self._span(start, end)
        return list(
            zip(self._times[s].tolist(), self._data[s], self._saliencies[s].tolist())
        )

    def most_salient(self, start: float, end: float) -> tuple[float, Any, float] | None:
        """The most salient sample with ``start <= time <= end`` (earliest on ties)."""
        s = self._span(start, end)
        if s.stop == s.start:
            return None
        i = s.start + int(np.argmax(self._saliencies[s]))
        return float(self._times[i]), self._data[i], float(self._saliencies[i])

    def masked_saliencies(self, start: float, end: float, *, reach: float) -> np.ndarray:
        """Acausally masked saliencies of the samples in ``[start, end]``.

        Every sample within ``reach`` seconds — before *or* after — masks a sample whose
        saliency is lower than its own scaled by a triangular kernel 1 − |Δt|/reach; masked
        samples get 0, survivors keep their saliency. Neighbours just outside the window
        still mask (masking does not stop at the query's edges).
        """
        if not reach > 0:
            raise ValueError(f"masking reach must be a positive time (got {reach!r})")
        inner = self._span(start, end)
        outer = self._span(start - reach, end + reach)
        t_all, s_all = self._times[outer], self._saliencies[outer]
        own = np.arange(inner.start - outer.start, inner.stop - outer.start)
        t_in, s_in = t_all[own], s_all[own]
        # Only neighbours within reach can mask; walk outward one offset at a time, all
        # samples at once: O(n·k) for k neighbours in reach instead of O(n²).
        first = np.searchsorted(t_all, t_in - reach, side="left")
        last = np.searchsorted(t_all, t_in + reach, side="right") - 1
        widest = int(max((own - first).max(initial=0), (last - own).max(initial=0)))
        masker = np.zeros(len(own))
        for k in range(1, widest + 1):
            for j in (own - k, own + k):
                inside = (j >= 0) & (j < len(t_all))
                jj = np.where(inside, j, 0)
                kernel = np.clip(1.0 - np.abs(t_in - t_all[jj]) / reach, 0.0, None)
                np.maximum(masker, np.where(inside, kernel * s_all[jj], 0.0), out=masker)
        return np.where(s_in >= masker, s_in, 0.0)

    def unmasked(
        self, start: float, end: float, *, reach: float
    ) -> list[tuple[float, Any, float]]:
        """The samples in ``[start, end]`` that survive acausal masking (for model updates)."""
        s = self._span(start, end)
        keep = self.masked_saliencies(start, end, reach=reach) > 0
        return [
            (float(self._times[i]), self._data[i], float(self._saliencies[i]))
            for i in np.flatnonzero(keep) + s.start
        ]

    def __repr__(self) -> str:
        return f"StateObject({self.name!r}, {len(self)} samples)"
