"""``kind = "authored"``: a creature built from its config (thesis: "motivation-based
authoring"; docs/DESIGN.md "Authored creatures").

The config names the parts; this module only composes the library's own: drives are one
:class:`~creatures.behaviour.motivation.Motivation`, percepts come from
:mod:`creatures.authored.percepts` (library percepts and models), tuples are
:class:`~creatures.behaviour.action_tuple.ActionTuple`, groups are
:class:`~creatures.behaviour.action_group.ActionGroup` (nested with ``group_tuple``, learning
with :class:`~creatures.behaviour.learning.PerceptLearning`, ``follow`` Du from
:mod:`creatures.temporal.transitions`, constraints from :mod:`creatures.temporal.intervals`).
One tick: drives advance with their percept inputs and arcs, then every top-level group
selects (the groups inside them are ticked by their group tuples). A crowd's creatures tick
together (:meth:`Authored.tick_many`): their drives and their selection's arithmetic as arrays
across them, each then finishing its own tick in turn.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, Callable, Sequence

import numpy as np

from creatures import bounds
from creatures.authored import registry
from creatures.authored.aural import Aural
from creatures.authored.check import ROOT
from creatures.authored.scripted import Scripted
from creatures.authored.ear import Ear
from creatures.authored.learnt import learning_state, restore_learning
from creatures.authored.skills import (CUTOFF, DAMPING, GAIN, PAN, PUSH, TENSION, VOICE_PARAMETERS, VOICE_REST,
                                       AdverbModel)
from creatures.authored.spec import AuthoredSpec, PartSpec, TupleSpec, UntilSpec, ValueSpec
from creatures.behaviour.action_group import ActionGroup, CrowdTick, group_tuple
from creatures.behaviour.action_tuple import ActionTuple, DoUntil
from creatures.behaviour.emotion import Mood
from creatures.behaviour.expectation import Expectations, check_saved
from creatures.behaviour.learning import PerceptLearning, copy_value
from creatures.behaviour.models.fuzzy import OrPercept
from creatures.behaviour.models.gaussian import GaussianModel
from creatures.behaviour.motivation import Motivation
from creatures.behaviour.percept import FunctionPercept, Percept, WhateverPercept
from creatures.behaviour.proximity import Proximity
from creatures.behaviour.state_object import StateObject
from creatures.behaviour.unplaced import Unplaced
from creatures.behaviour.value import ChainValue, GaussianValue, ProcessedValue, ScalarValue, StanceValue, Value, value_from_dict
from creatures.clock import Clock
from creatures.config import ConfigError
from creatures.kinds import register
from creatures.kinds.base import CreatureKind
from creatures.kinds.note_world import NoteWorld
from creatures.kinds.figures import figure_of
from creatures.kinds.layers import BodySpec
from creatures.kinds.parts import Body, Voice, couple_to_hands
from creatures.kinds.report_parts import MotorTrail, report_values, selection_logger
from creatures.kinds.shaping import GestureShaping, PerformGesture
from creatures.motor.dispatch import Gesture, redispatch
from creatures.motor.gesture import BodyMemory
from creatures.motor.blend import Blend
from creatures.score.layout import ScoreLayout
from creatures.score.tiles import load_tiles
from creatures.temporal import intervals
from creatures.temporal.transitions import Succession, follow
from midi.notes import NoteEvent

if TYPE_CHECKING:
    from creatures.runtime.world import World


def find_sensor(world: "World", name: str) -> StateObject:
    """A sensor of the installation's input map by name: the World keeps them as state
    objects (``world.sensors``); a missing one is a clear error listing those there are."""
    sensors = getattr(world, "sensors", None) or {}
    if name not in sensors:
        raise KeyError(f"no sensor named {name!r} in this installation (sensors: {sorted(sensors) or 'none'})")
    return sensors[name]


def make_value(spec: float | ValueSpec, importance, clock: Clock) -> Value:
    """V from its config: a number, or a scalar/chain/gaussian/stance table (``plastic = false``
    gives plasticity 0: a reward credit assignment cannot move; ``plasticity`` a share of each
    blend, a value that learns slowly; a scalar with ``leak`` or
    ``momentum`` is a :class:`ProcessedValue`, thesis "value signal processing")."""
    if isinstance(spec, int | float):
        return ScalarValue(float(spec))
    plasticity = (1.0 if spec.plasticity is None else spec.plasticity) if spec.plastic else 0.0
    if spec.kind == "stance":
        return StanceValue(spec.value, plasticity=plasticity, stance=spec.stance or 0.0)
    if spec.kind == "chain":
        return ChainValue(spec.value, plasticity=plasticity, source=spec.source,
                          importance=importance(spec.serves) if spec.serves else None)
    if spec.kind == "gaussian":
        return GaussianValue(spec.value, plasticity=plasticity, spread=spec.spread)
    if spec.leak or spec.momentum:
        return ProcessedValue(spec.value, plasticity=plasticity, leak=spec.leak, rest=spec.rest,
                              momentum=spec.momentum, clock=clock)
    return ScalarValue(spec.value, plasticity=plasticity)


@register("authored")
class Authored(CreatureKind):
    """A creature whose behaviour is its config (see the module docstring)."""

    Spec = AuthoredSpec

    def __init__(self, spec: AuthoredSpec, world: "World", rng: np.random.Generator) -> None:
        super().__init__(spec, world, rng)
        registry.load_parts()
        self.body = (Body(rng, ratios=spec.ratio_metric, figure=figure_of(spec.body),  # motor actions hold it
                          spec=spec.body if isinstance(spec.body, BodySpec) else None) if spec.body else None)
        self.trail = MotorTrail(world, self.name, self.body) if self.body is not None else None
        self.notes = NoteWorld(spec.space, self, self.body, rng) if spec.space is not None else None
        self.memory: BodyMemory | None = None  # complex shaping's body memory, made when a tuple needs it
        self.gestures: list[tuple[str, Gesture]] = []  # (shaping tuple, gesture) in dispatch order
        learning = spec.learning
        self.ear = Ear(phrase_gap=learning.phrase_gap, max_phrases=learning.max_phrases)
        self.motivation = self._drives(spec)
        # Each drive's impulse per note heard and per note played, the non-zero ones (every
        # note reaches every ear of a crowd: the spec is not searched for them each time).
        self._impulses = {which: [(name, getattr(d, which)) for name, d in spec.drives.items() if getattr(d, which)]
                          for which in ("on_heard", "on_played")}
        self.aural = Aural(self) if spec.hearing is not None else None
        self._tickers: list[Callable[[float], None]] = []  # parts' own per-tick work (see 'parts with a life')
        self._listeners: list[Callable[[NoteEvent, str], None]] = []
        self._readers: list[Callable[[NoteEvent, str], bool]] = []
        self._reporters: list[Callable[[float], None]] = []
        self._kept: dict[tuple[str, str], tuple[Callable[[], Any], Callable[[Any], None]]] = {}
        # [creature.score]: its motor system lays out tiles of music, not poses (thesis "(void *)")
        self.score = (ScoreLayout(spec.score, load_tiles(spec.score.tiles), self, rng)
                      if spec.score is not None else None)
        if self.score is not None:
            self.on_hear(self.score.hear)
        self.root = WhateverPercept(ROOT)
        self.percepts: dict[str, Percept] = {ROOT: self.root}
        for name in spec.percepts:
            self.percept(name)
        # Drives fed by percepts or scripted arcs (the others need no work per tick).
        self._fed = [(self.motivation.index(name), [(self.percept(p), r) for p, r in d.inputs.items()],
                      _Arc(d.arc, d.arc_repeat)) for name, d in spec.drives.items() if d.inputs or d.arc]
        self.tuples = {name: self._tuple(name, tp) for name, tp in spec.tuples.items()}
        for group in spec.groups.values():
            for constraint in group.constraints:
                intervals.constrain(self.tuples[constraint.a], intervals.Relation(constraint.relation),
                                    self.tuples[constraint.b], gap=constraint.gap)
        self.groups: dict[str, ActionGroup] = {}
        self.expectations = self._expectations(spec)
        members = {m for g in spec.groups.values() for m in g.tuples}
        self.top = [self._group(name) for name in spec.groups if name not in members]
        self.mood = (Mood(self.motivation, spec.mood.drive, strength=spec.mood.strength,
                          on_event=selection_logger(world, self.name)) if spec.mood is not None else None)
        if self.mood is not None:  # every group: a stance tuple inside a group tuple moves it too
            for group in self.groups.values():
                group.on_start.append(self.mood.felt)
        self.voice: Voice | None = None
        self._learnt: list[int] = []  # phrase numbers that have a tuple of their own
        self._heated = [(self.groups[n], g.temperature, [(self.motivation.index(d), k) for d, k in g.heat.items()])
                        for n, g in spec.groups.items() if g.heat]
        self._next_report = 0.0
        self._next_pose = 0.0
        # The soft state's steps start at a random phase per creature (a colony's load spreads).
        self._next_soft = float(rng.uniform(0.0, 1.0 / spec.soft_rate)) if spec.soft_rate else 0.0
        self._voice_parameters: Blend | None = None
        # [creature.modulate]: (parameter's channel, [(percept, weight)]), read at each block
        self._modulate = [(VOICE_PARAMETERS.index(p), [(self.percept(n), w) for n, w in weights.items()])
                          for p, weights in spec.modulate.items()]
        self._modulated: tuple[float, np.ndarray] = (math.nan, VOICE_REST)
        self._gain = 1.0  # voice.gain at the end of the last block sounded
        # Whether its tick may be worked out with a crowd's (tick_many): only drives, one group
        # and reports (no body, notes in space, ear of sounds, score or phrases learnt), no
        # transitions followed (a colony's succession is what the others' ticks change), and
        # only percepts that read nothing another creature's tick changes (PerceptPart.pure).
        self._shares = (self.body is None and self.notes is None and self.aural is None and self.score is None
                        and spec.learning.phrases is None and len(self.top) == 1
                        and not any(tp.until.follow for tp in spec.tuples.values())
                        and all(registry.PERCEPTS.get(p.type).pure for p in spec.percepts.values()))

    # -- building ---------------------------------------------------------------------
    def _drives(self, spec: AuthoredSpec) -> Motivation | None:
        if not spec.drives:
            return None
        d = spec.drives
        return Motivation(
            {n: x.level for n, x in d.items()},
            growth={n: x.growth for n, x in d.items()},
            decay={n: x.decay for n, x in d.items()},
            equilibrium={n: x.equilibrium for n, x in d.items() if x.equilibrium is not None},
            coupling={(n, other): rate for n, x in d.items() for other, rate in x.coupling.items()},
            floor=spec.drive_floor, ceiling=spec.drive_ceiling, start=self.now(),
        )

    def _expectations(self, spec: AuthoredSpec) -> Expectations | None:
        e = spec.expectations
        if not e.groups:
            return None
        return Expectations(tolerance=e.tolerance, grace=e.grace, reliance=e.reliance, memory=e.memory,
                            rigidity=e.rigidity, confident=e.confident, fission=e.fission, decay=e.decay,
                            transitions=e.transitions,
                            on_event=selection_logger(self.world, self.name))

    def percept(self, name: str) -> Percept:
        """The percept ``name``, built on first use (the loader excluded reference cycles)."""
        if name not in self.percepts:
            p = self.spec.percepts[name]
            cls = registry.PERCEPTS.get(p.type)
            percept = cls().build(cls.Params.model_validate(p.params()), self, name)
            self.percepts[name] = percept
            if cls.joins_tree:
                self.percept(p.parent).add_child(percept)
        return self.percepts[name]

    def _action(self, action: str | PartSpec, name: str, **extra: Any):
        part = PartSpec(type=action) if isinstance(action, str) else action
        cls = registry.ACTIONS.get(part.type)
        return cls().build(cls.Params.model_validate({**part.params(), **extra}), self, name)

    def _do_until(self, until: UntilSpec, action) -> DoUntil:
        duration = until.seconds
        model = until.model
        if until.pulse is not None:
            fallback = {} if until.gaussian is None else {"mean": until.gaussian[0], "std": until.gaussian[1]}
            model = PartSpec(type="pulse", beats=until.pulse, **fallback)
        elif until.gaussian is not None:
            model = PartSpec(type="gaussian", mean=until.gaussian[0], std=until.gaussian[1])
        if model is not None:
            cls = registry.MODELS.get(model.type)
            duration = cls().build(cls.Params.model_validate(model.params()), self)
        stops = [self.percept(until.percept)] if until.percept is not None else []
        if until.done:
            stops.append(FunctionPercept(f"{action.name} done", action.done))
        stop = None if not stops else stops[0] if len(stops) == 1 else OrPercept(f"{action.name} stops", stops)
        return DoUntil(duration, until=stop, graded=until.graded, fresh=until.fresh)

    def _tuple(self, name: str, tp: TupleSpec) -> ActionTuple:
        action = self._action(tp.action, name)
        return ActionTuple(name, self.percept(tp.trigger), action, self._do_until(tp.until, action),
                           make_value(tp.value, self._importance, self.world.clock))

    def _importance(self, serves: dict[str, str]):
        return self.motivation.importance(serves)

    def _group(self, name: str) -> ActionGroup:
        g = self.spec.groups[name]
        tuples = []
        succession = None
        for member in g.tuples:
            if member in self.spec.groups:
                child = self._group(member)
                child_spec = self.spec.groups[member]
                tuples.append(group_tuple(child, self.percept(child_spec.trigger), child_spec.value))
                continue
            tuple_ = self.tuples[member]
            until = self.spec.tuples[member].until
            if until.follow:
                if succession is None and g.succession is not None:  # the colony's, one stream a group
                    succession = self.world.successions.setdefault(g.succession, Succession(innovation=None))
                succession = succession or Succession(innovation=g.innovation)
                follow(tuple_, succession, strength=until.priming, label=until.follow_as,
                       stream=None if g.succession is None else f"{self.name}.{name}", record=until.record)
            tuples.append(tuple_)
        learning = self.spec.learning
        learner = None
        options = dict(statistics=learning.statistics, innovation=max(learning.innovation, learning.statistics),
                       min_trigger=learning.min_trigger, on_event=selection_logger(self.world, self.name))
        if name in learning.groups:
            learner = PerceptLearning(split_at=learning.split_at, fuse_below=learning.fuse_below, **options)
        elif name in learning.aural:
            learner = self.aural.learning(refine=learning.refine, in_kind=learning.in_kind, **options)
        learn = g.proximity_learning
        proximity = Proximity({(a, b): p for a, row in g.proximity.items() for b, p in row.items()},
                              **({} if learn is None else {"rate": learn.rate, "window": learn.window}))
        expects = self.expectations if name in self.spec.expectations.groups else None
        group = ActionGroup(name, tuples, rng=self.rng, alpha=g.alpha, discount=g.discount, multiple=g.multiple,
                            temperature=g.temperature, max_active=len(tuples) if g.perception else g.max_active,
                            learning=learner, expectations=expects, on_event=selection_logger(self.world, self.name),
                            proximity=proximity)
        for tuple_ in tuples:
            if isinstance(tuple_.action, GestureShaping):
                tuple_.action.attach(group)
        self.groups[name] = group
        return group

    # -- complex shaping (creatures/kinds/shaping.py) -----------------------------------------
    def body_memory(self) -> BodyMemory:
        """The memory of motor-graph nodes the body passed, fed by its motor trail every tick."""
        if self.memory is None:
            self.memory = BodyMemory()
            self.trail.memory = self.memory
        return self.memory

    def _group_of(self, tuple_name: str) -> ActionGroup:
        return next(g for g in self.groups.values() if any(tp.name == tuple_name for tp in g.tuples))

    def leave_behind(self, shaping: str, gesture: Gesture, *, restored: bool = False) -> ActionTuple:
        """A shaping tuple's core was dispatched: in its place, ``whenever | perform the new
        gesture | until done | V`` (its trigger, its value), thesis "learning to chase your tail –
        part 2"."""
        group = self._group_of(shaping)
        old = group.find(shaping)
        action = PerformGesture(gesture.name, self.body, gesture)
        old.action.successor = action
        tuple_ = ActionTuple(gesture.name, old.trigger, action,
                             DoUntil(None, until=FunctionPercept(f"{gesture.name} done", action.done)),
                             copy_value(old.value))
        group.add(tuple_)
        group.remove(old, self.now())
        self.gestures.append((shaping, gesture))
        self.world.emit("gesture", creature=self.name, tuple=gesture.name, replaces=shaping,
                        core=list(gesture.core), nodes=list(gesture.nodes), restored=restored)
        return tuple_

    # -- what outside input reaches (the input map: creatures/runtime/input_map.py) ----------
    @classmethod
    def drive_names(cls, spec: AuthoredSpec) -> tuple[str, ...]:
        """The authored drives: ``[[input]] to = "drive"`` may name any of them."""
        return tuple(spec.drives)

    @classmethod
    def rewardable(cls, spec: AuthoredSpec) -> bool:
        return True  # every authored creature has at least one group (the schema requires it)

    @classmethod
    def has_body(cls, spec: AuthoredSpec) -> bool:
        return bool(spec.body)

    @property
    def group(self) -> ActionGroup:
        """The first top-level group: what the kinds' shared readers take for "the" group (what
        other colonies are shown it doing, creatures/runtime/network.py)."""
        return self.top[0]

    def reward_groups(self) -> list[ActionGroup]:
        """The clicker reaches every top-level group; each passes it to the groups it holds."""
        return list(self.top)

    # -- parts with a life of their own (a model population, a song's place) -------------
    def each_tick(self, work: Callable[[float], None]) -> None:
        """Run ``work(t)`` every tick, after the drives and before the body and the groups:
        a percept that maintains a model at its own rate (thesis "listen (installation)": "the
        bulk of the creature's computation is spent maintaining a population of percepts")."""
        self._tickers.append(work)

    def on_hear(self, hear: Callable[[NoteEvent, str], None]) -> None:
        """Tell ``hear(note, source)`` of every note the creature hears (after its ear)."""
        self._listeners.append(hear)

    def on_reading(self, read: Callable[[NoteEvent, str], bool]) -> None:
        """Show ``read(note, source)`` every note that reaches the creature first: one that
        returns True takes the note as a sensor reading, not music (a rock sensor that reports
        as notes), and nothing of the creature hears it."""
        self._readers.append(read)

    def feed(self, t: float) -> None:
        """The drives' step: advance them to ``t`` and set their percept inputs and arcs from
        now on. Every tick runs it; an action that changes what feeds a drive (singing draws
        breath) runs it as it starts and stops, so the change counts from that instant."""
        self.motivation.advance(t)
        for i, inputs, arc in self._fed:
            self.motivation.hold_input(i, sum(r * p.evaluate(t) for p, r in inputs) + arc(t))

    def reporting(self, report: Callable[[float], None]) -> None:
        """Call ``report(t)`` with every values snapshot (a part's own events-log record)."""
        self._reporters.append(report)

    def keep(self, section: str, name: str, state: Callable[[], Any], restore: Callable[[Any], None]) -> None:
        """Save ``state()`` as ``parts.SECTION.NAME`` of the creature's state ("percepts" or
        "tuples", and the part's name) and give it back to ``restore`` on reload: what a part
        learnt or where it is lasts across restarts like the values do."""
        self._kept[(section, name)] = (state, restore)
    def reward(self, amount: float, t: float, window: float, rate: float) -> list[str]:
        """The clicker's reward (CreatureKind.reward), and each credited tuple's action that
        samples an Ac percept feeds its sample back into it (thesis "simple shaping")."""
        credited = super().reward(amount, t, window, rate)
        actions = {id(self.tuples[n].action): self.tuples[n].action for n in credited if n in self.tuples}
        for action in actions.values():
            shape = getattr(action, "shape", None)
            if shape is not None:
                shape(amount)
        return credited

    def _adverb_models(self) -> dict[str, Any]:
        """The Ac percepts rewards shape, by name (what a reload must keep)."""
        return {n: p for n, p in self.percepts.items() if isinstance(p, AdverbModel)}

    # -- what the runtime calls ---------------------------------------------------------
    def now(self) -> float:
        return self.world.clock.now()

    def level(self, name: str, t: float) -> float:
        """Drive ``name``'s level at ``t`` (``drive`` is the input map's perturbation, CreatureKind)."""
        return self.motivation.level(name, max(t, self.motivation.time))

    def tuple(self, name: str) -> ActionTuple:
        return self.tuples[name]

    def sensor(self, name: str) -> StateObject:
        try:
            return find_sensor(self.world, name)
        except KeyError as exc:
            raise ConfigError(self.spec.source_file(), exc.args[0], key=f"creature {self.name}: sensor") from None

    def play(self, pitch: int, velocity: int, duration: float, *, at: float, channel: int | None = None) -> None:
        self.world.play(self, NoteEvent(round(at, 6), pitch, velocity, self.spec.channel, duration), channel=channel)

    def hear(self, note: NoteEvent, source: str) -> None:
        if source == "input" and not self.spec.hears_input:
            return
        if any([read(note, source) for read in self._readers]):  # every reader is shown it; a reading is not music
            return
        t = self.now()
        self.ear.hear(t, note, source)
        self._impulse(t, "on_heard")
        if self.notes is not None:
            self.notes.hear(t, note, source)
        for hear in self._listeners:
            hear(note, source)

    def listen(self, t: float, block: np.ndarray, sample_rate: int) -> None:
        if self.aural is not None:
            self.aural.listen(t, block, sample_rate)

    @property
    def hears_audio(self) -> bool:
        return self.aural is not None

    def played(self, note: NoteEvent) -> None:
        self.ear.played.append(note)
        self._impulse(self.now(), "on_played")
        band = self.score.band if self.score is not None else None
        if band is not None and band.play(note.pitch, note.velocity, note.end, note.channel):
            return  # a score's part sounds in its own voice
        if self.voice is not None:
            self.voice.play(note.pitch, note.velocity, note.end, start=note.time)

    def _impulse(self, t: float, which: str) -> None:
        for name, amount in self._impulses[which]:
            self.motivation.perturb(t, name, amount)

    def _learn_phrase(self, t: float) -> None:
        """A new hypothesis for the last phrase heard, once it is over (``phrase_gap`` of
        silence) and long enough (thesis "percept trees": a new distinction, a new tuple to try)."""
        ph = self.spec.learning.phrases
        if (ph is None or not self.ear.phrases or len(self.ear.phrases[-1]) < ph.min_notes
                or self.ear.since_heard(t) <= self.ear.phrase_gap):
            return
        number = self.ear.phrases_made
        if number in self._learnt:
            return
        name = self._phrase_tuple(number)
        self.world.emit("hypothesis", creature=self.name, tuple=name, notes=len(self.ear.phrases[-1]))

    def _phrase_tuple(self, number: int) -> str:
        """Add ``phrase N | sing it | until sung | V`` to the phrases' group; returns its name."""
        ph = self.spec.learning.phrases
        self._learnt.append(number)
        name = f"phrase {number}"
        action = self._action(ph.action, name, phrase=number)
        self.groups[ph.group].add(ActionTuple(name, self.percept(ph.trigger), action,
                                              self._do_until(ph.until, action), ScalarValue(ph.value)))
        return name

    def best_phrase(self) -> int | None:
        """The number of the remembered phrase whose own tuple is worth the most (its value
        learnt by credit assignment: ``learning.phrases``), or None while there is none."""
        ph = self.spec.learning.phrases
        if ph is None:
            return None
        worth = {tp.name: tp.value.to_float() for tp in self.groups[ph.group].tuples}
        kept = [n for n in self._learnt if f"phrase {n}" in worth and self.ear.phrase(n) is not None]
        return max(kept, key=lambda n: worth[f"phrase {n}"], default=None)

    def tick(self, t: float) -> None:
        self._learn_phrase(t)
        if self.notes is not None:
            self.notes.fade(t)
        soft = self._soft_step(t)
        self._prepare(t, soft)
        for group in self.top:
            if soft or group.active:  # a new tuple is chosen on the soft state's steps
                group.tick(t, choose=soft)
        self._conclude(t)

    @classmethod
    def tick_many(cls, creatures: Sequence[CreatureKind], t: float) -> None:
        """Every creature's :meth:`tick`, a crowd's selection worked out together: those that
        may share (:attr:`_shares`) have their drives advanced as one array
        (:meth:`Motivation.advance_all`) and their group's triggers, expected values and
        whether selection has work as arrays across them (:class:`CrowdTick`); then each
        creature, the others among them in their turn, finishes its tick in order (starts,
        stops, notes and events as one by one)."""
        shares = [creature._shares and not creature._tickers for creature in creatures]  # type: ignore[attr-defined]
        if sum(shares) < 2:
            super().tick_many(creatures, t)
            return
        crowd: list[Authored] = [creature for creature, share in zip(creatures, shares) if share]  # type: ignore[misc]
        soft = [creature._soft_step(t) for creature in crowd]  # phrases and notes in space they have none of
        Motivation.advance_all([c.motivation for c, s in zip(crowd, soft) if s and c.motivation is not None], t)
        ticking: list[ActionGroup | None] = []  # each one's group, if it ticks now
        for creature, s in zip(crowd, soft):
            creature._prepare(t, s)
            group = creature.top[0]
            ticking.append(group if s else None)  # between soft steps a running group ticks alone, choosing nothing
        together = CrowdTick([group for group in ticking if group is not None], t)
        shared = iter(zip(crowd, ticking))
        k = 0
        for creature, share in zip(creatures, shares):
            if not share:
                creature.tick(t)
                continue
            me, group = next(shared)
            if group is not None:
                together.finish(group, k)
                k += 1
            elif me.top[0].active:
                me.top[0].tick(t, choose=False)
            me._conclude(t)

    def _prepare(self, t: float, soft: bool) -> None:
        """A tick's work before the groups select: on a step of the soft state the drives'
        step and the heat they give groups; the parts' own work, what is heard, the body."""
        if self.motivation is not None and soft:
            self.feed(t)
            levels = self.motivation.levels
            for group, base, heat in self._heated:
                group.temperature = base * (1.0 + sum(k * float(levels[i]) for i, k in heat))
        for work in self._tickers:
            work(t)
        if self.aural is not None:
            self.aural.tick(t)
        if self.body is not None and t >= self._next_pose:
            self._next_pose = t + (1.0 / self.spec.body_rate if self.spec.body_rate else 0.0)
            self.trail.follow(t)
            pose = self.body.update(t)
            if self.voice is not None:
                self.voice.feel(pose, push=self.voice_now(t)[PUSH])

    def _conclude(self, t: float) -> None:
        """A tick's work after the groups: the score and the notes in space, then the reports."""
        if self.score is not None:  # after the groups: a course chosen now is laid before anything commits
            self.score.tick(t)
        if self.notes is not None:
            self.notes.space.tick()
        if t >= self._next_report:
            self._next_report = t + self.spec.report_every
            for group in self.groups.values():
                report_values(self.world, t, self.name, group)
            if self.trail is not None:
                self.trail.report(t)
            if self.motivation is not None:
                heated = {} if not self._heated else {"temperature": self._heated[0][0].temperature}
                self.world.log.emit(t, "motivation", creature=self.name,
                                    drives=dict(zip(self.motivation.names, self.motivation.levels.tolist())), **heated)
            if self.aural is not None:
                self.aural.report(t)
            if self._voice_parameters is not None:  # who drives the voice (as "motor" says who drives the joints)
                blend = self._voice_parameters
                self.world.log.emit(t, "voice parameters", creature=self.name,
                                    values=dict(zip(VOICE_PARAMETERS, blend.resolve(t).tolist())),
                                    contributors={p: who for p, who in zip(VOICE_PARAMETERS, blend.channel_contributors(t))
                                                  if who})
            for report in self._reporters:
                report(t)
            if self.spec.report_percepts:
                self.world.log.emit(t, "percepts", creature=self.name,
                                    levels={p: float(self.percepts[p].evaluate(t)) for p in self.spec.report_percepts})

    def _soft_step(self, t: float) -> bool:
        """Whether ``t`` is a step of the soft state (every tick without ``soft_rate``)."""
        rate = self.spec.soft_rate
        if rate is None or t < self._next_soft:
            return rate is None
        while self._next_soft <= t:
            self._next_soft += 1.0 / rate
        return True

    def voice_parameters(self) -> Blend:
        """The voice parameters skills drive (creatures/authored/skills.py ``VOICE_PARAMETERS``:
        gain, pan, push, cutoff, tension, damping), blended as a body's joints are; made when a
        skill first needs them."""
        if self._voice_parameters is None:
            self._voice_parameters = Blend(len(VOICE_PARAMETERS), rotations=False, hold=VOICE_REST.copy())
        return self._voice_parameters

    def sound(self, out: np.ndarray, sample_rate: int) -> None:
        if self.aural is not None:  # a loudspeaker-as-mouth sings what it heard
            self.aural.render(out, sample_rate)
        else:
            if self.voice is None:
                self.voice = Voice(self.spec.voice, sample_rate)
                if self.body is not None:
                    couple_to_hands(self.voice, self.body)
            cutoff = 1.0
            if self._voiced:  # voice.tension, voice.damping, voice.cutoff
                knobs = self.voice_now(self.now())
                self.voice.retune(float(knobs[TENSION]), float(knobs[DAMPING]))
                cutoff = max(float(knobs[CUTOFF]), 0.0)
            self.voice.render(out, self.now(), cutoff=cutoff, gain=self.spec.voice.gain)
            if self.score is not None and self.score.band is not None:
                self.score.band.render(out, self.now(), sample_rate)
        if self._voiced:  # voice.gain, ramped across the block (no zipper steps)
            gain = max(float(self.voice_now(self.now())[GAIN]), 0.0)
            if gain != self._gain:
                out *= np.linspace(self._gain, gain, len(out))
            elif gain != 1.0:
                out *= gain
            self._gain = gain

    @property
    def _voiced(self) -> bool:
        """Whether anything moves its voice parameters (a skill, or [creature.modulate])."""
        return self._voice_parameters is not None or bool(self._modulate)

    def voice_now(self, t: float) -> np.ndarray:
        """The voice parameters at ``t`` (creatures/authored/skills.py): what skills set (at rest
        when none has driven them), plus ``[creature.modulate]``'s weight × saliency of each
        percept (read once per time: a block asks several times)."""
        if not self._modulate:
            return VOICE_REST if self._voice_parameters is None else self._voice_parameters.resolve(t)
        if self._modulated[0] != t:
            knobs = (VOICE_REST if self._voice_parameters is None else self._voice_parameters.resolve(t)).copy()
            for channel, inputs in self._modulate:
                knobs[channel] += sum(w * p.evaluate(t) for p, w in inputs)
            self._modulated = (t, knobs)
        return self._modulated[1]

    def pan(self) -> float:
        """Where the mix places this creature now: its ``pan`` moved by ``voice.pan``."""
        return min(max(self.spec.pan + float(self.voice_now(self.now())[PAN]), -1.0), 1.0)

    def marks(self) -> list[tuple[tuple[float, float, float], int]]:
        return [] if self.notes is None else self.notes.marks()

    def figure(self) -> tuple[np.ndarray, np.ndarray] | None:
        if self.body is None:
            return None
        return self.body.pose.positions, np.asarray(self.body.skeleton.parents)

    # -- persistence -------------------------------------------------------------------
    def state(self) -> dict[str, Any]:
        kept = self.unplaced_parts
        aural = {}
        if self.aural is not None and self.aural.root is not None:
            heard = self.aural.state([self.groups[n] for n in self.spec.learning.aural], set(self.tuples))
            aural = {"aural": {**heard, **{key: kept.carry(f"aural.{key}", heard[key]) for key in AURAL_BY_GROUP}}}
        shaping = kept.carry("shaping", {name: tp.action.to_dict() for name, tp in self.tuples.items()
                                         if isinstance(tp.action, GestureShaping)})
        parts = self._parts_state()
        learnt = learning_state(self, kept)
        expected = kept.carry("expectations", {name: kept.carry(f"expectations.{name}", self._expected(self.groups[name]))
                                               for name in self.spec.expectations.groups})
        return {
            **aural,
            **({"learning": learnt} if learnt else {}),
            **({"expectations": expected} if expected else {}),
            **({"shaping": shaping} if shaping else {}),
            **({"gestures": [{"shaping": s, **g.to_dict()} for s, g in self.gestures]} if self.gestures else {}),
            "proximity": kept.carry("proximity", {name: g.proximities.to_dict() for name, g in self.groups.items()}),
            "values": kept.carry("values", {name: kept.carry(f"values.{name}", g.value_state())
                                            for name, g in self.groups.items()}),
            "motivation": None if self.motivation is None else self.motivation.to_dict(),
            "phrases": [[[n.time, n.pitch, n.velocity, n.duration] for n in p] for p in self.ear.phrases],
            "phrases_made": self.ear.phrases_made,
            "learnt": list(self._learnt),
            **({"parts": parts} if parts else {}),
            "adverb_models": kept.carry("adverb_models", {n: p.model.to_dict() for n, p in self._adverb_models().items()}),
        }

    def restore(self, state: dict[str, Any]) -> None:
        self.ear.phrases.clear()
        for phrase in state.get("phrases", []):
            self.ear.phrases.append([NoteEvent(float(t), int(p), int(v), self.spec.channel, float(d))
                                     for t, p, v, d in phrase])
        self.ear.phrases_made = int(state.get("phrases_made", len(self.ear.phrases)))
        for number in state.get("learnt", []):
            if self.spec.learning.phrases is not None and int(number) not in self._learnt:
                self._phrase_tuple(int(number))
        kept = self.unplaced_parts = Unplaced()
        if "aural" in state and self.aural is not None and self.aural.root is not None:
            aural = bounds.table(state["aural"], "aural")
            self.aural.restore({**aural, **{key: kept.place(f"aural.{key}", aural[key], self.groups, what="aural learning",
                                                            of="action-group") for key in AURAL_BY_GROUP if key in aural}},
                               self.groups)
        self._restore_shaping(state)
        if "learning" in state:  # the trees and tuples learning grew, before their values
            restore_learning(self, kept, state["learning"])
        for name, data in kept.place("proximity", state.get("proximity", {}), self.groups, what="proximity table",
                                     of="action-group", check=lambda data, key: Proximity().restore(data, key)).items():
            self.groups[name].proximities.restore(data, f"proximity.{name}")
        for name, values in kept.place("values", state.get("values", {}), self.groups, what="value table",
                                       of="action-group", check=_value_table).items():
            group = self.groups[name]
            group.restore_values(kept.place(f"values.{name}", values, {tp.name for tp in group.tuples}, what="value",
                                            of="tuple", within=f" in action-group {name!r}", check=_value))
        self._restore_expectations(state.get("expectations", {}))
        models = self._adverb_models()
        for name, data in kept.place("adverb_models", state.get("adverb_models", {}), models, what="adverb model",
                                     of="percept", no="adverb_model percept", check=_adverb_model).items():
            models[name].model = _adverb_model(data, f"adverb_models.{name}")
        if state.get("motivation") and self.motivation is not None:
            # Levels only: the rates are the config's, so an edited growth takes effect after a restart.
            self.motivation.restore(state["motivation"], now=self.now())
        parts = bounds.table(state.get("parts", {}), "parts")
        for section in sorted({section for section, _ in self._kept} | parts.keys()):
            names = {name: restore for (where, name), (_, restore) in self._kept.items() if where == section}
            for name, saved in kept.place(f"parts.{section}", parts.get(section, {}), names, what="state",
                                          of=section.removesuffix("s")).items():
                names[name](saved)

    def _expected(self, group: ActionGroup) -> dict[str, Any]:
        """The expectation state of each tuple of ``group`` that has one, by tuple name."""
        states = {tp.name: self.expectations.state(tp, self.now()) for tp in group.tuples}
        return {name: state for name, state in states.items() if state is not None}

    def _restore_expectations(self, saved: Any) -> None:
        """Each tuple's confidence and counts, by group and tuple name, after every tuple
        (learnt ones too) is back."""
        kept = self.unplaced_parts
        for name, tuples in kept.place("expectations", saved, self.spec.expectations.groups, what="expectations",
                                       of="action-group", check=_expectations).items():
            group = {tp.name: tp for tp in self.groups[name].tuples}
            for tuple_name, data in kept.place(f"expectations.{name}", tuples, group, what="expectation", of="tuple",
                                               within=f" in action-group {name!r}", check=check_saved).items():
                self.expectations.restore(group[tuple_name], data, self.now(), f"expectations.{name}.{tuple_name}")

    def _parts_state(self) -> dict[str, dict[str, Any]]:
        """What each part keeps (:meth:`keep`), by section and name, with what is kept for
        names no part of this config has."""
        out: dict[str, dict[str, Any]] = {}
        for (section, name), (state, _) in self._kept.items():
            out.setdefault(section, {})[name] = state()
        sections = {section for section, _ in self._kept} | {s.removeprefix("parts.") for s in self.unplaced_parts.kept
                                                             if s.startswith("parts.")}
        return {section: self.unplaced_parts.carry(f"parts.{section}", out.get(section, {})) for section in sorted(sections)}

    def _restore_shaping(self, state: dict[str, Any]) -> None:
        """Gesture models, then the gestures dispatched from them, again into the body's own
        graph (same base graph, same order: the same new nodes), each left behind in its
        shaping tuple's place; one of a shaping tuple the config no longer has is dispatched
        and kept, not left behind."""
        # every shaping tuple the config wrote, even one a dispatched gesture has replaced: its
        # model still judges the gesture's performances (the 'shaped' percept)
        shaping = {name: tp.action for name, tp in self.tuples.items() if isinstance(tp.action, GestureShaping)}
        for name, data in self.unplaced_parts.place("shaping", state.get("shaping", {}), shaping, what="shaping",
                                                    of="tuple", no="shape_gesture tuple").items():
            shaping[name].restore(data, f"shaping.{name}")
        for k, data in enumerate(state.get("gestures", [])):
            where = f"gestures.{k}"
            name = data.get("shaping") if isinstance(data, dict) else None
            if not isinstance(name, str) or not name or name in self.tuples and name not in shaping:
                raise ValueError(f"{where}.shaping: {name!r} is not a shape_gesture tuple of this creature")
            if self.body is None:
                raise ValueError(f"{where}: a gesture needs a body")
            gesture = redispatch(self.body.own_graph(), data, where)
            if name in shaping:
                shaping[name].dispatched = gesture
                self.leave_behind(name, gesture, restored=True)
            else:  # its tuple renamed or removed (its shaping said so): dispatched all the same, for the
                self.gestures.append((name, gesture))  # nodes of later ones, and kept for the name's return


