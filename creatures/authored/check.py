"""Load-time resolution of an authored creature: every name it writes must exist, and the
structure must be one that can run (DESIGN.md: "a run never meets an unresolved name").

Checked here, each as a :class:`ConfigError` at the offending key's file and line with the
nearest valid name: unknown action/percept/model types and their keys; a percept, drive or
tuple that is referred to but not declared; a cycle of percept references or of groups; a
tuple in no group (or in two); and a group that assigns credit with nothing grounding its
values (thesis "credit assignment": without a non-plastic value every value only shrinks by
β at each step).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from creatures.authored.registry import ACTIONS, MODELS, PERCEPTS, PluginError, load_parts
from creatures.authored.skills import VOICE_PARAMETERS
from creatures.config import nearest
from creatures.behaviour.action_group import ungrounded_message
from creatures.config import ConfigError, config_error, validate, written_in

if TYPE_CHECKING:
    from creatures.authored.spec import AuthoredSpec

ROOT = "whatever"
"""The root of every percept tree, always declared."""

Where = dict[tuple, tuple[Path, int]]

TYPED = {"utterances": ("utterance", "the aural tree"), "populations": ("population", "a model population"),
         "adverb models": ("adverb_model", "an Ac percept"), "maps": ("maps", "listen's self-organising maps")}
"""``refs`` namespaces that name a percept of one type: namespace → (type, what it is)."""


class _Checker:
    def __init__(self, spec: "AuthoredSpec", file: Path, where: Where, prefix: tuple) -> None:
        self.spec, self.file, self.where, self.prefix = spec, file, where, prefix
        self.notes: list[str] = []  # what may be a mistake but is run (the loader says each at a run's start)
        self.names = {
            "percepts": {ROOT, *spec.percepts},
            "drives": set(spec.drives),
            "tuples": set(spec.tuples),
            "groups": set(spec.groups),
        }

    def error(self, loc: tuple, message: str) -> ConfigError:
        return config_error(self.file, self.where, (*self.prefix, *loc), message)

    def need(self, namespace: str, name: Any, loc: tuple) -> None:
        if name in self.names[namespace]:
            return
        raise self.error(loc, f"no {namespace[:-1]} named {name!r}"
                              f"{nearest(name, sorted(self.names[namespace]), f'{namespace} declared')}")

    def part(self, registry, type_: Any, params: dict[str, Any], loc: tuple):
        cls = registry.get(type_) if isinstance(type_, str) else None
        if cls is None:
            raise self.error((*loc, "type"), registry.unknown(type_))
        return cls, validate(cls.Params, params, self.where, self.file, prefix=(*self.prefix, *loc))

    def references(self, cls, params, loc: tuple) -> list[str]:
        percepts = []
        for key, namespace, name in cls.references(params):
            if namespace in TYPED:  # a percept that must be of one type (the aural tree, a population)
                wanted, what = TYPED[namespace]
                self.need("percepts", name, (*loc, key))
                if self.spec.percepts[name].type != wanted:
                    raise self.error((*loc, key), f"{name!r} is a {self.spec.percepts[name].type!r} percept; "
                                                  f"{cls.name!r} needs {'an' if wanted[0] in 'aeiou' else 'a'} {wanted!r} percept ({what})")
                namespace = "percepts"
            else:
                self.need(namespace, name, (*loc, key))
            if namespace == "percepts":
                percepts.append(name)
        return percepts


"""Reference namespaces that name a percept of one type: namespace → (type, what it is)."""


def check(spec: "AuthoredSpec", file: Path, where: Where, prefix: tuple) -> list[str]:
    """Raise a :class:`ConfigError` for the first name or part that cannot work; return what
    runs but may be a mistake, one sentence each, with its file, line and key."""
    try:
        load_parts()
    except PluginError as exc:
        raise ConfigError(file, str(exc), key=".".join(map(str, (*prefix, "kind")))) from None
    c = _Checker(spec, file, where, prefix)
    for key in ("space", "ratio_metric"):
        if getattr(spec, key) and not spec.body:
            raise c.error((key,), f"'{key}' is for a creature with a body: set 'body = true'")
    _percepts(c)
    _drives(c)
    _tuples(c)
    _score(c)
    _sung_keys(c)
    _mouth(c)
    _modulate(c)
    _groups(c)
    _shaped(c)
    _learning(c)
    _expectations(c)
    _mood(c)
    return c.notes


def _mouth(c: _Checker) -> None:
    """A creature that sings through its body reads joints of that body (the rib cage, the back):
    a body without them is named here, not met as the wrong joints' positions at run time."""
    from creatures.kinds.figures import body_graph
    from creatures.kinds.hearing_parts import BodyFeatures

    if c.spec.hearing is None or not c.spec.body:
        return
    try:
        BodyFeatures.of(body_graph(c.spec.body), c.spec.mouth)
    except ValueError as exc:
        key = str(exc).split(":", 1)[0].split(".")[-1]
        raise c.error(("mouth", key), str(exc).split(": ", 1)[1]) from None


