"""``creatures describe CONFIG``: what each creature is made of, as a tree, before a run
(STYLE.md, after py_trees: "trees render as text for debugging").

Every creature is built on a silent world (a simulated clock, no output), so the tree shows
what the runtime would run — class-based kinds as well as authored ones: their action-groups
(nested groups inside), each tuple as ``Tr | Ac | Du | V``, the percept trees its triggers
grow from, and its drives; in a ``[room]``, its vehicle and steering too.
"""

from __future__ import annotations

from typing import Any, Iterable

import numpy as np

from creatures.behaviour.action_group import ActionGroup, GroupAction
from creatures.behaviour.action_tuple import ActionTuple, DoUntil
from creatures.behaviour.motivation import Motivation
from creatures.behaviour.percept import Percept
from creatures.behaviour.value import ChainValue, StanceValue
from creatures.clock import SimulatedClock
from creatures.events import EventLog
from creatures.kinds import KINDS
from creatures.room.spec import AIMED, SteerSpec, VehicleSpec
from creatures.runtime.schema import LoadedInstallation
from creatures.runtime.input_map import InputRouter
from creatures.runtime.world import World
from midi.scheduler import NoteScheduler
from midi.sinks import MemorySink


def _tree(label: str, children: list[Any]) -> list[str]:
    """``label`` then its children, drawn with box characters; a child is a label or (label, children)."""
    lines = [label]
    for k, child in enumerate(children):
        last = k == len(children) - 1
        sub = _tree(*child) if isinstance(child, tuple) else [child]
        lines.append(("└─ " if last else "├─ ") + sub[0])
        lines += [("   " if last else "│  ") + line for line in sub[1:]]
    return lines


def _du(du: DoUntil) -> str:
    inner = getattr(du, "inner", None)
    if isinstance(inner, DoUntil):
        return f"{_du(inner)} ({type(du).__name__})"
    if du.duration is None:
        length = ""
    elif isinstance(du.duration, int | float):
        length = f"{du.duration:g} s"
    else:  # a model: what it samples from (its repr), or its class when it says nothing (a plugin's)
        said = repr(du.duration)
        length = type(du.duration).__name__ if " object at 0x" in said else said
    if length and du.graded:
        length += " graded"
    until = f"until {du.until.name}" if du.until is not None else ""
    return " ".join(x for x in (length, until) if x) or "—"


def _tuple(tp: ActionTuple, actions: dict[str, str]) -> tuple[str, list[Any]] | str:
    """A tuple as ``name: Tr | Ac | Du | V``; an authored action named after its tuple is shown
    by its type (``echo``), which says what it does."""
    value = tp.value
    plastic = "" if getattr(value, "plasticity", 1.0) else ", non-plastic"
    if isinstance(value, ChainValue):  # what it is worth now is its learnt value × the drives its goals serve
        goal = f" = {value.source}" if value.source is not None else ""
        serves = ", ".join(sorted(value.importance)) if value.importance is not None else ""
        plastic += f", chained{goal} (learnt {value.value:.3g}{'; serves ' + serves if serves else ''})"
    if isinstance(value, StanceValue):  # the emotional tag each start pulls the mood toward
        plastic += f", stance {value.stance:+.2g}"
    action = actions.get(tp.action.name, tp.action.name) if tp.action.name == tp.name else tp.action.name
    label = f"{tp.name}: {tp.trigger.name} | {action} | {_du(tp.do_until)} | V {value.to_float():.3g}{plastic}"
    if isinstance(tp.action, GroupAction):
        return _group(tp.action.group, actions, label)
    return label


def _group(group: ActionGroup, actions: dict[str, str], label: str | None = None) -> tuple[str, list[Any]]:
    settings = f"max_active {group.max_active}, alpha {group.alpha:g}, discount {group.discount:g}"
    if group.temperature is not None:
        settings += f", temperature {group.temperature:g}"
    p = group.proximities
    if p.learning:
        settings += f", proximity learnt at {p.rate:g} over {p.window:g} s"
    near = [f"proximity {a} → {b}: {x:g}{' (fixed)' if (a, b) in p.fixed else ''}" for (a, b), x in sorted(p.table.items())]
    return (f"{label or 'group ' + group.name} [{settings}]", [_tuple(tp, actions) for tp in group.tuples] + near)


def _percept(p: Percept, types: dict[str, str]) -> tuple[str, list[Any]] | str:
    """A percept and its children; an authored percept is labelled by the type its config gave."""
    label = f"{p.name} ({types.get(p.name) or type(p).__name__})"
    return (label, [_percept(c, types) for c in p.children]) if p.children else label


