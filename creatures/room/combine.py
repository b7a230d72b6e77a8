"""Combining steering forces into one (Reynolds 1999, "Combining behaviors"; OpenSteer's
three policies, STYLE.md: contributions in, one policy out).

Each policy takes the behaviours' forces in priority order (a list of (M, 2) arrays), their
weights and the creatures' maximum force, and returns one (M, 2) force:

- :func:`weighted_truncated_sum`: every behaviour counts, in proportion to its weight; the
  sum is cut to ``max_force``. Simple, but a strong push can be averaged away by others.
- :func:`prioritised_budget`: behaviours in priority order each take what they ask for of
  ``max_force`` until it is spent; the avoidance that comes first is never diluted.
- :func:`prioritised_dithering`: for each creature only one behaviour steers this sub-step:
  in priority order, each that has something to say is chosen with its probability.
  Cheap and stochastic; the creature's motion averages the behaviours over sub-steps.
"""

from __future__ import annotations

from typing import Callable, Sequence

import numpy as np

from creatures.room.vehicle import EPS, norms, truncate


def weighted_truncated_sum(forces: Sequence[np.ndarray], weights: Sequence[float],
                           max_force: np.ndarray) -> np.ndarray:
    """Σ wᵢ fᵢ, truncated to ``max_force``."""
    total = sum(w * f for w, f in zip(weights, forces))
    return truncate(np.asarray(total, dtype=float), max_force)


def prioritised_budget(forces: Sequence[np.ndarray], weights: Sequence[float],
                       max_force: np.ndarray) -> np.ndarray:
    """Accumulate wᵢ fᵢ in priority order, each cut to what is left of ``max_force``."""
    total = np.zeros_like(forces[0])
    left = np.asarray(max_force, dtype=float).copy()
    for w, f in zip(weights, forces):
        f = w * f
        n = norms(f)
        take = np.minimum(n, left)
        total += f * (take / np.maximum(n, EPS))[:, None]
        left = left - take
    return total


def prioritised_dithering(forces: Sequence[np.ndarray], weights: Sequence[float], max_force: np.ndarray,
                          probabilities: Sequence[float], uniform: np.ndarray) -> np.ndarray:
    """Per creature, the first behaviour (in priority order) that is non-zero and passes its
    probability (``uniform`` is (len(forces), M) of U[0, 1) draws), weighted and truncated."""
    chosen = np.zeros_like(forces[0])
    open_ = np.ones(len(chosen), dtype=bool)
    for i, (w, f, p) in enumerate(zip(weights, forces, probabilities)):
        take = open_ & (norms(f) > EPS) & (uniform[i] < p)
        chosen[take] = w * f[take]
        open_ &= ~take
    return truncate(chosen, max_force)


Policy = Callable[..., np.ndarray]
POLICIES: dict[str, Policy] = {
    "weighted": weighted_truncated_sum,
    "budget": prioritised_budget,
    "dithering": prioritised_dithering,
}
"""The policies by the name a ``[creature.steer]`` table gives (``combine = "budget"``)."""