def _shaped(c: _Checker) -> None:
    """A 'shaped' percept judges with a shape_gesture tuple's model."""
    for name, p in c.spec.percepts.items():
        if p.type == "shaped":
            action = c.spec.tuples[p.params()["shaping"]].action
            if getattr(action, "type", action) != "shape_gesture":
                raise c.error(("percepts", name, "shaping"), f"{p.params()['shaping']!r} is not a shape_gesture "
                                                             "tuple: a 'shaped' percept judges with its gesture model")


def _percepts(c: _Checker) -> None:
    trees = [name for name, p in c.spec.percepts.items() if p.type == "utterance"]
    if len(trees) > 1:
        raise c.error(("percepts", trees[1], "type"), f"one 'utterance' percept per creature: it is the root of "
                                                      f"its one aural tree, and {trees[0]!r} is already")
    edges: dict[str, list[str]] = {}
    for name, p in c.spec.percepts.items():
        loc = ("percepts", name)
        if name == ROOT:
            raise c.error(loc, f"{ROOT!r} is the root of every percept tree; give this percept another name")
        cls, params = c.part(PERCEPTS, p.type, p.params(), loc)
        if getattr(params, "seed_model", None) is not None:
            _seed_model(c, p, (*loc, "seed_model"))
        _needs(c, cls, (*loc, "type"))
        _passage(c, cls, params, loc)
        edges[name] = c.references(cls, params, loc)
        c.need("percepts", p.parent, (*loc, "parent"))
        edges[name].append(p.parent)
    _acyclic(c, edges, "percepts", "a percept cannot be defined by itself")
    for k, name in enumerate(c.spec.report_percepts):
        c.need("percepts", name, ("report_percepts", k))


def _seed_model(c: _Checker, percept, loc: tuple) -> None:
    """An aural model named by a percept: relative to the file that wrote the key, loaded now
    (a wrong file is a config error at its key), kept absolute for the build."""
    from creatures.kinds.hearing_parts import resolve_aural_model

    written = written_in(c.where, (*c.prefix, *loc), c.file)
    try:
        percept.model_extra["seed_model"] = resolve_aural_model(percept.model_extra["seed_model"], written.parent)
    except ValueError as exc:
        raise c.error(loc, str(exc)) from None


def _sung_keys(c: _Checker) -> None:
    """A 'discord' percept compares what it hears with the key of what a tuple sings."""
    for name, p in c.spec.percepts.items():
        sung = p.params().get("key_of") if p.type == "discord" else None
        tp = c.spec.tuples.get(sung) if isinstance(sung, str) else None
        action = None if tp is None else tp.action if isinstance(tp.action, str) else tp.action.type
        if tp is not None and action != "sing_phrases":
            raise c.error(("percepts", name, "key_of"), f"tuple {sung!r} sings no song (its action is {action!r}; "
                                                        "'discord' needs a 'sing_phrases' tuple's key)")


