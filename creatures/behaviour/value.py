"""The Value interface and the scalar low-pass value (thesis: "complex value implementations").

Value gets its meaning only through action selection. The thesis asks only four operations of
a value: ``toDouble``, ``compareTo``, ``distanceTo`` and ``blendTo``; anything richer (tracer
dye, Gaussian models, emotional tags) is hidden behind them so action-groups never need to
know which implementation a tuple carries.
"""

from __future__ import annotations

import enum
from abc import ABC, abstractmethod
from typing import Any


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

    def __init__(self, value: float, *, plasticity: float = 1.0) -> None:
        self.value = float(value)
        self.plasticity = float(plasticity)

    def to_float(self) -> float:
        return self.value

    def blend_to(self, other: Value, alpha: float) -> None:
        a = min(max(alpha * self.plasticity, 0.0), 1.0)
        self.value = (1.0 - a) * self.value + a * other.to_float()

    def to_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "value": self.value, "plasticity": self.plasticity}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> "ScalarValue":
        return cls(data["value"], plasticity=data.get("plasticity", 1.0))

    def __repr__(self) -> str:
        return f"ScalarValue({self.value:.4g})"


VALUE_KINDS: dict[str, type] = {ScalarValue.kind: ScalarValue}


def value_from_dict(data: dict[str, Any]) -> Value:
    """Rebuild a value saved with ``to_dict``; the ``kind`` key picks the class."""
    try:
        cls = VALUE_KINDS[data["kind"]]
    except KeyError:
        raise ValueError(f"unknown value kind {data.get('kind')!r}") from None
    return cls.from_dict(data)
