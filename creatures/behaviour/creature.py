"""The Creature: one clock, one random generator, its state objects, percept trees,
action-groups and motivation, ticked together and saved together (thesis: "phase one" to
"phase four"; DESIGN.md "State that lasts"; the thesis's footnote on teaching parts of a
character separately and reloading them "needed not only a persistent storage mechanism, but
a way of automatically reconnecting parts into a greater whole").

Persistence splits a creature into what it *learnt* and what it *is*:

- the file stores data only — values, percept models, grown percepts and hypotheses, the
  activation state of every group, state-object histories, motivation levels, the clock
  time and the random generator's state — as JSON, with the arrays in an NPZ beside it;
- the author's code supplies behaviour. :meth:`Creature.load` calls the author's ``build()``
  to make the creature from code (actions, code percepts such as ``FunctionPercept``,
  saliency functions) and then re-binds the saved data onto it *by name*: a saved tuple
  finds its action among the built tuples' actions, its trigger among the built and grown
  percepts. Nothing in a file is ever executed.

Grown parts need no code: a percept that fission made is a :class:`GaussianPercept` rebuilt
from its model, a hypothesis is a tuple whose Ac and Du come from its siblings by name.

Save → load → continue produces exactly the sequence of actions that never saving would
have (same seed), provided the world outside the creature is restored too. A save writes
the NPZ under a fresh name, then the JSON naming it, each atomically; only then is the old
NPZ removed, so a crash at any point leaves the previous pair intact and loadable.
"""

from __future__ import annotations

import os
import secrets
from pathlib import Path
from typing import Any, Callable, Iterable, Iterator

import numpy as np

from creatures.behaviour.action_group import ActionGroup, GroupAction
from creatures.behaviour.action_tuple import ActionTuple, DoUntil
from creatures.behaviour.learning import PerceptLearning
from creatures.behaviour.models.activation import ActivationModel
from creatures.behaviour.models.gaussian import GaussianModel, GaussianPercept
from creatures.behaviour.models.transition import TransitionModel
from creatures.behaviour.motivation import Motivation
from creatures.behaviour.percept import Percept
from creatures.behaviour.state_object import StateObject
from creatures.behaviour.value import reattach, value_from_dict
from creatures.clock import Clock
from creatures.persist import StateFileError, load_json, load_npz, save_json, save_npz

KIND = "creature"
MODEL_KINDS: dict[str, Any] = {
    "gaussian_model": GaussianModel,
    "activation_model": ActivationModel,
    "transition_model": TransitionModel,
}