def _acyclic(c: _Checker, edges: dict[str, list[str]], section: str, why: str) -> None:
    state: dict[str, int] = {}  # 1 = on the path, 2 = done

    def visit(node: str, path: list[str]) -> None:
        if state.get(node) == 2 or node not in edges:
            return
        if state.get(node) == 1:
            loop = path[path.index(node):] + [node]
            raise c.error((section, node), f"reference cycle {' -> '.join(loop)}: {why}")
        state[node] = 1
        for nxt in edges[node]:
            visit(nxt, [*path, node])
        state[node] = 2

    for node in edges:
        visit(node, [])


def _drives(c: _Checker) -> None:
    for name, d in c.spec.drives.items():
        for other in d.coupling:
            c.need("drives", other, ("drives", name, "coupling", other))
        for percept in d.inputs:
            c.need("percepts", percept, ("drives", name, "inputs", percept))


def _until(c: _Checker, until, loc: tuple) -> None:
    given = [k for k in ("seconds", "gaussian", "pulse", "model") if getattr(until, k) is not None]
    if given == ["gaussian", "pulse"]:
        given = ["pulse"]  # the pulse, with the Gaussian as its fallback until the pulse is trusted
    if not (given or until.percept or until.done):
        raise c.error(loc, "a Do-until needs at least one of seconds, gaussian, pulse, model, percept or done")
    if len(given) > 1:
        raise c.error((*loc, given[1]), f"one duration per Do-until: {given[0]!r} and {given[1]!r} are both given")
    if until.model is not None:
        c.part(MODELS, until.model.type, until.model.params(), (*loc, "model"))
    if until.percept is not None:
        c.need("percepts", until.percept, (*loc, "percept"))
    if until.gaussian is not None and not (until.gaussian[0] > 0 and until.gaussian[1] > 0):
        raise c.error((*loc, "gaussian"), "mean and std must be positive seconds")


def _action(c: _Checker, action, loc: tuple):
    from creatures.authored.spec import PartSpec

    if isinstance(action, str):
        if action not in ACTIONS:
            raise c.error(loc, ACTIONS.unknown(action))
        action = PartSpec(type=action)
    cls, params = c.part(ACTIONS, action.type, action.params(), loc)
    c.references(cls, params, loc)
    _needs(c, cls, loc)
    _passage(c, cls, params, loc)
    labels = getattr(cls, "labels", None)
    if labels is not None:
        _labels(c, labels(params), loc)
    nodes = getattr(cls, "nodes", None)
    if nodes is not None:
        _nodes(c, nodes(params), loc)
    joints = getattr(cls, "joints", None)
    if joints is not None:  # a body of files is built before this check (schema._resolve_body)
        _joints(c, _named_joints(c, cls, joints(params)), loc)
    turns = getattr(cls, "turns", None)
    if turns is not None and c.spec.body:
        _held(c, turns(params), loc)
    voice = getattr(cls, "voice_parameters", None)
    named = voice(params) if voice is not None else []
    _voice_parameters(c, named, loc)
    blend = getattr(params, "blend", None)
    if blend is not None and blend.policy == "budget":
        if named:
            raise c.error(loc, "blend.policy 'budget' shares a joint's budget; voice parameters have none: "
                               "blend them with 'add', 'mean' or 'exclusive'")
        if getattr(c.spec.body, "budget", None) is None:
            raise c.error(loc, "blend.policy 'budget' shares each joint's budget: set [creature.body] budget "
                               "(degrees)")
    return cls


def _named_joints(c: _Checker, cls, joints: list[str]) -> list[str]:
    """The joints a skill names that the body must have and turn: all of them, but an adverb on
    a body of files takes the stick figure's as a manner written for it (``leaves_out_joints``:
    those the body lacks are left out, logged when built; those its material never turns stay
    still, as exchange's bored chest does on the dog), so only the others are checked."""
    if not (getattr(c.spec.body, "custom", False) and getattr(cls, "leaves_out_joints", False)):
        return joints
    from creatures.kinds.figures import figure_graph

    stick = figure_graph("stick").skeleton.names
    return [joint for joint in joints if joint not in stick]


