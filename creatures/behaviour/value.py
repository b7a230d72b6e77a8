"""The Value interface and its implementations (thesis: "complex value implementations",
"value chaining", "expectations about value", "emotional tags", "value signal processing").

Value gets its meaning only through action selection. The thesis asks only four operations of
a value: ``toDouble``, ``compareTo``, ``distanceTo`` and ``blendTo``; anything richer (tracer
dye, Gaussian models, emotional tags) is hidden behind them so action-groups never need to
know which implementation a tuple carries. ``VALUE_KINDS`` names every implementation for
``value_from_dict``.
"""

from __future__ import annotations

import enum
import math
from abc import ABC, abstractmethod
from typing import Any, Mapping

from creatures import bounds
from creatures.behaviour.confidence import Confidence
from creatures.behaviour.models.gaussian import GaussianModel
from creatures.clock import Clock


def toward(x: float, target: float, alpha: float) -> float:
    """The one-pole low-pass step (1 − α)x + αtarget, written x + α(target − x) so that a
    value already at its target stays exactly there (the metric axioms hold in floats)."""
    return x + alpha * (target - x)


class Comparison(enum.Enum):
    """Result of :meth:`Value.compare_to` (the thesis allows "unknown": no transitivity)."""

    SAME = "same"
    BIGGER = "bigger"
    SMALLER = "smaller"
    UNKNOWN = "unknown"


class Value(ABC):
    """What an action-tuple is worth: the common currency of action selection."""

    @abstractmethod
    def to_float(self) -> float:
        """The scalar used for selection probabilities."""

    @abstractmethod
    def blend_to(self, other: "Value", alpha: float) -> None:
        """Move this value toward ``other`` by ``alpha`` in [0, 1] (credit assignment)."""

    def compare_to(self, other: "Value") -> Comparison:
        a, b = self.to_float(), other.to_float()
        if a == b:
            return Comparison.SAME
        return Comparison.BIGGER if a > b else Comparison.SMALLER

    def distance_to(self, other: "Value") -> float:
        return abs(self.to_float() - other.to_float())

    @abstractmethod
    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-able state; ``value_from_dict`` rebuilds the same value."""


class ScalarValue(Value):
    """A single number filtered by a one-pole low-pass: V ← (1 − α)V + αV_n.

    ``plasticity`` scales every blend, so a "perception action" such as seeing a lion can
    carry a value far less plastic than ordinary tuples (thesis: the lion problem).
    """

    kind = "scalar"
    SETTINGS: tuple[str, ...] = ("plasticity",)
    """What the author sets and learning never moves: a restart takes these from the config
    (:func:`restored`), the rest from the saved record."""

    def __init__(self, value: float, *, plasticity: float = 1.0) -> None:
        self.value = float(value)
        self.plasticity = float(plasticity)

    def to_float(self) -> float:
        return self.value

    def take_settings(self, authored: "ScalarValue") -> None:
        """This (learnt) value given ``authored``'s :data:`SETTINGS` (a restart, :func:`restored`)."""
        for setting in self.SETTINGS:
            if hasattr(authored, setting):
                setattr(self, setting, getattr(authored, setting))

    def rate(self, alpha: float) -> float:
        """The effective blend parameter: ``alpha`` scaled by plasticity, kept in [0, 1]."""
        return min(max(alpha * self.plasticity, 0.0), 1.0)

    def blend_to(self, other: Value, alpha: float) -> None:
        self.value = toward(self.value, other.to_float(), self.rate(alpha))

    def to_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "value": self.value, "plasticity": self.plasticity}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> "ScalarValue":
        return cls(data["value"], plasticity=data.get("plasticity", 1.0))

    def __repr__(self) -> str:
        return f"ScalarValue({self.value:.4g})"


def _learned(value: Value) -> float:
    """The learned scalar of a value, before any motivational modulation of ``to_float``."""
    return value.value if isinstance(value, ChainValue) else value.to_float()