class Creature:
    """A musical creature's behaviour system.

    ``tick()`` reads the clock once, advances the motivation to that time and ticks every
    action-group in order (so an earlier group, e.g. perception actions, acts first).
    """

    def __init__(
        self,
        name: str,
        *,
        clock: Clock,
        rng: np.random.Generator,
        groups: Iterable[ActionGroup],
        percepts: Iterable[Percept] = (),
        state_objects: Iterable[StateObject] = (),
        motivation: Motivation | None = None,
    ) -> None:
        self.name = name
        self.clock = clock
        self.rng = rng
        self.groups = list(groups)
        self.percepts = list(percepts)  # roots of the percept trees
        self.state_objects = {s.name: s for s in state_objects}
        self.motivation = motivation

    def tick(self) -> float:
        t = self.clock.now()
        if self.motivation is not None:
            self.motivation.advance(t)
        for group in self.groups:
            group.tick(t)
        return t

    def all_groups(self) -> Iterator[ActionGroup]:
        """The top-level groups and every group nested inside them as a group tuple."""
        stack = list(reversed(self.groups))
        while stack:
            group = stack.pop()
            yield group
            stack += [tp.action.group for tp in reversed(group.tuples) if isinstance(tp.action, GroupAction)]

    def group(self, name: str) -> ActionGroup:
        for group in self.all_groups():
            if group.name == name:
                return group
        raise KeyError(f"creature {self.name!r} has no action-group named {name!r}")

    def walk_percepts(self) -> Iterator[Percept]:
        for root in self.percepts:
            yield from root.walk()

    def describe(self) -> str:
        """What the creature is doing and what it believes, as indented text."""
        lines = [f"{self.name} at t={self.clock.now():.3f}"]
        for group in self.groups:
            lines.append(f"  {group!r}")
            lines += [f"    {tp!r}{' *' if tp.active else ''}" for tp in group.tuples]
        lines += ["  " + line for root in self.percepts for line in root.describe().splitlines()]
        return "\n".join(lines)

    # -- saving ---------------------------------------------------------------------------
    def save(self, path: str | os.PathLike) -> None:
        """Write ``path`` (JSON) and an NPZ beside it; all or nothing (see module docs)."""
        path = Path(path)
        arrays: dict[str, np.ndarray] = {}
        document = self._document(arrays)  # fails before anything is written
        npz_name = f"{path.name}.{secrets.token_hex(4)}.npz"
        document["arrays"] = npz_name
        old_npz = _npz_name_of(path)
        save_npz(path.parent / npz_name, arrays)
        try:
            save_json(path, document, kind=KIND)
        except BaseException:
            (path.parent / npz_name).unlink(missing_ok=True)
            raise
        if old_npz is not None and old_npz != npz_name:
            (path.parent / old_npz).unlink(missing_ok=True)

    def _document(self, arrays: dict[str, np.ndarray]) -> dict[str, Any]:
        return {
            "name": self.name,
            "time": self.clock.now(),
            "rng": self.rng.bit_generator.state,
            "state_objects": {n: _state_to_dict(s, arrays) for n, s in self.state_objects.items()},
            "percepts": [_percept_to_dict(root) for root in self.percepts],
            "groups": [_group_to_dict(g, arrays) for g in self.all_groups()],
            "motivation": None if self.motivation is None else self.motivation.to_dict(),
        }

    # -- loading --------------------------------------------------------------------------
    @classmethod
    def load(cls, path: str | os.PathLike, build: Callable[[], "Creature"]) -> "Creature":
        """Build the creature from the author's code, then restore what it learnt from
        ``path``. Raises :class:`StateFileError` naming the file for anything missing,
        malformed or not matching the code.

        A :class:`SimulatedClock` is moved on to the saved time so the run continues
        exactly; a live clock keeps its own time.
        """
        path = Path(path)
        document = load_json(path, kind=KIND)
        npz = document.get("arrays")
        if not isinstance(npz, str) or "/" in npz or "\\" in npz:
            raise StateFileError(f"{path}: key 'arrays' must name the NPZ file beside it")
        arrays = load_npz(path.parent / npz)
        creature = build()
        try:
            creature._restore(document, arrays)
        except (KeyError, TypeError, ValueError, IndexError, AttributeError) as exc:
            raise StateFileError(f"{path}: {_reason(exc)}") from None
        return creature

    def _restore(self, doc: dict[str, Any], arrays: dict[str, np.ndarray]) -> None:
        if doc["name"] != self.name:
            raise ValueError(f"file holds creature {doc['name']!r}, the code built {self.name!r}")
        advance_to = getattr(self.clock, "advance_to", None)
        if advance_to is not None and self.clock.now() < doc["time"]:
            advance_to(doc["time"])
        self.rng.bit_generator.state = doc["rng"]
        for name, data in doc["state_objects"].items():
            _restore_state(_lookup(self.state_objects, name, "state object"), data, arrays)
        for data in doc["percepts"]:
            root = next((p for p in self.percepts if p.name == data["name"]), None)
            if root is None:
                raise ValueError(f"percept tree {data['name']!r} is not built by the code")
            _restore_percept(root, data, self.state_objects)
        percepts = {p.name: p for p in self.walk_percepts()}
        for data in doc["groups"]:
            _restore_group(self.group(data["name"]), data, percepts, arrays)
        if doc["motivation"] is not None:
            if self.motivation is None:
                raise ValueError("file holds a motivation, the code built none")
            _refill(self.motivation, Motivation.from_dict(doc["motivation"]))


# -- helpers: one per kind of part ------------------------------------------------------------
def _reason(exc: Exception) -> str:
    return f"missing key {exc.args[0]!r}" if isinstance(exc, KeyError) else str(exc)


def _npz_name_of(path: Path) -> str | None:
    """The NPZ the current file at ``path`` refers to, if there is a readable one."""
    try:
        name = load_json(path, kind=KIND).get("arrays")
    except StateFileError:
        return None
    return name if isinstance(name, str) else None


def _lookup(table: dict[str, Any], name: str, what: str) -> Any:
    try:
        return table[name]
    except KeyError:
        raise ValueError(f"{what} {name!r} is not built by the code") from None