def _joints(c: _Checker, wanted: list[str], loc: tuple) -> None:
    """Each joint a skill names is on the body, and its material turns it: a body never turns
    a joint further than its material does (:class:`~creatures.motor.blend.Limits`), so a layer
    on a joint no frame turns from rest would run and move nothing."""
    from creatures.kinds.figures import body_graph
    from creatures.kinds.layers import source_limits

    if wanted and not c.spec.body:
        raise c.error(loc, f"it moves the joint {wanted[0]!r}: set 'body = true' on the creature")
    if not wanted:
        return
    graph = body_graph(c.spec.body)
    known = graph.skeleton.names
    turned = [name for name, most in zip(known, source_limits(graph).range) if most > 0.0]
    for joint in wanted:
        if joint not in known:
            raise c.error(loc, f"the body has no joint {joint!r}{nearest(joint, known, 'joints')}")
        if joint not in turned:
            raise c.error(loc, f"no frame of the body's material turns the joint {joint!r} from rest, and the body "
                               "never turns a joint further than its material does, so no layer can move it "
                               f"(joints it turns: {', '.join(turned)}); give it a take or a rest_pose that turns it")


HELD_SLACK = 0.5
"""Degrees past a joint's range a layer may ask without a word (a rounded range written by hand)."""


def _held(c: _Checker, turns: dict[str, float], loc: tuple) -> None:
    """A layer asking a joint to turn further than the body's takes do (or asking one they never
    turn: an adverb written for the stick figure, as exchange's bored chest on the dog) runs
    held within the takes' range: said once at load with the joints and their ranges, not
    refused, since the rest of the layer still moves. Joints the body lacks are left out of
    an adverb, and said when it is built (``layer joints missing``)."""
    from creatures.kinds.figures import body_graph
    from creatures.kinds.layers import held_range

    body = c.spec.body
    graph = body_graph(body)
    names = graph.skeleton.names
    held = np.degrees(held_range(graph, body.material().limits if getattr(body, "custom", False) else None))
    past = {j: (asked, float(held[names.index(j)])) for j, asked in turns.items()
            if j in names and asked > held[names.index(j)] + HELD_SLACK}
    if past:
        said = ", ".join(f"{j} {asked:.0f}° ({f'takes: at most {most:.1f}°' if most > 0 else 'the takes never turn it'})"
                         for j, (asked, most) in past.items())
        c.notes.append(str(c.error(loc, f"it turns {said}: a body never turns a joint further than its takes do, "
                                        "so the layer is held there on those joints")))


def _voice_parameters(c: _Checker, named: list[str], loc: tuple) -> None:
    """The voice parameters a skill or ``[creature.modulate]`` moves are ones this creature has."""
    if "voice.cutoff" in named and c.spec.hearing is None and c.spec.voice.bright_hz is None:
        raise c.error(loc, "it moves voice.cutoff, a low-pass: the creature needs one, a mouth's "
                           "([creature.hearing]: it sings through a mouth) or its strings' "
                           "([creature.voice] bright_hz)")
    strings = [n for n in named if n in ("voice.push", "voice.tension", "voice.damping")]
    if strings and c.spec.hearing is not None:
        raise c.error(loc, f"it moves {strings[0]}, a scanned string's: this creature sings through a mouth "
                           "([creature.hearing]), not strings")
    if "voice.push" in named and not c.spec.body:
        raise c.error(loc, "it moves voice.push, how hard the body pushes the strings: set 'body = true'")


def _modulate(c: _Checker) -> None:
    """``[creature.modulate]``: voice parameters this creature has, each by percepts it has."""
    for parameter, weights in c.spec.modulate.items():
        loc = ("modulate", parameter)
        if parameter not in VOICE_PARAMETERS:
            raise c.error(loc, f"no voice parameter {parameter!r}{nearest(parameter, VOICE_PARAMETERS, 'voice parameters')}")
        _voice_parameters(c, [parameter], loc)
        for name in weights:
            c.need("percepts", name, (*loc, name))


