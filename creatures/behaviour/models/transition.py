"""Forward transition models: *what usually happens next* (thesis: "phase three – models",
"forward transition models").

For N action-tuples the probability of going from i to j is estimated from the transitions
recorded *recently* out of i (the last ``window`` of them), mixed with a uniform prior:

    p(i → j) ≈ (N'_ij / Σ_j N'_ij + α) / (1 + αN)

Each row sums to 1; a tuple never left yet gives the uniform 1/N (its empty fractions are
read as uniform, which the formula alone would not sum to 1); and because old
transitions fall out of the window, a change in what follows i is followed within
``window`` transitions. ``bias(i)`` is the row a Du hands to action selection to lower the
bar for likely transitions.

Alongside the destinations, the value credited on each transition is kept in the same
window, so ``value_contrast(i)`` can tell whether transitions out of i carry different
values — the grounds for this percept to fission into sub-hypotheses.
"""

from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np

_EMPTY = -1

SAME = 1e-9
"""Values within this fraction of their size of each other are one value: a constant credit
(1/3, ten times) has a mean a rounding away from each of its values, and those last bits
alone, split by destination, read as a contrast of 1."""


def _with_prior(counts: np.ndarray, alpha: float) -> np.ndarray:
    """(N'_ij / Σ_j N'_ij + α) / (1 + αN) along the last axis of a count row or matrix.

    A row with no transitions yet has no fractions to speak of; it takes the uniform 1/N,
    so that row too sums to 1 and p(i → j) = 1/N.
    """
    n = counts.shape[-1]
    total = counts.sum(axis=-1, keepdims=True)
    frac = np.divide(counts, total, out=np.full(counts.shape, 1.0 / max(n, 1)), where=total > 0)
    return (frac + alpha) / (1.0 + alpha * n)


class TransitionModel:
    """Recency-windowed transition counts with a prior, plus per-transition values."""

    def __init__(self, names: Sequence[str] = (), *, window: int = 10, alpha: float = 0.1) -> None:
        if window < 1:
            raise ValueError(f"window must hold at least one transition (got {window})")
        if not alpha > 0:
            raise ValueError(f"the prior weight alpha must be positive (got {alpha!r})")
        self.window = int(window)
        self.alpha = float(alpha)
        self.names: list[str] = []
        self._index: dict[str, int] = {}
        self.counts = np.zeros((0, 0), dtype=np.int64)  # N'_ij over each row's window
        self._next = np.zeros((0, self.window), dtype=np.int64)  # destinations, ring per row
        self._values = np.zeros((0, self.window))  # credited value per ring slot (NaN: none)
        self._head = np.zeros(0, dtype=np.int64)
        for name in names:
            self.add(name)

    def add(self, name: str) -> int:
        """Start modelling a tuple; the prior spreads over one more destination."""
        if name in self._index:
            return self._index[name]
        self.names.append(name)
        self._index[name] = len(self.names) - 1
        self.counts = np.pad(self.counts, ((0, 1), (0, 1)))
        self._next = np.vstack([self._next, np.full((1, self.window), _EMPTY)])
        self._values = np.vstack([self._values, np.full((1, self.window), np.nan)])
        self._head = np.append(self._head, 0)
        return self._index[name]

    def index(self, name: str) -> int:
        try:
            return self._index[name]
        except KeyError:
            raise KeyError(f"transition model has no tuple named {name!r}") from None

    def record(self, i: str, j: str, value: float | None = None) -> None:
        """A transition from ``i`` to ``j``, optionally with the value it was credited."""
        if value is not None and not math.isfinite(value):
            raise ValueError(f"transition value must be finite (got {value!r})")
        a, b = self.index(i), self.index(j)
        slot = self._head[a]
        evicted = self._next[a, slot]
        if evicted != _EMPTY:
            self.counts[a, evicted] -= 1
        self._next[a, slot] = b
        self._values[a, slot] = np.nan if value is None else float(value)
        self.counts[a, b] += 1
        self._head[a] = (slot + 1) % self.window

    def probabilities(self) -> np.ndarray:
        """The whole matrix p(i → j); each row sums to 1."""
        return _with_prior(self.counts, self.alpha)

    def bias(self, i: str) -> np.ndarray:
        """p(i → ·) over all tuples, in ``names`` order, for biasing selection after i."""
        return _with_prior(self.counts[self.index(i)], self.alpha)

    def probability(self, i: str, j: str) -> float:
        return float(self.bias(i)[self.index(j)])

    def _valued(self, i: str) -> tuple[np.ndarray, np.ndarray]:
        a = self.index(i)
        keep = (self._next[a] != _EMPTY) & ~np.isnan(self._values[a])
        return self._next[a][keep], self._values[a][keep]

    def value_stats(self, i: str, j: str) -> tuple[int, float, float]:
        """(count, mean, std) of the values credited on recent i → j transitions."""
        dest, vals = self._valued(i)
        v = vals[dest == self.index(j)]
        if len(v) == 0:
            return 0, math.nan, math.nan
        return len(v), float(v.mean()), float(v.std())

    def value_contrast(self, i: str) -> float:
        """How much of the spread of values after ``i`` is explained by *where* it went.

        The correlation ratio η² = between-destination / total sum of squares over the
        recent valued transitions, in [0, 1]: near 1 when each destination carries its own
        value (fission would pay), 0 when the destination makes no difference or there is
        no spread at all (none beyond :data:`SAME`).
        """
        dest, vals = self._valued(i)
        if len(vals) < 2 or np.ptp(vals) <= SAME * np.abs(vals).max():
            return 0.0
        total = float(((vals - vals.mean()) ** 2).sum())
        n = len(self.names)
        count = np.bincount(dest, minlength=n)
        means = np.bincount(dest, weights=vals, minlength=n) / np.maximum(count, 1)
        between = float((count * (means - vals.mean()) ** 2).sum())
        return between / total

    def to_dict(self) -> dict[str, Any]:
        """JSON-able state: each row's window oldest first; missing values as null."""
        rows = []
        for a in range(len(self.names)):
            row = []
            for k in np.roll(np.arange(self.window), -self._head[a]):
                if self._next[a, k] != _EMPTY:
                    v = self._values[a, k]
                    row.append([self.names[self._next[a, k]], None if np.isnan(v) else float(v)])
            rows.append(row)
        return {
            "kind": "transition_model",
            "window": self.window,
            "alpha": self.alpha,
            "names": list(self.names),
            "recent": rows,
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> "TransitionModel":
        try:
            model = cls(data["names"], window=data["window"], alpha=data["alpha"])
            recent = data["recent"]
        except KeyError as exc:
            raise ValueError(f"transition model state is missing key {exc.args[0]!r}") from None
        if len(recent) != len(model.names):
            raise ValueError("transition model state: 'recent' needs one row per name")
        for name, row in zip(model.names, recent):
            for k, (destination, value) in enumerate(row):
                if destination not in model._index:
                    raise ValueError(
                        f"transition model state: recent[{name!r}][{k}] names unknown tuple"
                        f" {destination!r}"
                    )
                model.record(name, destination, value)
        return model