class ChainValue(ScalarValue):
    """A scalar value carrying "tracer dye" distances to goal sources (thesis: "value chaining
    – the *precedes* relationship").

    ``distances`` maps a source name (a consummatory action such as "eat") to how many
    credit-assignment steps this tuple usually is from it. A source is distance 0 from itself
    (``source=``) and every unknown distance reads as ``max_distance``. Blending moves the
    dye with the scalar, by the same α: D_s ← (1 − α)D_s + α(D_n,s + 1), clamped to
    ``max_distance``.

    Motivational modulation. ``importance`` is a live mapping from source to how much the
    creature wants it now (e.g. {"eat": hunger, "drink": thirst}), shared by every value of
    a creature and read live from its drives (see ``Motivation.importance``). Then

        to_float = value · Σ_s I_s·w_s / Σ_s w_s,   w_s = 2^(−D_s / half_distance),

    over the sources named in either mapping (missing importances count 1, missing
    distances count ``max_distance``). It is a proximity-weighted mean of importances:
    importances of 1 leave the value unchanged, and when the creature is not hungry every tuple
    that earned its value by preceding "eat" loses it at once, the whole chain together.
    ``compare_to`` and ``distance_to`` use the learned scalar, so the metric axioms do not
    depend on the creature's mood. ``importance`` is creature state, not value state: it is
    not saved by ``to_dict`` and must be re-attached after loading.
    """

    kind = "chain"
    SETTINGS = (*ScalarValue.SETTINGS, "source", "max_distance", "half_distance")

    def __init__(
        self,
        value: float,
        *,
        plasticity: float = 1.0,
        distances: Mapping[str, float] | None = None,
        source: str | None = None,
        max_distance: float = 10.0,
        half_distance: float = 1.0,
        importance: Mapping[str, float] | None = None,
    ) -> None:
        super().__init__(value, plasticity=plasticity)
        if not max_distance > 0 or not half_distance > 0:
            raise ValueError("max_distance and half_distance must be positive")
        self.max_distance = float(max_distance)
        self.half_distance = float(half_distance)
        self.source = source
        self.distances: dict[str, float] = {
            k: min(max(float(d), 0.0), self.max_distance) for k, d in (distances or {}).items()
        }
        if source is not None:
            self.distances[source] = 0.0
        self.importance = importance

    def distance_from(self, source: str) -> float:
        return self.distances.get(source, self.max_distance)

    def take_settings(self, authored: ScalarValue) -> None:
        """As a scalar's; a source changed leaves the old one's distance (0 by being the source,
        never learnt) and is 0 itself, and distances past a lowered ``max_distance`` are clamped."""
        was = self.source
        super().take_settings(authored)
        if self.source != was:
            self.distances.pop(was, None)
            if self.source is not None:
                self.distances[self.source] = 0.0
        self.distances = {k: min(d, self.max_distance) for k, d in self.distances.items()}

    def modulation(self) -> float:
        """The motivational factor applied by ``to_float`` (1 without an importance map)."""
        if not self.importance:
            return 1.0
        sources = self.distances.keys() | self.importance.keys()
        num = den = 0.0
        for s in sources:
            w = 2.0 ** (-self.distance_from(s) / self.half_distance)
            num += w * float(self.importance.get(s, 1.0))
            den += w
        return num / den

    def to_float(self) -> float:
        return self.value * self.modulation()

    def compare_to(self, other: Value) -> Comparison:
        a, b = self.value, _learned(other)
        if a == b:
            return Comparison.SAME
        return Comparison.BIGGER if a > b else Comparison.SMALLER

    def distance_to(self, other: Value) -> float:
        return abs(self.value - _learned(other))

    def blend_to(self, other: Value, alpha: float) -> None:
        a = self.rate(alpha)
        self.value = toward(self.value, _learned(other), a)
        theirs = other.distances if isinstance(other, ChainValue) else {}
        for s in self.distances.keys() | theirs.keys():
            if s == self.source:
                continue
            there = theirs.get(s, self.max_distance)
            d = toward(self.distance_from(s), there + 1.0, a)
            self.distances[s] = min(d, self.max_distance)

    def to_dict(self) -> dict[str, Any]:
        return {
            **super().to_dict(),
            "distances": dict(self.distances),
            "source": self.source,
            "max_distance": self.max_distance,
            "half_distance": self.half_distance,
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> "ChainValue":
        return cls(
            data["value"],
            plasticity=data.get("plasticity", 1.0),
            distances=data.get("distances"),
            source=data.get("source"),
            max_distance=data.get("max_distance", 10.0),
            half_distance=data.get("half_distance", 1.0),
        )

    def __repr__(self) -> str:
        dye = ", ".join(f"{k}:{d:.2g}" for k, d in sorted(self.distances.items()))
        return f"ChainValue({self.value:.4g}; {dye})"


class GaussianValue(ScalarValue):
    """A value with expectations: a model of the incoming V_n (thesis: "expectations about
    value").

    ``to_float`` is the low-pass moving mean V_l of the V_n it was blended toward (so the
    metric axioms hold exactly as for :class:`ScalarValue`), and a rolling-buffer
    :class:`GaussianModel` of the same V_n supplies the spread σ. Then

        p(V_n) ∝ exp(−(V_n − V_l)² / 2σ²)

    and a V_n whose likelihood falls below ``threshold`` is surprising. How surprising is
    scaled by ``confidence``, which the thesis asks to fall in two cases:

    - the model has been wrong recently: ``reliability`` is an exponential average of hits
      (1 when a blended V_n was unsurprising, 0 when surprising) with rate ``reliance``;
    - the model has not been tested for a long time: with a clock, confidence decays as
      exp(−(t − t_tested) / ``memory``) seconds since the last blend.

    confidence = reliability · staleness factor, in [0, 1]. The clock is not saved with
    the value: after ``value_from_dict`` the owner re-attaches it (``value.clock = clock``).
    """

    kind = "gaussian"
    SETTINGS = (*ScalarValue.SETTINGS, "threshold", "reliance", "memory")

    def __init__(
        self,
        value: float,
        *,
        plasticity: float = 1.0,
        spread: float = 1.0,
        size: int = 16,
        prior_weight: float = 0.1,
        threshold: float = 0.05,
        reliance: float = 0.2,
        memory: float = 600.0,
        clock: Clock | None = None,
    ) -> None:
        super().__init__(value, plasticity=plasticity)
        if not 0.0 < threshold < 1.0:
            raise ValueError(f"surprise threshold must be in (0, 1) (got {threshold!r})")
        if not 0.0 < reliance <= 1.0:
            raise ValueError(f"reliance must be in (0, 1] (got {reliance!r})")
        if not memory > 0:
            raise ValueError(f"memory must be a positive time in seconds (got {memory!r})")
        self.model = GaussianModel(value, spread, size=size, prior_weight=prior_weight)
        self.threshold = float(threshold)
        self.trust = Confidence(float(reliance), float(memory), 1.0, clock.now() if clock is not None else None)
        self.clock = clock

    @property
    def reliance(self) -> float:
        return self.trust.reliance

    @reliance.setter
    def reliance(self, rate: float) -> None:
        self.trust.reliance = rate

    @property
    def memory(self) -> float:
        return self.trust.memory

    @memory.setter
    def memory(self, seconds: float) -> None:
        self.trust.memory = seconds

    @property
    def reliability(self) -> float:
        return self.trust.reliability

    @reliability.setter
    def reliability(self, r: float) -> None:
        self.trust.reliability = r

    @property
    def tested_at(self) -> float | None:
        return self.trust.tested_at

    @tested_at.setter
    def tested_at(self, t: float | None) -> None:
        self.trust.tested_at = t

    def likelihood(self, v_n: float) -> float:
        """Unnormalised p(V_n) around the moving mean V_l with the model's σ."""
        z = (float(v_n) - self.value) / self.model.std
        return math.exp(-0.5 * z * z)

    def confidence(self, t: float | None = None) -> float:
        """How much to trust the model now (see the class docstring)."""
        if t is None and self.clock is not None:
            t = self.clock.now()
        return self.trust.at(t)

    def surprise(self, v_n: float, t: float | None = None) -> float:
        """0 if V_n is expected; else confidence·(1 − p(V_n)) — how surprising it is."""
        p = self.likelihood(v_n)
        return 0.0 if p >= self.threshold else self.confidence(t) * (1.0 - p)

    def blend_to(self, other: Value, alpha: float) -> None:
        a = self.rate(alpha)
        if a == 0.0:
            return
        v_n = _learned(other)
        hit = self.likelihood(v_n) >= self.threshold
        self.trust.record(hit, self.clock.now() if self.clock is not None else None, weight=a)
        self.model.update(v_n, weight=a)
        self.value = toward(self.value, v_n, a)

    def to_dict(self) -> dict[str, Any]:
        return {
            **super().to_dict(),
            "model": self.model.to_dict(),
            "threshold": self.threshold,
            "reliance": self.reliance,
            "memory": self.memory,
            "reliability": self.reliability,
            "tested_at": self.tested_at,
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any], *, clock: Clock | None = None) -> "GaussianValue":
        model = GaussianModel.from_dict(data["model"])
        value = cls(
            data["value"],
            plasticity=data.get("plasticity", 1.0),
            spread=model.prior_std,
            size=model.size,
            prior_weight=model.prior_weight,
            threshold=data["threshold"],
            reliance=data["reliance"],
            memory=data["memory"],
            clock=clock,
        )
        value.model = model
        value.reliability = float(data["reliability"])
        value.tested_at = data.get("tested_at")
        return value

    def restore(self, data: dict[str, Any]) -> None:
        """Take back what was learnt (the value, its reliability, the model's samples) into
        this value, whose threshold, reliance, memory and prior are the author's settings.
        Raises ValueError naming the key on damaged data."""
        data = bounds.table(data, "value")
        self.model.restore(bounds.table(data.get("model"), "value.model"))
        self.value = bounds.number(data.get("value"), "value.value", low=-bounds.LARGEST_VALUE, high=bounds.LARGEST_VALUE)
        self.reliability = bounds.number(data.get("reliability"), "value.reliability", low=0.0, high=1.0)
        tested = data.get("tested_at")
        self.tested_at = None if tested is None else bounds.number(tested, "value.tested_at", low=0.0,
                                                                  high=bounds.LATEST_TIME)

    def __repr__(self) -> str:
        return f"GaussianValue({self.value:.4g} ± {self.model.std:.3g})"