def _needs(c: _Checker, cls, loc: tuple) -> None:
    """A part that uses the body or the note space needs the creature to have it."""
    if getattr(cls, "needs", None) in ("body", "space") and not c.spec.body:
        raise c.error(loc, f"{cls.name!r} uses the body: set 'body = true' on the creature")
    if getattr(cls, "needs", None) == "hearing" and c.spec.hearing is None:
        raise c.error(loc, f"{cls.name!r} hears sound: give the creature a [creature.hearing] table")
    if getattr(cls, "needs", None) == "space" and c.spec.space is None:
        raise c.error(loc, f"{cls.name!r} uses notes in space: give the creature a [creature.space] table")
    if getattr(cls, "needs", None) == "score" and c.spec.score is None:
        raise c.error(loc, f"{cls.name!r} steers a score: give the creature a [creature.score] table")


def _passage(c: _Checker, cls, params, loc: tuple) -> None:
    """A heard passage longer than the space remembers heard notes (``space.max_notes``:
    :attr:`NoteWorld.heard`) is never found, so a part waiting for one would never act
    (thesis "exchange (installation)": the variations are of passages heard)."""
    fewest = getattr(cls, "passage_notes", None)
    if fewest is None or c.spec.space is None:
        return
    key, notes = fewest(params)
    if notes > c.spec.space.max_notes:
        raise c.error((*loc, key), f"{cls.name!r} needs a heard passage of {notes} notes, and the space remembers "
                                   f"at most {c.spec.space.max_notes} (space.max_notes): it would never act")


def _score(c: _Checker) -> None:
    """``[creature.score]``: its tile file loads (its own errors name that file), and every
    layer, idle tag, part, percept and steered tag is one the tiles and the creature have."""
    from creatures.score.tiles import load_tiles

    score = c.spec.score
    if score is None:
        return
    written = c.where.get((*c.prefix, "score", "tiles"), c.where.get((*c.prefix, "score"), (c.file, 0)))[0]
    score.tiles = str((Path(written).parent / score.tiles).resolve())
    if not Path(score.tiles).is_file():
        raise c.error(("score", "tiles"), f"tile file not found: {score.tiles}")
    tiles = load_tiles(score.tiles)

    def known(what: str, name: str, choices: list[str], loc: tuple) -> None:
        if name not in choices:
            raise c.error(loc, f"no {what} named {name!r}{nearest(name, choices, 'there are')}")

    for name, layer in score.layers.items():
        known("layer in the tiles", name, tiles.layers, ("score", "layers", name))
        known(f"tag on layer {name!r}'s tiles", layer.idle, tiles.tags(name), ("score", "layers", name, "idle"))
    for name, part in score.parts.items():
        known("part in the tiles", name, tiles.parts, ("score", "parts", name))
        for key in ("stance", "visible", "energy"):
            if getattr(part, key) is not None:
                c.need("percepts", getattr(part, key), ("score", "parts", name, key))
    for name, tp in c.spec.tuples.items():
        if getattr(tp.action, "type", tp.action) != "score":
            continue
        params = ACTIONS.get("score").Params.model_validate(tp.action.params())  # checked by _tuples
        loc = ("tuples", name, "action")
        known("layer in [creature.score]", params.layer, sorted(score.layers), (*loc, "layer"))
        for tag in params.tags():
            known(f"tag on layer {params.layer!r}'s tiles", tag, tiles.tags(params.layer), loc)


def _labels(c: _Checker, wanted: list[str], loc: tuple) -> None:
    from creatures.kinds.figures import body_labels

    known = sorted(body_labels(c.spec.body))
    for label in wanted:
        if label not in known:
            raise c.error(loc, f"the body has no motor label {label!r}{nearest(label, known, 'labels')}")


def _nodes(c: _Checker, wanted: list[int], loc: tuple) -> None:
    """Node indices a motor program names are nodes of the body's graph: one past its end was
    an IndexError on the creature's thread when the statement ran, and -1 went to the last."""
    from creatures.kinds.figures import body_graph

    if not wanted:
        return
    size = len(body_graph(c.spec.body))
    for node in wanted:
        if not 0 <= node < size:
            raise c.error(loc, f"the program names node {node}, and the body's motor graph has nodes 0..{size - 1}")


