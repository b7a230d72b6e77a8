"""The behaviour system: action-tuples, percepts, state objects, values and action-groups
(Downie 2001, "phase one" to "phase four"). One concept per module; the names are the
thesis's vocabulary."""

from creatures.behaviour.action_tuple import Action, ActionTuple, DoUntil, DurationModel
from creatures.behaviour.percept import FunctionPercept, Percept, WhateverPercept
from creatures.behaviour.state_object import StateObject
from creatures.behaviour.value import Comparison, ScalarValue, Value, value_from_dict

__all__ = [
    "Action",
    "ActionTuple",
    "Comparison",
    "DoUntil",
    "DurationModel",
    "FunctionPercept",
    "Percept",
    "ScalarValue",
    "StateObject",
    "Value",
    "WhateverPercept",
    "value_from_dict",
]
