"""The rolling-buffer Gaussian model with a prior (thesis: "phase three – models", "simple
generic one-dimensional models", figure 8; "temporal models – simple durations").

A non-stationary one-dimensional distribution is tracked by second-order statistics over a
FIFO buffer. The buffer starts full of samples of the prior, so a fresh model already says
something sensible, and new data pushes the prior's samples out one at a time: the buffer
length is the plasticity (rate of forgetting). The statistics the creature uses are blended
with the prior by ``prior_weight``, which is what the thesis means by "the prior ensures
stability": however narrow or wild the recent data, the model never collapses to zero width
nor wanders off without a pull back toward the authored expectation.

The same object is the "simple duration model" of a Do-until (it has ``sample``/``update``),
and :class:`GaussianPercept` is a Tr percept that models one :class:`StateObject` flow.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.stats import norm

from creatures import bounds
from creatures.behaviour.percept import Percept
from creatures.behaviour.state_object import StateObject


MAX_SIZE = 65_536
"""Most samples a saved model may hold (a damaged size is refused, not allocated)."""


def _finite(x: float, what: str) -> float:
    x = float(x)
    if not math.isfinite(x):
        raise ValueError(f"{what} must be a finite number (got {x!r})")
    return x


class GaussianModel:
    """Rolling FIFO buffer of samples, initially filled by sampling the prior (thesis fig. 8).

    With an ``rng`` the buffer is filled with random draws from N(prior_mean, prior_std²);
    without one it is filled with the prior's evenly spaced quantiles, so models made
    without a generator are deterministic and start with the prior's exact shape.

    ``mean`` and ``std`` pool the buffer's moments with the prior's:
    mean = (1 − w)·m_buffer + w·μ₀ and std² = (1 − w)·s²_buffer + w·σ₀²,
    w = prior_weight, so std ≥ √w·σ₀ > 0 always.

    Each sample carries a weight (1 unless ``update`` is given one) and the buffer moments
    are weighted, so a partial credit assignment (blend parameter α < 1) can count as a
    partial observation instead of a whole one.
    """

    def __init__(
        self,
        prior_mean: float,
        prior_std: float,
        *,
        size: int = 32,
        prior_weight: float = 0.1,
        rng: np.random.Generator | None = None,
    ) -> None:
        self.prior_mean = _finite(prior_mean, "prior_mean")
        self.prior_std = _finite(prior_std, "prior_std")
        if not self.prior_std > 0:
            raise ValueError(f"prior_std must be positive (got {prior_std!r})")
        if size < 2:
            raise ValueError(f"a rolling buffer needs at least 2 samples (got size={size})")
        if not 0.0 < prior_weight <= 1.0:
            raise ValueError(f"prior_weight must be in (0, 1] (got {prior_weight!r})")
        self.prior_weight = float(prior_weight)
        if rng is None:
            quantiles = (np.arange(size) + 0.5) / size
            self.buffer = norm.ppf(quantiles, loc=self.prior_mean, scale=self.prior_std)
        else:
            self.buffer = rng.normal(self.prior_mean, self.prior_std, size)
        self.weights = np.ones(size)
        self._head = 0  # index of the oldest sample: the next to be overwritten
        self._refresh()

    @property
    def size(self) -> int:
        return len(self.buffer)

    @property
    def mean(self) -> float:
        return self._mean

    @property
    def std(self) -> float:
        return self._std

    def _refresh(self) -> None:
        w = self.prior_weight
        total = float(self.weights.sum())
        if total > 0:
            m = float(self.weights @ self.buffer) / total
            v = float(self.weights @ (self.buffer - m) ** 2) / total
        else:  # every sample has zero weight: only the prior speaks
            m, v = self.prior_mean, self.prior_std**2
        self._mean = (1.0 - w) * m + w * self.prior_mean
        self._std = math.sqrt((1.0 - w) * v + w * self.prior_std**2)

    def update(self, x: float, weight: float = 1.0) -> None:
        """Push one observation (with a weight in [0, 1]), dropping the oldest (FIFO)."""
        x = _finite(x, "a model observation")
        if not 0.0 <= weight <= 1.0:
            raise ValueError(f"an observation weight must be in [0, 1] (got {weight!r})")
        self.buffer[self._head] = x
        self.weights[self._head] = weight
        self._head = (self._head + 1) % len(self.buffer)
        self._refresh()

    def observations(self) -> list[tuple[float, float]]:
        """The samples with their weights, oldest first: what :meth:`update` took, in order (a
        model of another size takes them back by updating with each)."""
        order = np.roll(np.arange(self.size), -self._head)
        return list(zip(self.buffer[order].tolist(), self.weights[order].tolist()))

    def sample(self, rng: np.random.Generator) -> float:
        """Draw from the current model modulated by the prior (the prior-pooled Gaussian)."""
        return float(rng.normal(self._mean, self._std))

    def likelihood(self, x: float | np.ndarray) -> float | np.ndarray:
        """Unnormalised likelihood exp(−(x − m)²/2s²) in [0, 1]; 1 at the mean.

        Unnormalised on purpose: a percept's saliency should not depend on how wide the
        model happens to be at its peak. Works elementwise on arrays.
        """
        x_arr = np.asarray(x, dtype=float)
        if np.isnan(x_arr).any():
            raise ValueError("cannot evaluate the likelihood of NaN")
        z = (x_arr - self._mean) / self._std
        out = np.exp(-0.5 * z * z)
        return float(out) if out.ndim == 0 else out

    def to_dict(self) -> dict[str, Any]:
        """JSON-able state; the ring buffer is stored as laid out, with the index of its
        oldest sample, so the FIFO order and every later statistic survive bit for bit."""
        return {
            "kind": "gaussian_model",
            "prior_mean": self.prior_mean,
            "prior_std": self.prior_std,
            "prior_weight": self.prior_weight,
            "buffer": self.buffer.tolist(),
            "weights": self.weights.tolist(),
            "head": self._head,
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> "GaussianModel":
        try:
            buffer = bounds.items(data["buffer"], "gaussian model state: 'buffer'", shortest=1, longest=MAX_SIZE)
            model = cls(
                bounds.number(data["prior_mean"], "gaussian model state: 'prior_mean'",
                              low=-bounds.LARGEST_VALUE, high=bounds.LARGEST_VALUE),
                bounds.number(data["prior_std"], "gaussian model state: 'prior_std'", low=0.0, high=bounds.LARGEST_VALUE),
                size=len(buffer),
                prior_weight=bounds.number(data["prior_weight"], "gaussian model state: 'prior_weight'", low=0.0),
            )
        except KeyError as exc:
            raise ValueError(f"gaussian model state is missing key {exc.args[0]!r}") from None
        model.restore(data)
        return model

    def restore(self, data: dict[str, Any]) -> None:
        """Take back the samples of a saved model of this size; the prior stays this one's
        (a setting: an edited config wins over a saved file). Raises ValueError."""
        buffer = np.asarray(bounds.items(data.get("buffer"), "gaussian model state: 'buffer'",
                                         shortest=self.size, longest=self.size), dtype=float)
        weights = np.asarray(data.get("weights", np.ones(len(buffer))), dtype=float)
        if buffer.ndim != 1 or not (np.isfinite(buffer) & (np.abs(buffer) <= bounds.LARGEST_VALUE)).all():
            raise ValueError("gaussian model state: 'buffer' must be a flat list of finite numbers")
        if weights.shape != buffer.shape or not ((weights >= 0) & (weights <= 1)).all():
            raise ValueError("gaussian model state: 'weights' must match 'buffer', each in [0, 1]")
        head = data.get("head", 0)
        if not (isinstance(head, int) and 0 <= head < len(buffer)):
            raise ValueError(f"gaussian model state: 'head' must index the buffer (got {head!r})")
        self.buffer[:] = buffer
        self.weights[:] = weights
        self._head = head
        self._refresh()

    def __repr__(self) -> str:
        return f"GaussianModel(mean={self._mean:.4g}, std={self._std:.4g}, size={self.size})"


class GaussianPercept(Percept):
    """A Tr percept modelling one StateObject flow with a :class:`GaussianModel`.

    ``evaluate(t)`` is how typical the flow's datum at ``t`` is of the situations that led to
    valuable actions; ``update(t, value)`` is called by credit assignment only for those
    situations (thesis: model the 'higher-value' transitions rather than the joint
    distribution with value), so ``value`` itself is not modelled here.

    With ``lookback > 0`` the update uses the most salient datum in ``[t − lookback, t]``
    rather than the datum at ``t`` (thesis: "updating the model with most salient event inside
    a window around the start of an action"). With ``mask_reach > 0`` as well, it uses every
    datum in that window that survives acausal masking (:meth:`StateObject.masked_saliencies`):
    two separate events before one action both teach the model, while the weaker echoes
    around each event do not.
    """

    def __init__(
        self,
        name: str,
        state: StateObject,
        model: GaussianModel,
        *,
        parent: Percept | None = None,
        lookback: float = 0.0,
        mask_reach: float = 0.0,
    ) -> None:
        super().__init__(name, parent=parent)
        if lookback < 0 or mask_reach < 0:
            raise ValueError(f"lookback and mask_reach must be non-negative (got {lookback!r}, {mask_reach!r})")
        self.state = state
        self.model = model
        self.lookback = float(lookback)
        self.mask_reach = float(mask_reach)

    def evaluate(self, t: float) -> float:
        datum = self.state.datum_at(t)
        if datum is None:
            return 0.0
        return float(self.model.likelihood(float(datum)))

    def update(self, t: float, value: float) -> None:
        if self.lookback > 0 and self.mask_reach > 0:
            for _, datum, _ in self.state.unmasked(t - self.lookback, t, reach=self.mask_reach):
                self.model.update(float(datum))
            return
        if self.lookback > 0:
            event = self.state.most_salient(t - self.lookback, t)
            datum = None if event is None else event[1]
        else:
            datum = self.state.datum_at(t)
        if datum is not None:
            self.model.update(float(datum))

    def to_dict(self) -> dict[str, Any]:
        return {
            **super().to_dict(),
            "state": self.state.name,
            "lookback": self.lookback,
            "mask_reach": self.mask_reach,
            "model": self.model.to_dict(),
        }