class StanceValue(ScalarValue):
    """A value with an emotional stance tag in [−1, 1] (thesis: "emotional tags").

    The stance is blended by the same α as the scalar (toward the stance of a following
    StanceValue; other values carry no tag and leave it alone). When the owning tuple becomes
    active, :meth:`perturb` pulls a character-wide mood toward this stance
    (:class:`creatures.behaviour.emotion.Mood`), so a startle that has come to predict food
    stops being frightening.
    """

    kind = "stance"

    def __init__(self, value: float, *, plasticity: float = 1.0, stance: float = 0.0) -> None:
        super().__init__(value, plasticity=plasticity)
        if not -1.0 <= stance <= 1.0:
            raise ValueError(f"stance must be in [-1, 1] (got {stance!r})")
        self.stance = float(stance)

    def blend_to(self, other: Value, alpha: float) -> None:
        super().blend_to(other, alpha)
        if isinstance(other, StanceValue):
            self.stance = toward(self.stance, other.stance, self.rate(alpha))

    def perturb(self, mood: float, strength: float) -> float:
        """The mood moved toward this stance by ``strength`` in [0, 1]."""
        s = min(max(strength, 0.0), 1.0)
        return (1.0 - s) * mood + s * self.stance

    def to_dict(self) -> dict[str, Any]:
        return {**super().to_dict(), "stance": self.stance}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> "StanceValue":
        return cls(data["value"], plasticity=data.get("plasticity", 1.0), stance=data["stance"])

    def __repr__(self) -> str:
        return f"StanceValue({self.value:.4g}, stance={self.stance:+.2f})"