def _tuples(c: _Checker) -> None:
    for name, tp in c.spec.tuples.items():
        loc = ("tuples", name)
        c.need("percepts", tp.trigger, (*loc, "trigger"))
        cls = _action(c, tp.action, (*loc, "action"))
        _until(c, tp.until, (*loc, "until"))
        if tp.until.done and not cls.ends:
            raise c.error((*loc, "until", "done"), f"action {cls.name!r} has no end of its own: give the Du "
                                                    "seconds, a model or a percept")
        if not isinstance(tp.value, float | int):
            for drive in tp.value.serves.values():
                c.need("drives", drive, (*loc, "value", "serves"))
            for key in ("leak", "momentum"):
                if getattr(tp.value, key) and tp.value.kind != "scalar":
                    raise c.error((*loc, "value", key), f"'{key}' processes a scalar value; this one is "
                                                        f"{tp.value.kind!r} (thesis 'value signal processing')")
            if tp.value.plasticity is not None and not tp.value.plastic:
                raise c.error((*loc, "value", "plasticity"), "'plasticity' is how much a plastic value learns; "
                                                             "this one is plastic = false (it learns nothing): "
                                                             "give one or the other")
            if tp.value.stance is not None and tp.value.kind != "stance":
                raise c.error((*loc, "value", "stance"), f"'stance' is the tag of a stance value; this one is "
                                                         f"{tp.value.kind!r}: set kind = \"stance\"")
        if tp.until.fresh and tp.until.percept is None:
            raise c.error((*loc, "until", "fresh"), "'fresh' is about the until-percept: give the Du a 'percept'")
        for key in ("follow_as", "priming", "record"):
            if key in tp.until.model_fields_set and not tp.until.follow:
                raise c.error((*loc, "until", key), f"'{key}' is about the forward transition model: "
                                                    "set until.follow = true")


def _groups(c: _Checker) -> None:
    owner: dict[str, str] = {}
    edges: dict[str, list[str]] = {}
    for name, g in c.spec.groups.items():
        loc = ("groups", name)
        if name in c.spec.tuples:
            raise c.error(loc, f"{name!r} is both a tuple and a group; a member name must say which")
        edges[name] = []
        for member in g.tuples:
            if member in c.spec.groups:
                edges[name].append(member)
            else:
                c.need("tuples", member, (*loc, "tuples"))
            if member in owner:
                raise c.error((*loc, "tuples"), f"{member!r} is already a member of group {owner[member]!r} "
                                                "(a tuple or group belongs to one group)")
            owner[member] = name
        c.need("percepts", g.trigger, (*loc, "trigger"))
        for drive in g.heat:
            c.need("drives", drive, (*loc, "heat", drive))
        if g.heat and g.temperature is None:
            raise c.error((*loc, "heat"), "heat raises the Boltzmann temperature: give the group a 'temperature'")
        for k, constraint in enumerate(g.constraints):
            for end in ("a", "b"):
                c.need("tuples", getattr(constraint, end), (*loc, "constraints", k, end))
        _proximities(c, name, g)
        if g.succession is not None and not any(m in c.spec.tuples and c.spec.tuples[m].until.follow
                                                for m in g.tuples):
            raise c.error((*loc, "succession"), f"no tuple of group {name!r} has until.follow = true: nothing "
                                                f"would record into or be primed by {g.succession!r}")
    _acyclic(c, edges, "groups", "a group cannot contain itself")
    for name in c.spec.tuples:
        if name not in owner:
            raise c.error(("tuples", name), f"tuple {name!r} is in no group: add it to a group's 'tuples' "
                                            f"(groups: {sorted(c.spec.groups)})")
    for name, g in c.spec.groups.items():
        if g.alpha > 0 and g.discount < 1 and not _grounded(c, g):
            raise c.error(("groups", name, "alpha"), ungrounded_message(name, g.alpha, g.discount) +
                          ". Give a reward tuple 'value = { value = ..., plastic = false }', or set alpha = 0 "
                          "to keep the values as authored")


