"""State objects: data flows with history and saliency (thesis: "state objects and decaying
memory traces").

A StateObject wraps one flow of data a percept needs (a level, a pitch, a cepstral frame) and
keeps a bounded history of ``(time, data, saliency)`` so credit assignment can look back at
what *led up to* an action. Saliency is a low-level measure of how stimulating the flow is;
this is where habituation, sensitisation and inhibition (not hearing while singing) live.
"""

from __future__ import annotations

from collections import deque
from typing import Any, Callable

import numpy as np


class StateObject:
    """A bounded history of samples of one data flow, with a computed saliency.

    ``saliency_fn`` maps a pushed datum to raw saliency (default: ``abs(float(datum))``).
    Inhibitors scale the saliency down while they are salient themselves, e.g. the
    creature's own "singing" flow inhibits its "hearing" flow.
    """

    def __init__(
        self,
        name: str,
        *,
        history: int = 1024,
        saliency_fn: Callable[[Any], float] | None = None,
    ) -> None:
        if history < 1:
            raise ValueError(f"history must hold at least one sample (got {history})")
        self.name = name
        self.saliency_fn = saliency_fn or (lambda datum: abs(float(datum)))
        self.times: deque[float] = deque(maxlen=history)
        self.data: deque[Any] = deque(maxlen=history)
        self.saliencies: deque[float] = deque(maxlen=history)
        self.inhibitors: list[tuple[StateObject, float]] = []

    def inhibit_by(self, other: "StateObject", strength: float = 1.0) -> None:
        """While ``other`` is salient, this flow's saliency is scaled by (1 − strength·s)."""
        self.inhibitors.append((other, float(strength)))

    def push(self, t: float, datum: Any) -> float:
        """Record a datum at time ``t``; returns the saliency stored with it."""
        if self.times and t < self.times[-1]:
            raise ValueError(f"{self.name}: time went backwards ({t} < {self.times[-1]})")
        saliency = self._modulate(t, float(self.saliency_fn(datum)))
        self.times.append(float(t))
        self.data.append(datum)
        self.saliencies.append(saliency)
        return saliency

    def _modulate(self, t: float, raw: float) -> float:
        gain = 1.0
        for other, strength in self.inhibitors:
            gain *= max(0.0, 1.0 - strength * max(0.0, other.saliency_at(t)))
        return raw * gain

    def saliency_at(self, t: float) -> float:
        """Saliency of the newest sample at or before ``t`` (0 before any sample)."""
        if not self.times or t < self.times[0]:
            return 0.0
        i = int(np.searchsorted(np.fromiter(self.times, float), t, side="right")) - 1
        return self.saliencies[i]

    def latest(self) -> Any:
        return self.data[-1] if self.data else None

    def window(self, start: float, end: float) -> list[tuple[float, Any, float]]:
        """Samples with ``start <= time <= end`` as ``(time, datum, saliency)``."""
        return [
            (t, d, s)
            for t, d, s in zip(self.times, self.data, self.saliencies)
            if start <= t <= end
        ]
