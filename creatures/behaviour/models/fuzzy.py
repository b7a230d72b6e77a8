"""Combinational percepts: "this *and* that", "this *or* that", "not this" (thesis: "phase
three – models", "combinational models").

Percepts are read as fuzzy membership measures, so the Boolean operations extend the fuzzy
way. Two standard families are offered, chosen per percept by ``logic``:

- ``"minmax"`` (Zadeh): and = min, or = max. Idempotent — "loud and loud" is just "loud".
- ``"product"`` (probabilistic): and = Π x, or = 1 − Π(1 − x). Every input counts, as for
  independent evidence.

Not is 1 − x in both. Saliencies outside [0, 1] are allowed elsewhere in the system (the
lion, the startling click); here inputs are clipped to [0, 1] first, because membership
algebra is only defined there.
"""

from __future__ import annotations

from typing import Any, Literal, Sequence

import math

from creatures.behaviour.percept import Percept

Logic = Literal["minmax", "product"]


def _memberships(operands: Sequence[Percept], t: float) -> list[float]:
    """Each operand's saliency clipped to a membership in [0, 1] (plain floats: a handful of
    operands per tick is cheaper in Python than as an array)."""
    return [min(max(float(p.evaluate(t)), 0.0), 1.0) for p in operands]


class _Combination(Percept):
    """A percept over other percepts (its operands, which stay where they are in their tree)."""

    symbol = ""

    def __init__(
        self,
        name: str,
        operands: Sequence[Percept],
        *,
        logic: Logic = "minmax",
        parent: Percept | None = None,
    ) -> None:
        super().__init__(name, parent=parent)
        if not operands:
            raise ValueError(f"{name}: a combinational percept needs at least one operand")
        if logic not in ("minmax", "product"):
            raise ValueError(f"{name}: logic must be 'minmax' or 'product' (got {logic!r})")
        self.operands = list(operands)
        self.logic = logic

    def to_dict(self) -> dict[str, Any]:
        return {
            **super().to_dict(),
            "logic": self.logic,
            "operands": [p.name for p in self.operands],
        }

    def __repr__(self) -> str:
        inner = f" {self.symbol} ".join(p.name for p in self.operands)
        return f"{type(self).__name__}({self.name!r}: {inner})"


class AndPercept(_Combination):
    """Fuzzy conjunction of its operands."""

    symbol = "and"

    def evaluate(self, t: float) -> float:
        x = _memberships(self.operands, t)
        return min(x) if self.logic == "minmax" else math.prod(x)


class OrPercept(_Combination):
    """Fuzzy disjunction of its operands."""

    symbol = "or"

    def evaluate(self, t: float) -> float:
        x = _memberships(self.operands, t)
        return max(x) if self.logic == "minmax" else 1.0 - math.prod(1.0 - v for v in x)


class NotPercept(_Combination):
    """Fuzzy complement of one operand: 1 − x."""

    symbol = "not"

    def __init__(self, name: str, operand: Percept, *, parent: Percept | None = None) -> None:
        super().__init__(name, [operand], parent=parent)

    def evaluate(self, t: float) -> float:
        return float(1.0 - _memberships(self.operands, t)[0])