def _proximities(c: _Checker, name: str, g) -> None:
    """A proximity table names tuples of its own group; a gesture-shaping tuple's guide is in
    its group (the guide's credit must reach it there)."""
    members = sorted(m for m in g.tuples if m in c.spec.tuples)
    loc = ("groups", name, "proximity")

    def member(tuple_: str, where: tuple) -> None:
        if tuple_ not in members:
            raise c.error(where, f"{tuple_!r} is not a tuple of group {name!r}{nearest(tuple_, members, 'its tuples')}")

    for a, row in g.proximity.items():
        member(a, (*loc, a))
        for b in row:
            member(b, (*loc, a, b))
    for m in members:
        action = c.spec.tuples[m].action
        guide = None if isinstance(action, str) else action.params().get("guide")
        if getattr(action, "type", None) != "shape_gesture":
            continue
        if guide not in members:
            raise c.error(("tuples", m, "action", "guide"), f"the guide {guide!r} is not a tuple of {m!r}'s group "
                                                            f"{name!r} (its tuples: {members})")
        gesture = _gesture(m, action)
        if gesture in c.spec.tuples or gesture in c.spec.groups:
            raise c.error(("tuples", m, "action", "gesture"), f"the learnt gesture's tuple would be named {gesture!r}, "
                                                              "which is already a tuple or group: give 'gesture' "
                                                              "another name")
        _dispatchable(c, m, gesture)


def _gesture(tuple_: str, action) -> str | None:
    """The name a shape_gesture tuple's learnt gesture is dispatched under (None: another action)."""
    if getattr(action, "type", None) != "shape_gesture":
        return None
    return action.params().get("gesture") or f"{tuple_} gesture"


def _dispatchable(c: _Checker, tuple_: str, gesture: str) -> None:
    """The gesture becomes new material of the body under its name: a take of the body, or
    another tuple's gesture, by that name would make the dispatch fail after ``dispatch_after``
    lessons, hours into a run, on the creature's thread."""
    from creatures.kinds.figures import body_graph

    loc = ("tuples", tuple_, "action", "gesture")
    twin = next((o for o, tp in c.spec.tuples.items() if o != tuple_ and _gesture(o, tp.action) == gesture), None)
    if twin is not None:
        raise c.error(loc, f"{gesture!r} is {twin!r}'s learnt gesture too: give 'gesture' another name")
    takes = body_graph(c.spec.body).poses.sources
    if gesture in takes:
        raise c.error(loc, f"{gesture!r} is already material of the body (its takes: {', '.join(takes)}): "
                           "give 'gesture' another name")


def _grounded(c: _Checker, group) -> bool:
    """A non-plastic tuple among the group's leaves: credit blends toward the leaf that ran, inside
    a group it holds too (hierarchical groups; the groups were checked acyclic before)."""
    for member in group.tuples:
        if member in c.spec.groups and _grounded(c, c.spec.groups[member]):
            return True
        tp = c.spec.tuples.get(member)
        if tp is not None and not isinstance(tp.value, float | int) and (not tp.value.plastic or tp.value.plasticity == 0):
            return True
    return False


def _once_each(c: _Checker, names: list[str], loc: tuple) -> None:
    """A list of group names names each once: a second was taken without a word, as if it meant something."""
    for k, name in enumerate(names):
        if name in names[:k]:
            raise c.error((*loc, k), f"group {name!r} is named twice (first at {names.index(name)})")


