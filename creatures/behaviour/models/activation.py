"""Activation (clique) models of which action-tuples are active together (thesis: "phase three
– models", "activation models", figure 9).

Every ordered pair of tuples (i, j) keeps a distance D_ij, initialised to a large M. While
i and j are in the same state (both active or both inactive) D_ij decays toward 0; while one
is active and the other is not, it relaxes toward M — a Hebbian rule. The per-second filter
constant α is replaced by

    β_i = α^(time i inactive / time i active)   while i is active,
    γ_i = α^(time i active / time i inactive)   while i is inactive,

so a tuple that is rarely active learns quickly from the little time it is active and
slowly from the long time it is not ("nothing profound" in being idle). Updates happen only
at (in)activation events: over the Δt seconds since the last event the state was constant,
so the filter is applied once with its constant raised to the power Δt; the distances
therefore describe the history up to the latest event. Following the
thesis's footnote, a pair is only tracked once the two tuples have first been active
together; until then it stays at M. The matrix work is vectorised over all tuples.
"""

from __future__ import annotations

from typing import Any, Iterable, Sequence

import numpy as np
from scipy.sparse.csgraph import connected_components


class ActivationModel:
    """Distances D_ij between action-tuples from their overlapping activations.

    ``alpha`` is the per-second filter constant in (0, 1): the fraction of D_ij that
    survives one second of (uncompensated) evidence. ``max_ratio`` bounds the
    active/inactive time ratios used as exponents, so a tuple seen active for a moment
    does not wipe its whole row at once.
    """

    def __init__(
        self,
        names: Sequence[str] = (),
        *,
        alpha: float = 0.9,
        max_distance: float = 10.0,
        max_ratio: float = 100.0,
        start: float = 0.0,
    ) -> None:
        if not 0.0 < alpha < 1.0:
            raise ValueError(f"alpha must be in (0, 1) (got {alpha!r})")
        if not max_distance > 0 or not max_ratio >= 1:
            raise ValueError("max_distance must be positive and max_ratio at least 1")
        self.alpha = float(alpha)
        self.max_distance = float(max_distance)
        self.max_ratio = float(max_ratio)
        self.names: list[str] = []
        self._index: dict[str, int] = {}
        self.distances = np.zeros((0, 0))
        self.met = np.zeros((0, 0), dtype=bool)
        self.active = np.zeros(0, dtype=bool)
        self.time_active = np.zeros(0)
        self.time_inactive = np.zeros(0)
        self.last_event = float(start)
        for name in names:
            self.add(name)

    def add(self, name: str) -> int:
        """Start modelling a tuple (inactive, at distance M from every other); its index."""
        if name in self._index:
            return self._index[name]
        n = len(self.names)
        self.names.append(name)
        self._index[name] = n
        self.distances = np.pad(
            self.distances, ((0, 1), (0, 1)), constant_values=self.max_distance
        )
        self.distances[n, n] = 0.0
        self.met = np.pad(self.met, ((0, 1), (0, 1)), constant_values=False)
        self.active = np.append(self.active, False)
        self.time_active = np.append(self.time_active, 0.0)
        self.time_inactive = np.append(self.time_inactive, 0.0)
        return n

    def index(self, name: str) -> int:
        try:
            return self._index[name]
        except KeyError:
            raise KeyError(f"activation model has no tuple named {name!r}") from None

    def _integrate(self, t: float) -> None:
        """Apply the constant activation pattern held since the last event, up to ``t``.

        Called only when the pattern changes, so the result does not depend on how often
        the caller ticks (the compensation exponents are read once per held interval).
        """
        dt = float(t) - self.last_event
        if dt == 0 or not self.names:
            self.last_event = float(t)
            return
        a = self.active
        eps = 1e-9
        ratio = np.clip(
            (self.time_inactive + eps) / (self.time_active + eps),
            1.0 / self.max_ratio,
            self.max_ratio,
        )
        exponent = np.where(a, ratio, 1.0 / ratio)  # β_i while active, γ_i while inactive
        keep = (self.alpha ** (exponent * dt))[:, None]
        target = self.max_distance * (a[:, None] != a[None, :])
        relaxed = keep * self.distances + (1.0 - keep) * target
        self.distances = np.where(self.met, relaxed, self.distances)
        np.fill_diagonal(self.distances, 0.0)
        self.time_active += np.where(a, dt, 0.0)
        self.time_inactive += np.where(a, 0.0, dt)
        self.last_event = float(t)

    def set_active(self, t: float, name: str, active: bool) -> None:
        """An (in)activation event for one tuple at time ``t`` (no-op if nothing changes)."""
        pattern = self.active.copy()
        pattern[self.index(name)] = bool(active)
        self._change(t, pattern)

    def activate(self, t: float, name: str) -> None:
        self.set_active(t, name, True)

    def deactivate(self, t: float, name: str) -> None:
        self.set_active(t, name, False)

    def observe(self, t: float, active: Iterable[str]) -> None:
        """Set the whole activation pattern at ``t``: exactly ``active`` are active.

        Safe to call every tick: an unchanged pattern is not an event.
        """
        pattern = np.zeros_like(self.active)
        pattern[[self.index(n) for n in active]] = True
        self._change(t, pattern)

    def _change(self, t: float, pattern: np.ndarray) -> None:
        if float(t) < self.last_event:
            raise ValueError(f"activation model: time went backwards ({t} < {self.last_event})")
        if np.array_equal(pattern, self.active):
            return
        self._integrate(t)
        self.active = pattern
        self.met |= np.outer(pattern, pattern)

    def distance(self, i: str, j: str) -> float:
        return float(self.distances[self.index(i), self.index(j)])

    def cliques(self, threshold: float) -> list[list[str]]:
        """Groups of tuples linked by symmetric distance (D_ij + D_ji)/2 < ``threshold``.

        Connected components of that graph, largest first; a tuple correlated with nobody
        is a clique of one. Each clique of two or more is a candidate for a new percept.
        """
        sym = 0.5 * (self.distances + self.distances.T)
        linked = (sym < threshold) & self.met
        _, labels = connected_components(linked, directed=False)
        groups: dict[int, list[str]] = {}
        for name, label in zip(self.names, labels):
            groups.setdefault(int(label), []).append(name)
        return sorted(groups.values(), key=lambda g: (-len(g), self._index[g[0]]))

    def to_dict(self) -> dict[str, Any]:
        return {
            "kind": "activation_model",
            "alpha": self.alpha,
            "max_distance": self.max_distance,
            "max_ratio": self.max_ratio,
            "names": list(self.names),
            "distances": self.distances.tolist(),
            "met": self.met.tolist(),
            "active": self.active.tolist(),
            "time_active": self.time_active.tolist(),
            "time_inactive": self.time_inactive.tolist(),
            "last_event": self.last_event,
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> "ActivationModel":
        try:
            model = cls(
                data["names"],
                alpha=data["alpha"],
                max_distance=data["max_distance"],
                max_ratio=data["max_ratio"],
                start=data["last_event"],
            )
            n = len(model.names)
            arrays = {
                "distances": (np.asarray(data["distances"], dtype=float), (n, n)),
                "met": (np.asarray(data["met"], dtype=bool), (n, n)),
                "active": (np.asarray(data["active"], dtype=bool), (n,)),
                "time_active": (np.asarray(data["time_active"], dtype=float), (n,)),
                "time_inactive": (np.asarray(data["time_inactive"], dtype=float), (n,)),
            }
        except KeyError as exc:
            raise ValueError(f"activation model state is missing key {exc.args[0]!r}") from None
        for key, (array, shape) in arrays.items():
            if array.shape != shape:
                raise ValueError(
                    f"activation model state: {key!r} has shape {array.shape}, expected {shape}"
                )
            setattr(model, key, array)
        return model