def _number(x: Any, what: str, *, optional: bool = False) -> float | None:
    """A finite number (or ``None`` where allowed) from a file; anything else is an error."""
    if x is None and optional:
        return None
    if isinstance(x, bool) or not isinstance(x, (int, float)) or not np.isfinite(x):
        raise ValueError(f"{what} must be a finite number (got {x!r})")
    return float(x)


def _flag(x: Any, what: str) -> bool:
    if not isinstance(x, bool):
        raise ValueError(f"{what} must be true or false (got {x!r})")
    return x


def _refill(target: Any, fresh: Any) -> None:
    """Give ``target`` the state of ``fresh`` in place, so everything that shares ``target``
    (tuples looking at one duration model, values looking at one motivation) still does."""
    target.__dict__.update(fresh.__dict__)


def _model_to_dict(model: Any) -> dict[str, Any] | None:
    return model.to_dict() if hasattr(model, "to_dict") else None


def _restore_model(model: Any, data: dict[str, Any] | None) -> None:
    if data is None:
        return
    cls = MODEL_KINDS.get(data.get("kind"))
    if cls is None:
        raise ValueError(f"unknown model kind {data.get('kind')!r}")
    _refill(model, cls.from_dict(data))


def _state_to_dict(state: StateObject, arrays: dict[str, np.ndarray]) -> dict[str, Any]:
    try:
        data = np.asarray(state.data, dtype=float)
    except (TypeError, ValueError):
        raise TypeError(f"state object {state.name!r} holds data that is not numeric; it cannot be saved") from None
    key = f"state/{state.name}"
    arrays[f"{key}/times"] = state.times_array.copy()
    arrays[f"{key}/saliencies"] = state.saliencies_array.copy()
    arrays[f"{key}/data"] = data
    hab = state.habituation
    return {"arrays": key, "stimulus": state._stimulus, "habituation": None if hab is None else [hab.h, hab.z]}


def _restore_state(state: StateObject, data: dict[str, Any], arrays: dict[str, np.ndarray]) -> None:
    key = data["arrays"]
    times, saliencies, values = (arrays[f"{key}/{part}"] for part in ("times", "saliencies", "data"))
    if not len(times) == len(saliencies) == len(values):
        raise ValueError(f"state object {state.name!r}: history arrays differ in length")
    state._start = state._end = 0  # empty the history, keep its inhibitors
    for t, datum, saliency in zip(times, values, saliencies):
        state._append(float(t), datum if np.ndim(datum) else float(datum), float(saliency))
    state._stimulus = float(data["stimulus"])
    if data["habituation"] is not None:
        state.habituation.h, state.habituation.z = data["habituation"]


def _percept_to_dict(percept: Percept) -> dict[str, Any]:
    out: dict[str, Any] = {"name": percept.name, "type": type(percept).__name__}
    if isinstance(percept, GaussianPercept):
        out.update(state=percept.state.name, lookback=percept.lookback, mask_reach=percept.mask_reach,
                   model=percept.model.to_dict())
    out["children"] = [_percept_to_dict(c) for c in percept.children]
    return out


def _restore_percept(percept: Percept, data: dict[str, Any], states: dict[str, StateObject]) -> None:
    if isinstance(percept, GaussianPercept):
        _restore_model(percept.model, data.get("model"))
    existing = {c.name: c for c in percept.children}
    for child_data in data["children"]:
        child = existing.get(child_data["name"])
        if child is None:  # grown by fission: data, not code
            if child_data["type"] != GaussianPercept.__name__:
                raise ValueError(f"percept {child_data['name']!r} is code and is not built by the code")
            child = GaussianPercept(
                child_data["name"],
                _lookup(states, child_data["state"], "state object"),
                GaussianModel.from_dict(child_data["model"]),
                parent=percept,
                lookback=child_data["lookback"],
                mask_reach=child_data.get("mask_reach", 0.0),
            )
        _restore_percept(child, child_data, states)


def _group_to_dict(group: ActionGroup, arrays: dict[str, np.ndarray]) -> dict[str, Any]:
    key = f"group/{group.name}"
    state = group.activation_state()
    arrays[f"{key}/base"] = state.pop("base")
    arrays[f"{key}/trigger_at_last_start"] = state.pop("trigger_at_last_start")
    learning = group.learning
    return {
        "name": group.name,
        "arrays": key,
        **state,
        "grown": learning.grown if isinstance(learning, PerceptLearning) else None,
        "tuples": [_tuple_to_dict(tp) for tp in group.tuples],
    }