def _roots(groups: Iterable[ActionGroup]) -> list[Percept]:
    roots: dict[int, Percept] = {}
    for group in groups:
        for tp in group.tuples:
            node = tp.trigger
            while node.parent is not None:
                node = node.parent
            roots.setdefault(id(node), node)
    return list(roots.values())


def _drives(m: Motivation, spec: Any) -> list[str]:
    """Each drive's level and dynamics; an authored drive's impulses, inputs and coupling too
    (what moves it is most of what it is)."""
    written = getattr(spec, "drives", {})
    lines = []
    for i, name in enumerate(m.names):
        parts = [f"growth {m.growth[i]:g}", f"decay {m.decay[i]:g}"]
        d = written.get(name)
        if d is not None:
            parts += [f"{key} {getattr(d, key):g}" for key in ("on_heard", "on_played") if getattr(d, key)]
            parts += [f"{what} {{{', '.join(f'{k} {v:g}' for k, v in getattr(d, what).items())}}}"
                      for what in ("inputs", "coupling") if getattr(d, what)]
            parts += [f"arc of {len(d.arc)} points"] if d.arc else []
        lines.append(f"{name} = {m.levels[i]:g} ({', '.join(parts)})")
    return lines


def _vehicle(v: VehicleSpec) -> tuple[str, list[str]]:
    """A creature's vehicle (a crowd's clones each with what ``vary`` drew) and its steering in
    priority order: in a room, where it goes is as much of what it does as what it plays."""
    at = f"at [{v.at[0]:g}, {v.at[1]:g}], " if v.at is not None else ""
    label = (f"vehicle [{at}max_speed {v.max_speed:g} m/s, max_force {v.max_force:g} N, mass {v.mass:g} kg, "
             f"radius {v.radius:g} m, max_turn {v.max_turn:g}°/s, {v.combine}, {v.neighbours} neighbours within "
             f"{v.reach:g} m, fov {v.fov:g}°, sight {v.sight:g} m]")
    return label, [_steer(s) for s in v.steer]


def _steer(s: SteerSpec) -> str:
    """One steering behaviour with what it aims at (an aimed one written without a target: the
    visitor), its keys, weight and gate."""
    params = ({"target": "visitor"} if s.behaviour in AIMED else {}) | s.params()
    keys = [f"{k} {_said(v)}" for k, v in params.items()] + [f"weight {s.weight:g}"]
    keys += [f"probability {s.probability:g}"] if s.probability < 1 else []
    keys += [f"when {s.when}"] if s.when else []
    return f"{s.behaviour} ({', '.join(keys)})"


def _said(value: Any) -> str:
    """A steering parameter as written: a number without trailing zeros, a point as [x, y]."""
    if isinstance(value, tuple):
        return f"[{value[0]:g}, {value[1]:g}]"
    return f"{value:g}" if isinstance(value, float) else str(value)


def _actions(spec: Any) -> dict[str, str]:
    """An authored creature's tuples' action types by tuple name (a name alone is its own type)."""
    return {name: tp.action if isinstance(tp.action, str) else tp.action.type
            for name, tp in getattr(spec, "tuples", {}).items()}


def describe(inst: LoadedInstallation) -> str:
    """The tree of every creature of ``inst``."""
    clock = SimulatedClock()
    world = World(clock, EventLog(), NoteScheduler(MemorySink(), clock))
    InputRouter(inst.routes, world, lambda message: None)  # the [[input]] maps' sensors, which percepts read
    seeds = np.random.SeedSequence(inst.settings.seed).spawn(len(inst.specs))
    out = [inst.settings.title]
    for spec, seed in zip(inst.specs, seeds):
        creature = KINDS[spec.kind](spec, world, np.random.default_rng(seed))
        world.add(creature)
        parts = vars(creature)
        groups = [g for g in parts.values() if isinstance(g, ActionGroup)]
        groups += [g for d in parts.values() if isinstance(d, dict) for g in d.values() if isinstance(g, ActionGroup)]
        nested = {id(tp.action.group) for g in groups for tp in g.tuples if isinstance(tp.action, GroupAction)}
        top = list({id(g): g for g in groups if id(g) not in nested}.values())
        children: list[Any] = []
        motivations = [m for m in parts.values() if isinstance(m, Motivation)]
        if motivations:
            children.append(("drives", _drives(motivations[0], spec)))
        types = {name: p.type for name, p in getattr(spec, "percepts", {}).items()}
        roots = [_percept(r, types) for r in _roots(top)]
        children += [("percepts", roots)] if roots else []
        children += [_vehicle(spec.vehicle)] if inst.settings.room is not None else []
        children += [_group(g, _actions(spec)) for g in top] + creature.described()
        out += _tree(f"{spec.name} ({spec.kind})", children)
    return "\n".join(out) + "\n"