AURAL_BY_GROUP = ("tuples", "refined")
"""The keys of the aural state that hold what learning did to each action-group, by its name."""


def _value(data: Any, key: str) -> None:
    """A saved value checked as a tuple would take it (:class:`ValueError` naming ``key``): one
    kept for a tuple of another name is refused at load, not carried until the name returns."""
    try:
        value_from_dict(data)
    except ValueError as exc:
        raise ValueError(f"{key}: {exc}") from None


def _value_table(data: Any, key: str) -> None:
    """A saved group's values checked, tuple by tuple (:func:`_value`)."""
    for name, entry in bounds.table(data, key).items():
        _value(entry, f"{key}.{name}")


def _expectations(data: Any, key: str) -> None:
    """A group's saved expectations checked, tuple by tuple (:class:`ValueError` naming the key)."""
    for name, entry in bounds.table(data, key).items():
        check_saved(entry, f"{key}.{name}")


def _adverb_model(data: Any, key: str) -> GaussianModel:
    """An Ac percept's saved model (:class:`ValueError` naming ``key`` when damaged)."""
    try:
        return GaussianModel.from_dict(bounds.table(data, key))
    except ValueError as exc:
        raise ValueError(f"{key}: {exc}") from None


class _Arc:
    """A drive's scripted input rate (``arc``): linear between the points, held outside them,
    0 with none; with ``repeat``, ``t`` counts from the start of the current cycle."""

    def __init__(self, points: list[tuple[float, float]], repeat: float | None) -> None:
        self.script = Scripted(points) if points else None
        self.repeat = repeat

    def __call__(self, t: float) -> float:
        if self.script is None:
            return 0.0
        return self.script(t if self.repeat is None else math.fmod(t, self.repeat))