def _tuple_to_dict(tuple_: ActionTuple) -> dict[str, Any]:
    du = tuple_.do_until
    return {
        "name": tuple_.name,
        "trigger": tuple_.trigger.name,
        "action": tuple_.action.name,
        "action_state": tuple_.action.to_dict() if hasattr(tuple_.action, "to_dict") else None,
        "value": tuple_.value.to_dict(),
        "active": tuple_.active,
        "started_at": tuple_.started_at,
        "stopped_at": tuple_.stopped_at,
        "trigger_at_start": tuple_.trigger_at_start,
        "do_until": {
            "duration": du.duration if isinstance(du.duration, (int, float)) or du.duration is None else None,
            "model": _model_to_dict(du.model),
            "until": None if du.until is None else du.until.name,
            "learn": du.learn,
            "graded": du.graded,
            "fresh": du.fresh,
            "started_at": du.started_at,
            "planned": du.planned if np.isfinite(du.planned) else None,
            "spans_gap": du.spans_gap,
        },
    }


def _restore_group(
    group: ActionGroup, data: dict[str, Any], percepts: dict[str, Percept], arrays: dict[str, np.ndarray]
) -> None:
    built = {tp.name: tp for tp in group.tuples}
    actions = {tp.action.name: tp.action for tp in group.tuples}
    for tuple_data in data["tuples"]:
        tuple_ = built.get(tuple_data["name"])
        if tuple_ is None:  # a grown hypothesis: its Ac is a sibling's, found by name
            action = _lookup(actions, tuple_data["action"], "action")
            du_data = tuple_data["do_until"]
            model_owner = next((tp for tp in group.tuples if tp.action is action), None)
            duration = du_data["duration"]
            if duration is None and du_data["model"] is not None and model_owner is not None:
                duration = model_owner.do_until.duration
            until = None if du_data["until"] is None else _lookup(percepts, du_data["until"], "percept")
            tuple_ = ActionTuple(
                tuple_data["name"],
                _lookup(percepts, tuple_data["trigger"], "percept"),
                action,
                DoUntil(duration, until=until, learn=du_data["learn"], graded=du_data.get("graded", False),
                        fresh=du_data.get("fresh", False)),
                0.0,
            )
            group.add(tuple_)
        _restore_tuple(tuple_, tuple_data, group)
    key = data["arrays"]
    state = {
        **data,
        "base": arrays[f"{key}/base"],
        "trigger_at_last_start": arrays[f"{key}/trigger_at_last_start"],
    }
    group.restore_activation(state, [d["name"] for d in data["tuples"]])
    if data["grown"] is not None and isinstance(group.learning, PerceptLearning):
        group.learning.grown = int(data["grown"])


def _restore_tuple(tuple_: ActionTuple, data: dict[str, Any], group: ActionGroup) -> None:
    if data["action"] != tuple_.action.name:
        raise ValueError(f"tuple {tuple_.name!r}: saved action {data['action']!r}, built {tuple_.action.name!r}")
    if data["trigger"] != tuple_.trigger.name:
        raise ValueError(f"tuple {tuple_.name!r}: saved trigger {data['trigger']!r}, built {tuple_.trigger.name!r}")
    fresh = reattach(value_from_dict(data["value"]), tuple_.value)  # importance, clock: creature state
    if type(fresh) is type(tuple_.value):
        _refill(tuple_.value, fresh)
    else:
        tuple_.value = fresh
    if data["action_state"] is not None:
        tuple_.action.restore(data["action_state"])
    where = f"tuple {tuple_.name!r}"
    tuple_.active = _flag(data["active"], f"{where}: 'active'")
    tuple_.started_at = _number(data["started_at"], f"{where}: 'started_at'", optional=True)
    tuple_.stopped_at = _number(data["stopped_at"], f"{where}: 'stopped_at'", optional=True)
    tuple_.trigger_at_start = _number(data["trigger_at_start"], f"{where}: 'trigger_at_start'")
    tuple_.context = {"group": group} if tuple_.active else {}
    du, du_data = tuple_.do_until, data["do_until"]
    if du.model is not None:
        _restore_model(du.model, du_data["model"])
    du.started_at = _number(du_data["started_at"], f"{where}: do-until 'started_at'", optional=True)
    planned = _number(du_data["planned"], f"{where}: do-until 'planned'", optional=True)
    du.planned = float("inf") if planned is None else planned
    du.spans_gap = _flag(du_data.get("spans_gap", False), f"{where}: do-until 'spans_gap'")
