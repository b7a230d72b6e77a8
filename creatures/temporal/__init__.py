"""Temporal models for action-tuples (thesis: "temporal models": simple durations, forward
transition models, exotic duration models, temporal logics). One concept per module:

* :mod:`~creatures.temporal.onsets` — onsets → inter-onset intervals (MIDI and audio paths);
* :mod:`~creatures.temporal.durations` — the simple and the low-integer-ratio duration models;
* :mod:`~creatures.temporal.tree` — duration percept trees: a shared pulse and its levels;
* :mod:`~creatures.temporal.transitions` — Du with a forward transition model, and fission;
* :mod:`~creatures.temporal.intervals` — Allen's thirteen interval relations as Tr/Du constraints;
* :mod:`~creatures.temporal.du` — the Du wrapper the last two build on.
"""

from creatures.temporal.durations import LowIntegerRatioModel, SimpleDurationModel
from creatures.temporal.intervals import Relation, constrain, relation
from creatures.temporal.onsets import inter_onset_intervals, merge_onsets, onsets_from_intervals
from creatures.temporal.transitions import Succession, fission, follow
from creatures.temporal.tree import PulsePercept, Subdivision

__all__ = [
    "LowIntegerRatioModel",
    "PulsePercept",
    "Relation",
    "SimpleDurationModel",
    "Subdivision",
    "Succession",
    "constrain",
    "fission",
    "follow",
    "inter_onset_intervals",
    "merge_onsets",
    "onsets_from_intervals",
    "relation",
]