def _learning(c: _Checker) -> None:
    learning = c.spec.learning
    _once_each(c, learning.groups, ("learning", "groups"))
    _once_each(c, learning.aural, ("learning", "aural"))
    for k, group in enumerate(learning.groups):
        c.need("groups", group, ("learning", "groups", k))
        if c.spec.groups[group].alpha == 0:
            # PerceptLearning learns in credit assignment, whose blend rates are alpha × …: at 0 it never
            # runs, and the group's percepts would silently never learn nor grow
            raise c.error(("learning", "groups", k), f"group {group!r} has alpha = 0: it assigns no credit, "
                                                     "so its percepts would never learn nor split; give it an "
                                                     "alpha above 0")
    for k, group in enumerate(learning.aural):
        c.need("groups", group, ("learning", "aural", k))
        if group in learning.groups:
            raise c.error(("learning", "aural", k), f"group {group!r} learns one way: it is in 'groups' as well")
        if not any(c.spec.percepts[p].type == "utterance" for p in c.spec.percepts):
            raise c.error(("learning", "aural", k), "aural learning grows an 'utterance' percept's tree: "
                                                    "declare one")
    for key, what in (("refine", "refines the singing tuples"), ("in_kind", "answers in kind in the tuples")):
        if getattr(learning, key) and not learning.aural:
            raise c.error(("learning", key), f"{key} {what} of aural groups: name them in learning.aural")
    ph = learning.phrases
    if ph is not None:
        loc = ("learning", "phrases")
        c.need("groups", ph.group, (*loc, "group"))
        c.need("percepts", ph.trigger, (*loc, "trigger"))
        cls = ACTIONS.get(ph.action)
        if cls is None:
            raise c.error((*loc, "action"), ACTIONS.unknown(ph.action))
        if ph.until.done and not cls.ends:
            raise c.error((*loc, "until", "done"), f"action {ph.action!r} has no end of its own")
        if "phrase" not in cls.Params.model_fields:
            raise c.error((*loc, "action"), f"action {ph.action!r} has no 'phrase' key to sing a learnt phrase with")
        _until(c, ph.until, (*loc, "until"))


def _expectations(c: _Checker) -> None:
    """Expectation groups exist, and a surprise or confidence percept reads a tuple that
    keeps expectations (else it would read 0 for ever)."""
    groups = c.spec.expectations.groups
    _once_each(c, groups, ("expectations", "groups"))
    for k, group in enumerate(groups):
        c.need("groups", group, ("expectations", "groups", k))
    followed = [m for g in groups for m in c.spec.groups[g].tuples if m in c.spec.tuples and c.spec.tuples[m].until.follow]
    if c.spec.expectations.transitions and not followed:
        raise c.error(("expectations", "transitions"), "'transitions' judges the starts of tuples with until.follow: "
                                                       "none is in the expectation groups")
    owner = {m: name for name, g in c.spec.groups.items() for m in g.tuples}
    for name, p in c.spec.percepts.items():
        if p.type not in ("surprise", "confidence"):
            continue
        tuple_ = p.params().get("tuple")
        if not groups or (tuple_ is not None and owner.get(tuple_) not in groups):
            where = f"tuple {tuple_!r}'s group {owner.get(tuple_)!r}" if tuple_ is not None else "a group"
            raise c.error(("percepts", name, "type"), f"a {p.type!r} percept needs {where} in "
                                                      f"[creature.expectations] groups = [...]")


def _mood(c: _Checker) -> None:
    """Stance values have a mood to perturb, a drive that can reach every stance (thesis
    "emotional tags": a stance −1 under a drive_floor of 0 would be clipped to 0)."""
    mood, spec = c.spec.mood, c.spec
    if mood is not None:
        c.need("drives", mood.drive, ("mood", "drive"))
    for name, tp in spec.tuples.items():
        if isinstance(tp.value, float | int) or tp.value.kind != "stance":
            continue
        loc = ("tuples", name, "value")
        if mood is None:
            raise c.error((*loc, "kind"), "a stance value perturbs the creature's mood when the tuple starts: "
                                          "name the drive that is the mood in [creature.mood] drive = \"…\"")
        stance = tp.value.stance or 0.0
        for key, bound, out in (("drive_floor", spec.drive_floor, "below"), ("drive_ceiling", spec.drive_ceiling, "above")):
            if bound is not None and (stance < bound if out == "below" else stance > bound):
                raise c.error((*loc, "stance"), f"stance {stance:g} is {out} {key} = {bound:g}: the mood drive "
                                                f"{mood.drive!r} could never reach it (set {key} = "
                                                f"{-1 if out == 'below' else 1}, or none)")


__all__ = ["ROOT", "check"]
