"""The behaviour system: action-tuples, percepts, state objects, values and action-groups
(Downie 2001, "phase one" to "phase four"). One concept per module; the names are the
thesis's vocabulary."""

from creatures.behaviour.action_group import ActionGroup, group_tuple
from creatures.behaviour.action_tuple import Action, ActionTuple, DoUntil, DurationModel
from creatures.behaviour.creature import Creature
from creatures.behaviour.emotion import Mood
from creatures.behaviour.learning import ParametrisedAction, PerceptLearning
from creatures.behaviour.models.activation import ActivationModel
from creatures.behaviour.models.fuzzy import AndPercept, NotPercept, OrPercept
from creatures.behaviour.models.gaussian import GaussianModel, GaussianPercept
from creatures.behaviour.models.transition import TransitionModel
from creatures.behaviour.motivation import Motivation
from creatures.behaviour.percept import FunctionPercept, Percept, WhateverPercept
from creatures.behaviour.state_object import Habituation, StateObject
from creatures.behaviour.value import (
    ChainValue,
    Comparison,
    GaussianValue,
    ScalarValue,
    StanceValue,
    Value,
    value_from_dict,
)

__all__ = [
    "Action",
    "ActionGroup",
    "ActionTuple",
    "ActivationModel",
    "AndPercept",
    "ChainValue",
    "Comparison",
    "Creature",
    "DoUntil",
    "DurationModel",
    "FunctionPercept",
    "GaussianModel",
    "GaussianPercept",
    "GaussianValue",
    "Habituation",
    "Mood",
    "Motivation",
    "NotPercept",
    "OrPercept",
    "ParametrisedAction",
    "Percept",
    "PerceptLearning",
    "ScalarValue",
    "StanceValue",
    "StateObject",
    "TransitionModel",
    "Value",
    "WhateverPercept",
    "group_tuple",
    "value_from_dict",
]