class ProcessedValue(ScalarValue):
    """A scalar value with signal processing in its blend (thesis: "value signal processing":
    "we can look at V₁.blendTo(V₂, α) as an opportunity to perform arbitrary signal processing").

    - **Leaky**: value slowly leaks out toward ``rest``, V(t) = rest + (V − rest)·exp(−leak·Δt)
      over the seconds Δt since it was last set, so what is not re-earned is forgotten. It
      needs the creature's ``clock`` (not saved: re-attached after loading, like a chain
      value's importance); without one nothing leaks.
    - **Momentum**: credit assignment keeps going in the direction it has been going,
      Δ = a·(V_n − V) + momentum·Δ_previous, so a run of credit in one direction moves the
      value further than each step alone, and one contrary step only slows it.
    """

    kind = "processed"
    SETTINGS = (*ScalarValue.SETTINGS, "leak", "rest", "momentum")

    def __init__(
        self,
        value: float,
        *,
        plasticity: float = 1.0,
        leak: float = 0.0,
        rest: float = 0.0,
        momentum: float = 0.0,
        velocity: float = 0.0,
        clock: Clock | None = None,
        set_at: float | None = None,
    ) -> None:
        super().__init__(value, plasticity=plasticity)
        if not leak >= 0:
            raise ValueError(f"leak must be a rate ≥ 0 per second (got {leak!r})")
        if not 0.0 <= momentum < 1.0:
            raise ValueError(f"momentum must be in [0, 1) (got {momentum!r})")
        self.leak = float(leak)
        self.rest = float(rest)
        self.momentum = float(momentum)
        self.velocity = float(velocity)
        self.clock = clock
        self.set_at = set_at if set_at is not None else (clock.now() if clock is not None else None)

    def to_float(self) -> float:
        if not self.leak or self.clock is None or self.set_at is None:
            return self.value
        dt = max(0.0, self.clock.now() - self.set_at)
        return self.rest + (self.value - self.rest) * math.exp(-self.leak * dt)

    def blend_to(self, other: Value, alpha: float) -> None:
        self.value = self.to_float()  # what has leaked out is gone
        if self.clock is not None:
            self.set_at = self.clock.now()
        a = self.rate(alpha)
        if a == 0.0:
            return
        self.velocity = toward(self.value, _learned(other), a) - self.value + self.momentum * self.velocity
        self.value += self.velocity

    def to_dict(self) -> dict[str, Any]:
        return {**super().to_dict(), "value": self.to_float(), "leak": self.leak, "rest": self.rest,
                "momentum": self.momentum, "velocity": self.velocity}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> "ProcessedValue":
        return cls(data["value"], plasticity=data.get("plasticity", 1.0), leak=data["leak"], rest=data["rest"],
                   momentum=data["momentum"], velocity=data.get("velocity", 0.0))

    def __repr__(self) -> str:
        return f"ProcessedValue({self.to_float():.4g}, leak={self.leak:g}, momentum={self.momentum:g})"


