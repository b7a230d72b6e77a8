"""Hearing sounds and singing them back, for authored creatures (thesis "soundcreatures
(installation)", "aural Ac percept trees", "aural models – cepstral models").

``[creature.hearing]`` gives a creature a microphone-as-ear and a loudspeaker-as-mouth
(:mod:`creatures.kinds.hearing_parts`): the ear cuts what it hears into cepstral utterances,
deaf while its own mouth sings (half-duplex). What it hears goes to one utterance percept tree,
declared as a percept of type ``utterance``; value-driven fission splits the tree into
utterance classes, and the same tree is the *Ac* side: ``sing`` sings an exemplar drawn from
a percept of it, and every new class becomes a new tuple to try (``learning.aural``,
:class:`~creatures.kinds.hearing_parts.AuralLearning`). Raw samples are kept with the cepstra
because cepstra cannot be sung back.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from audio.utterance import Utterance, UtterancePercept, load_aural_model
from creatures.authored.skills import CUTOFF
from creatures.behaviour.action_group import ActionGroup
from creatures.behaviour.action_tuple import ActionTuple, DoUntil
from creatures.config import ConfigError
from creatures.kinds.hearing_parts import AuralLearning, Ear, Mouth, Singers, SingFrom, tree_from_state, tree_state
from creatures.motor.search import NoPath

if TYPE_CHECKING:
    from creatures.authored.creature import Authored


class Aural:
    """One creature's ear, mouth and utterance tree (built by its ``utterance`` percept)."""

    def __init__(self, creature: "Authored") -> None:
        spec = creature.spec
        self.creature = creature
        self.ear = Ear(spec.hearing)
        self.mouth = Mouth(spec.mouth, self.ear.singing, None if creature.body is None else creature.body.graph)
        self.root: UtterancePercept | None = None
        self.attended: Utterance | None = None  # the sound an ``attend`` last took
        self.singers = Singers(creature.rng, self._sing)

    def tree(self, name: str, seed_model: str | None, *, nearest: bool = False) -> UtterancePercept:
        """The creature's utterance tree, named ``name`` (one per creature: Tr and Ac share it);
        ``nearest``: its classes classify each sound (:class:`UtterancePercept`)."""
        if self.root is not None:
            raise ConfigError(self.creature.spec.source_file(), f"creature {self.creature.name}: one 'utterance' "
                              f"percept per creature (it is the root of its one aural tree; {self.root.name!r} "
                              f"is already)", key=f"percepts.{name}")
        h = self.creature.spec.hearing
        self.root = (load_aural_model(seed_model) if seed_model else
                     UtterancePercept(name, radius=h.radius, memory=h.memory, max_members=h.keep,
                                      max_classes=h.classes))
        self.root.name = name
        self.root.nearest = nearest
        return self.root

    def percept(self, name: str) -> UtterancePercept:
        """A percept of the tree by name (for ``sing``, ``attend``): one the config declared."""
        percept = self.creature.percept(name)
        if not isinstance(percept, UtterancePercept):
            raise ConfigError(self.creature.spec.source_file(), f"creature {self.creature.name}: {name!r} is not an "
                              f"'utterance' percept, so there is nothing in it to sing or attend")
        return percept

    # -- hearing and singing ---------------------------------------------------------------
    def listen(self, t: float, block: np.ndarray, sample_rate: int) -> None:
        for utterance in self.ear.listen(t, block, sample_rate):
            if self.root is not None:
                self.root.hear(utterance)
            self.creature.world.emit("sound", creature=self.creature.name,
                                     start=utterance.time - len(utterance.samples) / sample_rate,
                                     end=utterance.time, singing=self.mouth.sounding(t))

    def unattended(self, tree: UtterancePercept, t: float) -> float:
        """1 while ``tree`` hears a sound (within ``hearing.memory``) that no ``attend`` has
        taken yet, else 0."""
        heard = tree.heard(t)
        return 1.0 if heard is not None and heard is not self.attended else 0.0

    def sing_from(self, percept: UtterancePercept) -> SingFrom:
        """The one singing action of ``percept``, shared by every tuple that sings it (credit
        flows between them by its name)."""
        return self.singers(percept)

    def _sing(self, t: float, utterance: Utterance, percept: UtterancePercept) -> None:
        c = self.creature
        end = self.mouth.sing(t, utterance)
        if c.body is not None:  # the body breathes the sound out: a movement across the graph while singing
            try:
                c.body.motor.set_course(t, c.body.motor.course(t, [int(c.rng.integers(len(c.body.graph)))]))
            except NoPath:
                pass
        c.world.emit("sing", creature=c.name, percept=percept.name, start=t, end=end, heard_at=utterance.time)

    def learning(self, **options: Any) -> AuralLearning:
        """Fission of the tree's percepts when a tuple on them becomes valuable, new tuples
        for the classes it finds (Tr side and Ac side)."""
        return AuralLearning(self.root, self.sing_from, **options)

    def tick(self, t: float) -> None:
        self.mouth.tick(t)

    def render(self, out: np.ndarray, sample_rate: int) -> None:
        c = self.creature
        self.mouth.render(out, sample_rate, None if c.body is None else c.body.pose,
                          cutoff=max(float(c.voice_now(c.now())[CUTOFF]), 0.0))

    def report(self, t: float) -> None:
        log, name = self.creature.world.log, self.creature.name
        if self.root is not None:
            log.emit(t, "percepts", creature=name, sizes={p.name: len(p.members) for p in self.root.walk()})
        body = self.creature.body
        if body is not None:  # what the body gives the voice (thesis: rib cage → amplitude)
            pose = body.pose
            log.emit(t, "voice", creature=name, rib_cage=self.mouth.amplitude.feature(pose.positions),
                     amplitude=self.mouth.amplitude(pose), cutoff=self.mouth.cutoff(pose))

    # -- persistence -----------------------------------------------------------------------
    def state(self, groups: list[ActionGroup], authored: set[str]) -> dict[str, Any]:
        """The tree, the tuples learning added to ``groups`` (by trigger and action name), and
        the authored tuples it took away (``learning.refine``)."""
        members = {g.name: [m for m in self.creature.spec.groups[g.name].tuples if m in authored] for g in groups}
        return {"tree": tree_state(self.root),
                "tuples": {g.name: [[tp.trigger.name, tp.action.name, tp.name] for tp in g.tuples
                                    if tp.name not in authored] for g in groups},
                "refined": {g.name: [m for m in members[g.name] if all(tp.name != m for tp in g.tuples)]
                            for g in groups}}

    def restore(self, state: dict[str, Any], groups: dict[str, ActionGroup]) -> None:
        """Take back the learnt classes in place (the tuples holding the root keep it), then
        the tuples learning had made, each with the Du of the authored tuple it came from,
        and take away again the authored tuples refinement had taken away."""
        saved = tree_from_state(state["tree"], like=self.root)
        for child in list(self.root.utterance_children()):
            self.root.remove_child(child)
            child.parent = None
        self.root.members, self.root._born = saved.members, saved._born
        for child in list(saved.utterance_children()):
            self.root.add_child(child)
        percepts = {p.name: p for p in self.root.walk()}
        try:
            for group_name, tuples in state.get("tuples", {}).items():
                group = groups[group_name]
                for trigger, action, name in tuples:
                    if any(tp.name == name for tp in group.tuples):
                        continue
                    parent = next(tp for tp in group.tuples if tp.action.name == action
                                  or action.startswith("sing ") and isinstance(tp.action, SingFrom))
                    trig = percepts.get(trigger) or self.creature.percepts[trigger]
                    act = (self.sing_from(percepts[action.removeprefix("sing ")]) if action.startswith("sing ")
                           else parent.action)
                    du = parent.do_until
                    group.add(ActionTuple(name, trig, act, DoUntil(du.duration, until=du.until, learn=du.learn), 0.0))
            for group_name, names in state.get("refined", {}).items():
                for name in names:  # after the learnt tuples, whose Du some of these lend
                    groups[group_name].remove(groups[group_name].find(name), self.creature.now())
        except (KeyError, StopIteration, TypeError, ValueError) as exc:
            raise ValueError(f"{self.creature.name}: saved tuples name an unknown group, percept or action "
                             f"({type(exc).__name__}: {exc})") from None
