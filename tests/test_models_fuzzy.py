"""Combinational (fuzzy-logic) percepts."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from creatures.behaviour.models.fuzzy import AndPercept, NotPercept, OrPercept
from creatures.behaviour.percept import FunctionPercept, WhateverPercept

unit = st.floats(0.0, 1.0)


def const(name: str, x: float) -> FunctionPercept:
    return FunctionPercept(name, lambda t: x)


def test_minmax_by_hand():
    a, b = const("loud", 0.7), const("high", 0.2)
    assert AndPercept("loud and high", [a, b]).evaluate(0.0) == 0.2
    assert OrPercept("loud or high", [a, b]).evaluate(0.0) == 0.7
    assert NotPercept("quiet", a).evaluate(0.0) == pytest.approx(0.3)


def test_product_by_hand():
    a, b = const("loud", 0.7), const("high", 0.2)
    assert AndPercept("and", [a, b], logic="product").evaluate(0.0) == pytest.approx(0.14)
    assert OrPercept("or", [a, b], logic="product").evaluate(0.0) == pytest.approx(
        1 - 0.3 * 0.8
    )


def test_saliencies_outside_unit_are_clipped():
    click = const("click", 3.0)  # the startling click
    lion = const("lion", -2.0)
    assert OrPercept("either", [click, lion]).evaluate(0.0) == 1.0
    assert AndPercept("both", [click, lion]).evaluate(0.0) == 0.0


def test_operands_are_evaluated_at_the_asked_time():
    rising = FunctionPercept("rising", lambda t: t)
    whatever = WhateverPercept()
    both = AndPercept("rising and whatever", [rising, whatever], parent=whatever)
    assert both.evaluate(0.25) == 0.25
    assert both.evaluate(0.75) == 0.75
    assert both.parent is whatever and rising.parent is None  # operands are not adopted


@given(unit, unit, st.sampled_from(["minmax", "product"]))
def test_boolean_corners_and_de_morgan(x, y, logic):
    a, b = const("a", x), const("b", y)
    and_ = AndPercept("and", [a, b], logic=logic).evaluate(0.0)
    or_ = OrPercept("or", [a, b], logic=logic).evaluate(0.0)
    not_or_nots = NotPercept(
        "n", OrPercept("o", [NotPercept("na", a), NotPercept("nb", b)], logic=logic)
    ).evaluate(0.0)
    assert and_ == pytest.approx(not_or_nots)  # De Morgan holds in both families
    assert 0.0 <= and_ <= min(x, y) + 1e-12 and max(x, y) - 1e-12 <= or_ <= 1.0


def test_bad_construction_is_refused():
    with pytest.raises(ValueError, match="at least one operand"):
        AndPercept("empty", [])
    with pytest.raises(ValueError, match="logic"):
        OrPercept("odd", [const("a", 1.0)], logic="lukasiewicz")  # type: ignore[arg-type]


def test_to_dict_names_operands():
    d = OrPercept("o", [const("a", 1), const("b", 0)], logic="product").to_dict()
    assert d["operands"] == ["a", "b"] and d["logic"] == "product" and d["type"] == "OrPercept"
