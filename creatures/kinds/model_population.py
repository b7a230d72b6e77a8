"""A population of sequence models that themselves have no idea how to split (thesis
"other models" and "listen (installation)": such models need "a percept higher in the tree
that manages its children ... the maintenance of a population of models").

The models are gesture models (:class:`~creatures.motor.gesture.GestureModel`) over node
identities whose states carry heard notes. The population spawns a model for material none
explains (fission), fuses models whose cores are the same cycle, distils an overgrown model
to its core, and retires models that stop being useful, so its size stays bounded however
long the music goes on. The ``population`` percept of authored creatures keeps one
(:mod:`creatures.authored.listening`) and ``dance`` dances its best member.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from creatures import bounds
from creatures.motor.gesture import GestureModel, Observation

FLOOR = 1e-3
"""Probability GestureModel.log_likelihood gives a transition the model has never seen."""

FORGOTTEN = 0.01
"""Usefulness below which a model that is not the best match retires."""

NOTES_KEPT = 8
"""Heard notes a model state keeps a reference to (their mean velocity sets predicted notes')."""


@dataclass
class Member:
    """One model of the population, with what maintenance needs to know about it."""

    id: int
    model: GestureModel
    born: float
    usefulness: float = 0.0


class ModelPopulation:
    """Gesture models of heard notes: spawned, taught, fused, distilled and retired.

    ``on_event(kind, **fields)`` is told of every birth and retirement. Time only enters
    through the ``t`` arguments (usefulness decays by elapsed time, never by call count).
    """

    def __init__(self, *, known: float, evidence: int, max_models: int, max_states: int, forget: float,
                 on_event=None) -> None:
        self.members: list[Member] = []
        self.known = known
        self.evidence = evidence
        self.max_models = max_models
        self.max_states = max_states
        self.forget = forget
        self.best: Member | None = None
        self.best_score = -math.inf
        self._next_id = 0
        self._time = 0.0
        self._on_event = on_event or (lambda kind, **fields: None)

    @property
    def threshold(self) -> float:
        """Lowest mean log-likelihood of a window that a model may learn: that of a window
        with ``known`` of its transitions certain and the rest never heard."""
        return (1.0 - self.known) * math.log(FLOOR)

    def _spawn(self, t: float) -> Member:
        member = Member(self._next_id, GestureModel(), t)
        self._next_id += 1
        self.members.append(member)
        self._on_event("model", action="spawn", model=member.id)
        return member

    def _retire(self, member: Member, reason: str) -> None:
        self.members.remove(member)
        if self.best is member:
            self.best, self.best_score = None, -math.inf
        self._on_event("model", action="retire", model=member.id, reason=reason,
                       states=len(member.model.states))

    def learn(self, t: float, context: list[Observation], new: list[Observation]) -> Member | None:
        """Teach ``context + new`` to a model, spawn one for it, or wait for more evidence.

        In order: the model that best explains the transitions into and within the ``new``
        notes learns them; else a model still growing at that point (its state for the last
        context note leads nowhere yet) that explains the context extends itself; else, once
        at least ``evidence`` transitions are unexplained, a new model is spawned (fission).
        Returns None while waiting: the caller keeps the notes and asks again later.
        """
        arriving = context[-1:] + new
        window = context + new
        if self.members and len(arriving) >= 2:
            scores = [m.model.log_likelihood(arriving, floor=FLOOR) for m in self.members]
            if max(scores) >= self.threshold:
                return self._teach(self.members[int(np.argmax(scores))], window)
        growing = [m for m in self.members if context and _grows_from(m.model, context, self.threshold)]
        if growing:
            return self._teach(max(growing, key=lambda m: m.usefulness), window)
        if len(arriving) - 1 >= self.evidence:
            return self._teach(self._spawn(t), window)
        return None

    @staticmethod
    def _teach(member: Member, window: list[Observation]) -> Member:
        for state in member.model.learn(window):
            notes = member.model.states[state].notes
            del notes[:-NOTES_KEPT]
        return member

    def match(self, t: float, memory: list[Observation]) -> Member | None:
        """Choose the model that best explains ``memory``; it gains usefulness."""
        self._decay(t)
        if not self.members or len(memory) < 2:
            return self.best
        scores = np.array([m.model.log_likelihood(memory, floor=FLOOR) for m in self.members])
        k = int(np.argmax(scores))
        self.best, self.best_score = self.members[k], float(scores[k])
        self.best.usefulness += 1.0
        return self.best

    def _decay(self, t: float) -> None:
        factor = math.exp(-max(t - self._time, 0.0) / self.forget)
        self._time = max(t, self._time)
        for m in self.members:
            m.usefulness *= factor

    def maintain(self, t: float) -> None:
        """Fusion, distillation and retirement (the population stays bounded)."""
        for member in list(self.members):
            if len(member.model.states) > self.max_states:
                self._distil(member)
        cores: dict[tuple[int, ...], Member] = {}
        for member in sorted(self.members, key=lambda m: -m.usefulness):
            key = _cycle_key(member.model)
            if key is None:
                continue
            if key in cores:
                cores[key].usefulness += member.usefulness
                self._retire(member, "fused with model %d" % cores[key].id)
            else:
                cores[key] = member
        for member in [m for m in self.members if m is not self.best and m.usefulness < FORGOTTEN
                       and t - m.born > self.forget]:
            self._retire(member, "forgotten")
        while len(self.members) > self.max_models:
            spare = [m for m in self.members if m is not self.best]
            self._retire(min(spare, key=lambda m: (m.usefulness, -m.id)), "population full")

    def _distil(self, member: Member) -> None:
        """Replace a model overgrown with noise by one learnt from its core alone. A core may
        be the whole model (one long path, each step repeated): then its first ``max_states``
        states are kept, so that a distilled model is always within the bound."""
        old = member.model
        core = old.core()[: self.max_states]
        fresh = GestureModel(entropy_weight=old.entropy_weight, threshold=old.threshold)
        times = np.concatenate(([0.0], np.cumsum([old.states[s].dwell for s in core[:-1]])))
        fresh.learn([Observation(old.states[s].node, float(u)) for s, u in zip(core, times)])
        if len(core) > 1 and core[0] in old.states[core[-1]].out:  # the core is a cycle: close it
            fresh.learn([Observation(old.states[core[-1]].node, 0.0),
                         Observation(old.states[core[0]].node, old.states[core[-1]].dwell)])
        self._on_event("model", action="distil", model=member.id, states=len(old.states), core=len(core))
        member.model = fresh

    def to_dict(self) -> dict[str, Any]:
        """The members, and how well the best one matched (what the ``population`` percept
        reads between analyses: without it a restored best matched at −inf, the percept 0);
        a match never made (−inf, not JSON) is left out, as states saved before it were."""
        data = {"next_id": self._next_id, "time": self._time,
                "best": None if self.best is None else self.best.id,
                "members": [{"id": m.id, "born": m.born, "usefulness": m.usefulness, "model": m.model.to_dict()}
                            for m in self.members]}
        if self.best is not None and math.isfinite(self.best_score):
            data["best_score"] = self.best_score
        return data

    def restore(self, data: dict[str, Any], *, nodes: int, now: float) -> None:
        """Take back saved members (models over a graph of ``nodes`` poses); every number is
        checked against this population's bounds, which stay its own (the config's).

        The clock restarts at ``now`` (a run's clock starts at 0): each member keeps its age,
        so it is born before ``now`` (a negative time for one older than this run), and
        usefulness decays from ``now``. Taken back as saved, the clock stood where the last
        run ended and nothing decayed or grew old enough to retire for as long again."""
        self._next_id = bounds.count(data["next_id"], "population.next_id")
        saved_at = bounds.number(data["time"], "population.time", low=0.0, high=bounds.LATEST_TIME)
        self._time = now
        members = []
        # The config's max_models wins: a population saved larger keeps its first members.
        saved = bounds.items(data["members"], "population.members", longest=MOST_MODELS)[: self.max_models]
        for i, m in enumerate(saved):
            where = f"population.members.{i}"
            m = bounds.table(m, where)
            members.append(Member(bounds.count(m["id"], f"{where}.id"),
                                  GestureModel.from_dict(m["model"], nodes=nodes, longest=4 * MOST_STATES, where=f"{where}.model"),
                                  now - saved_at + bounds.number(m["born"], f"{where}.born", low=-bounds.LATEST_TIME,
                                                                 high=bounds.LATEST_TIME),
                                  bounds.number(m["usefulness"], f"{where}.usefulness")))
        self.members = members
        self.best = next((m for m in self.members if m.id == data["best"]), None)
        self.best_score = -math.inf
        if self.best is not None and data.get("best_score") is not None:  # a log-likelihood: at most 0
            self.best_score = bounds.number(data["best_score"], "population.best_score",
                                            low=-bounds.LARGEST_VALUE, high=0.0)


MOST_MODELS, MOST_STATES = 64, 4096
"""Largest ``max_models`` and ``max_states`` a config may set; a saved model may have grown
past ``max_states`` until its next distillation, so up to four times that is read back."""


def _grows_from(model: GestureModel, context: list[Observation], threshold: float) -> bool:
    """Whether ``model`` explains ``context`` and its state for the last context note has no
    way on yet: new notes there extend the model rather than depart from it."""
    if not any(not model.states[s].out for s in model.states_of(context[-1].node)):
        return False
    return len(context) < 2 or model.log_likelihood(context, floor=FLOOR) >= threshold


def _cycle_key(model: GestureModel) -> tuple[int, ...] | None:
    """A model's core as a rotation-free key (the rotation starting at its smallest node)."""
    nodes = model.core_nodes()
    if len(nodes) < 3:
        return None
    k = nodes.index(min(nodes))
    return tuple(nodes[k:] + nodes[:k])