VALUE_KINDS: dict[str, type] = {
    cls.kind: cls for cls in (ScalarValue, ChainValue, GaussianValue, StanceValue, ProcessedValue)
}


def reattach(fresh: Value, old: Value) -> Value:
    """``fresh`` (just loaded) given the creature state ``old`` held and values do not save:
    a chain value's live ``importance`` map, a leaky or Gaussian value's ``clock``."""
    for attr in ("importance", "clock"):
        if getattr(old, attr, None) is not None and hasattr(fresh, attr):
            setattr(fresh, attr, getattr(old, attr))
    if isinstance(fresh, ProcessedValue) and fresh.clock is not None:
        fresh.set_at = fresh.clock.now()
    return fresh


def restored(authored: Value, saved: Value) -> Value:
    """The value a restart gives a tuple: what it learnt (``saved``) with the settings the
    config now gives it (its kind's ``SETTINGS``: plasticity, a leak and its rest, a chain's
    source …), or the config's own where either is a reward.

    A non-plastic value was written by the author, never learnt: the config's stands, so an
    author who raises a reward, or makes a tuple a reward, hears it after a restart (before,
    the saved record replaced it whole, and a group could lose the reward that grounds it).
    Settings are the config's as every other setting is (README, "What a restart keeps"): an
    edited leak or rest came back as saved.
    """
    if getattr(authored, "plasticity", 1.0) == 0.0 or getattr(saved, "plasticity", 1.0) == 0.0:
        return authored
    if isinstance(saved, ScalarValue) and isinstance(authored, ScalarValue):
        saved.take_settings(authored)
    return saved


def value_from_dict(data: dict[str, Any]) -> Value:
    """Rebuild a value saved with ``to_dict``; the ``kind`` key picks the class.

    A malformed record raises ValueError naming the missing key; a value or plasticity that
    is not a finite number of sane size (:data:`creatures.bounds.LARGEST_RATE`) is refused,
    whatever the kind, before it can weigh in action selection.
    """
    data = bounds.table(data, "value")
    try:
        cls = VALUE_KINDS[data["kind"]]
    except (KeyError, TypeError):
        raise ValueError(f"unknown value kind {data.get('kind')!r}") from None
    if "value" in data:
        bounds.number(data["value"], "value", low=-bounds.LARGEST_VALUE, high=bounds.LARGEST_VALUE)
    bounds.number(data.get("plasticity", 1.0), "plasticity", low=0.0, high=1e3)
    try:
        return cls.from_dict(data)
    except KeyError as exc:
        raise ValueError(f"{data['kind']} value is missing key {exc.args[0]!r}") from None
