"""What a creature learned, between two saved states: diff, roll back, merge (``creatures state``).

A state folder (or one of its snapshots, creatures/runtime/snapshots.py) holds one JSON file per
creature. Reading two of them side by side answers the questions of a long show: what did the
heron learn this week (:func:`diff`), take it back to Monday (:func:`rollback`), give the
heron of one installation the phrases the heron of another learned (:func:`merge`).

A diff reports the *repertoire*, what the thesis calls the creature's learned material
("Learning", "Percept trees"): percepts grown, tuples and their values, phrases heard and kept,
motor material. Drive levels (``motivation``) are what the creature feels now, not what it
learned, and counters of time and numbering are bookkeeping: both are left out, so two
snapshots of a creature that learned nothing differ by nothing.
"""

from __future__ import annotations

import json
import re
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from creatures.bounds import table
from creatures.config import nearest
from creatures.lock import FolderLock
from creatures.persist import StateFileError, atomic_write, json_text, load_json
from creatures.state_set import files, settle
from creatures.runtime import snapshots
from creatures.runtime.repertoire_shape import SHAPES
from creatures.runtime.session import COLONY_FILE, RESTORE_ERRORS, STATE_KIND

SKIPPED = frozenset({"motivation", "time", "born", "next_id", "phrases_made", "learnt", "grown", "untested"})
"""Keys a diff leaves out: drive levels and bookkeeping (``learnt`` is the phrase numbers that
have tuples: each shows as its tuple's value appearing; ``grown`` counts percepts made, each
shows as its percept; ``untested`` is how long an expectation went untested, which every
save finds longer)."""

LABELS = {"values": "value", "phrases": "phrase", "tree": "percept", "tuples": "tuple", "poses": "motor material",
          "population": "phrase model", "memory": "sound", "expected match": "expectation",
          "gestures": "motor material", "shaping": "gesture model", "aural": "aural percept tree",
          "learning": "percept learning", "expectations": "expectation"}
"""What each section of a kind's state is, in the words of the thesis."""


@dataclass(frozen=True)
class Change:
    """One difference: ``sign`` is ``+`` (new), ``-`` (gone) or ``~`` (changed)."""

    creature: str
    sign: str
    path: tuple[str, ...]
    old: Any = None
    new: Any = None

    @property
    def what(self) -> str:
        label = LABELS.get(self.path[0], self.path[0]) if self.path else "creature"
        return {"+": "new ", "-": "lost ", "~": "changed "}[self.sign] + label

    def __str__(self) -> str:
        where = ".".join(self.path)
        shown = _short(self.new if self.sign == "+" else self.old) if self.sign != "~" \
            else f"{_short(self.old)} -> {_short(self.new)}"
        return f"{self.creature}: {self.what} {where}: {shown}"


def _short(value: Any, longest: int = 160) -> str:
    text = json.dumps(value, sort_keys=True)
    return text if len(text) <= longest else text[: longest - 1] + "…"


def read_creatures(folder: Path) -> dict[str, dict[str, Any]]:
    """``name -> {"kind", "state"}`` of every creature file in a state folder or snapshot."""
    if not folder.is_dir():
        raise StateFileError(f"{folder}: not a state folder or snapshot")
    found = {}
    for path in files(folder).values():  # as the last whole save left them (creatures.state_set)
        if path.name != COLONY_FILE:
            document = load_json(path, kind=STATE_KIND)
            found[path.stem] = {"kind": document.get("kind"), "state": document.get("state", {})}
    return found


def diff(before: Path, after: Path) -> list[Change]:
    """What each creature learned between two state folders or snapshots."""
    a, b = read_creatures(before), read_creatures(after)
    changes: list[Change] = []
    for name in sorted(set(a) | set(b)):
        if name not in a or name not in b:
            changes.append(Change(name, "+" if name in b else "-", (), new=(b.get(name) or {}).get("kind"),
                                  old=(a.get(name) or {}).get("kind")))
            continue
        _walk(name, a[name]["state"], b[name]["state"], (), changes)
    return changes


def _walk(name: str, a: Any, b: Any, path: tuple[str, ...], out: list[Change]) -> None:
    if isinstance(a, dict) and isinstance(b, dict):
        for key in sorted(set(a) | set(b)):
            if key in SKIPPED:
                continue
            if key not in a:
                out.append(Change(name, "+", path + (key,), new=b[key]))
            elif key not in b:
                out.append(Change(name, "-", path + (key,), old=a[key]))
            else:
                _walk(name, a[key], b[key], path + (key,), out)
    elif _is_collection(a) and _is_collection(b):
        if _keyed(a) and _keyed(b):  # members with ids: compared member by member
            _walk(name, {str(m["id"]): m for m in a}, {str(m["id"]): m for m in b}, path, out)
            return
        # Phrases, utterances, tuples: a collection, whatever order a bounded memory keeps.
        old, new = Counter(map(_key, a)), Counter(map(_key, b))
        for item in (new - old).elements():
            out.append(Change(name, "+", path, new=json.loads(item)))
        for item in (old - new).elements():
            out.append(Change(name, "-", path, old=json.loads(item)))
    elif a != b:
        out.append(Change(name, "~", path, old=a, new=b))


def _is_collection(value: Any) -> bool:
    """A list of tables or lists (a vector of numbers is one value)."""
    return isinstance(value, list) and any(isinstance(v, (list, dict)) for v in value)


def _keyed(items: list[Any]) -> bool:
    return all(isinstance(m, dict) and "id" in m for m in items)


def _key(item: Any) -> str:
    return json.dumps(item, sort_keys=True)


def _creature_file(folder: Path, name: str) -> Path:
    """``folder``'s file of creature ``name``. Only a name the folder keeps a file for is one:
    ``--creature ../other/x`` read (and a merge wrote) a file outside the folder, and the
    colony's own file was taken for a creature's."""
    if not folder.is_dir():
        raise StateFileError(f"{folder}: not a state folder or snapshot")
    saved = files(folder)  # the creatures it keeps a file for (NAME.json), unread
    if f"{name}.json" not in saved or f"{name}.json" == COLONY_FILE:
        names = sorted(Path(file).stem for file in saved if file != COLONY_FILE)
        raise StateFileError(f"{folder}: no saved state for creature {name!r}{nearest(name, names, 'saved')}")
    return saved[f"{name}.json"]


def rollback(state_dir: Path, snapshot: Path, name: str) -> Path:
    """Put creature ``name``'s file from ``snapshot`` back into ``state_dir``, byte for byte,
    atomically; refused while a run holds the state folder (it would overwrite it), into a
    folder that does not exist (a typo made a new folder no run reads, and said it restored),
    and over a file of another kind (a snapshot of another installation: the run would refuse
    it at its next start, and not be restarted)."""
    if not state_dir.is_dir():
        raise StateFileError(f"{state_dir}: no such state folder" + (" (it is a file)" if state_dir.exists() else ""))
    snapshots.refuse_to_change(state_dir, "roll back")
    with FolderLock(state_dir, "state folder"):
        settle(state_dir)  # a save a crash cut short, finished first: rolled forward later, it would undo this
        return _rollback(state_dir, snapshot, name)


def _rollback(state_dir: Path, snapshot: Path, name: str) -> Path:
    source = _creature_file(snapshot, name)
    kind = load_json(source, kind=STATE_KIND).get("kind")  # a damaged snapshot is refused before anything changes
    data = source.read_bytes()
    target = state_dir / source.name
    try:
        now = load_json(target, kind=STATE_KIND).get("kind")
    except StateFileError:  # none, or damaged: what a rollback is for
        now = kind
    if now != kind:
        raise StateFileError(f"{source} holds a creature of kind {kind!r} and {target} one of kind {now!r}: a "
                             f"snapshot of another installation? (nothing changed)")
    atomic_write(target, lambda handle: handle.write(data), "wb")
    return target


def merge(source: Path, name: str, target: Path, into: str) -> list[str]:
    """Add what creature ``name`` of ``source`` learned to creature ``into`` of ``target``
    (same kind), keeping everything ``into`` knew; returns what was added. A snapshot is read
    as a source, never written as a target."""
    snapshots.refuse_to_change(target, "merge into")
    with FolderLock(target, "state folder"):
        settle(target)  # as rollback: the file merged into is the last save's
        return _merge(source, name, target, into)


def _merge(source: Path, name: str, target: Path, into: str) -> list[str]:
    src_path = _creature_file(source, name)
    src = load_json(src_path, kind=STATE_KIND)
    path = _creature_file(target, into)
    dst = load_json(path, kind=STATE_KIND)
    kind = dst.get("kind")
    if src.get("kind") != kind:
        raise StateFileError(f"cannot merge {name!r} ({src.get('kind')}) into {into!r} ({kind}): different kinds")
    if kind not in MERGERS:
        why = UNMERGED.get(kind, "its saved state is not a repertoire this command knows")
        raise StateFileError(f"kind {kind!r} has no repertoire merge: {why} (kinds that merge: "
                             f"{', '.join(sorted(MERGERS))})")
    for document, file in ((src, src_path), (dst, path)):
        try:
            SHAPES[kind](table(document.get("state"), "state"))
        except ValueError as exc:
            raise StateFileError(f"{file}: malformed {kind} state ({exc}); nothing merged") from None
    try:
        state, added = MERGERS[kind](src["state"], dst["state"])
    except RESTORE_ERRORS as exc:  # what the checks above do not reach: said, naming both files
        raise StateFileError(f"cannot merge {src_path} into {path}: malformed {kind} state "
                             f"({type(exc).__name__}: {exc}); nothing merged") from None
    text = json_text({**{k: v for k, v in dst.items() if k not in ("format", "version")}, "state": state},
                     kind=STATE_KIND)  # what else the file keeps (the path its body took) stays
    atomic_write(path, lambda handle: handle.write(text), "w")
    return added


def not_carried(source: Path, name: str) -> list[str]:
    """What a merge of creature ``name`` of ``source`` leaves behind, the target keeping its own:
    an authored creature's parts' own learning (``parts.<section>.<name>``: a model population, a
    percept's memory), which has no phrase or class to graft; the percept trees its
    ``[creature.learning] groups`` grew (``learning.trees.<percept>``, with the tuples tried on
    them), which split the target's own percepts by the source's experience; and its tuples'
    expectation confidences (``expectations.<group>``), which are its own tests of its own tuples."""
    state = _table(load_json(_creature_file(source, name), kind=STATE_KIND).get("state"))  # damaged: the merge said it
    left = [f"parts.{section}.{part}" for section, kept in sorted(_table(state.get("parts")).items())
            if isinstance(kept, dict) for part in sorted(kept)]
    left += [f"learning.trees.{percept}" for percept in sorted(_table(_table(state.get("learning")).get("trees")))]
    return left + [f"expectations.{group}" for group in sorted(_table(state.get("expectations")))]


def _table(value: Any) -> dict[str, Any]:
    """``value`` if it is a table, else an empty one (what a damaged file has of it)."""
    return value if isinstance(value, dict) else {}


def _merge_authored(src: dict[str, Any], dst: dict[str, Any]) -> tuple[dict[str, Any], list[str]]:
    """An authored creature's heard phrases, each with its tuple's learned value: the source's
    phrases the target lacks are appended under new numbers (``phrase N`` tuples renumbered);
    the target's ``max_phrases`` keeps the newest when it restores. Its sound classes are
    grafted onto the target's aural tree (:func:`_merge_aural`)."""
    merged = json.loads(json.dumps(dst))
    phrases, made = merged.setdefault("phrases", []), int(merged.get("phrases_made", len(merged.get("phrases", []))))
    learnt, values = merged.setdefault("learnt", []), merged.setdefault("values", {})
    first = int(src.get("phrases_made", len(src.get("phrases", [])))) - len(src.get("phrases", [])) + 1
    added = []
    for offset, phrase in enumerate(src.get("phrases", [])):
        if phrase in phrases:
            continue
        made += 1
        phrases.append(phrase)
        number = first + offset
        if number in src.get("learnt", []):
            learnt.append(made)
            for group, tuples in src.get("values", {}).items():
                if f"phrase {number}" in tuples:
                    values.setdefault(group, {})[f"phrase {made}"] = tuples[f"phrase {number}"]
        added.append(f"phrase {made} (was phrase {number}: pitches {' '.join(str(n[1]) for n in phrase)})")
    merged["phrases_made"] = made
    if "aural" in src:
        if "aural" not in merged:
            raise StateFileError("the source creature hears sounds (an aural percept tree) and the target does "
                                 "not: give the target a [creature.hearing] and an 'utterance' percept first")
        added += _merge_aural(src["aural"], merged["aural"], src.get("values", {}), values)
    added += _merge_gestures(src, merged)
    return merged, added


def _merge_gestures(src: dict[str, Any], dst: dict[str, Any]) -> list[str]:
    """The source's motor material: each gesture its complex shaping dispatched into the body's
    graph (thesis "learning to chase your tail – part 2") whose shape_gesture tuple the target
    has and has not dispatched itself is appended after the target's own. The target dispatches
    it again on restore, after its own, so its new nodes come later by the nodes the target's
    gestures added: its program is renumbered by that (the base graph's size cancels). A gesture
    learnt over another gesture's nodes, or from a body whose base graph differs from the
    target's, is not carried (said, or refused); a restore still checks every program against
    the nodes it dispatches. Changes ``dst`` in place; returns what was added."""
    theirs, ours = src.get("gestures", []), list(dst.get("gestures", []))
    if not theirs:
        return []
    base = {who: min(_program_nodes(g[0]["program"])) for who, g in (("source", theirs), ("target", ours)) if g}
    if len(set(base.values())) > 1:
        raise StateFileError(f"cannot merge motor material: the source's body graph had {base['source']} nodes "
                             f"before its gestures and the target's {base['target']} (different bodies)")
    done, shaping = {g["shaping"] for g in ours}, set(dst.get("shaping", {}))
    added, offset = [], sum(len(g["core"]) for g in ours)
    for gesture in theirs:
        name, count = gesture["shaping"], len(gesture["core"])
        if name not in shaping:
            added.append(f"not added: gesture {gesture['name']} (the target has no shape_gesture tuple {name!r})")
        elif name in done:
            added.append(f"not added: gesture {gesture['name']} (the target dispatched its own from {name!r})")
        elif max(gesture["core"]) >= base["source"]:
            added.append(f"not added: gesture {gesture['name']} (learnt over another gesture's nodes)")
        else:
            shift = offset - (min(_program_nodes(gesture["program"])) - base["source"])
            program = re.sub(r"getTo (\d+)", lambda m: f"getTo {int(m.group(1)) + shift}", gesture["program"])
            ours.append({**gesture, "program": program})
            done.add(name)
            offset += count
            added.append(f"gesture {gesture['name']} ({count} new nodes, from shaping {name!r})")
    if len(ours) > len(dst.get("gestures", [])):
        dst["gestures"] = ours
    return added


def _program_nodes(program: str) -> list[int]:
    """The nodes a dispatched gesture's program goes to (``name: getTo 12; wait; …``)."""
    found = [int(n) for n in re.findall(r"getTo (\d+)", program)]
    if not found:
        raise StateFileError(f"a saved gesture's program goes to no node: {program[:80]!r}")
    return found


def _merge_aural(src: dict[str, Any], dst: dict[str, Any], src_values: dict[str, Any],
                 values: dict[str, Any]) -> list[str]:
    """The source's sound classes grafted onto the target's aural tree (thesis "percept trees",
    "aural Ac percept trees"): each class under the source's root becomes one more class under
    the target's, renumbered as the target's root would have numbered it (its descendants' names
    follow), with its exemplars; the root keeps the exemplars of both; the tuples learning made
    on those classes come too, with their values. The tree's own settings are the target's, and
    a root that would hold more classes than its ``max_children`` keeps its own first.
    Changes ``dst`` and ``values`` in place; returns what was added."""
    tree, theirs = dst["tree"], src["tree"]
    utterances = tree.setdefault("utterances", [])
    index = {u["samples"]: i for i, u in enumerate(utterances)}

    def take(members: list[int]) -> list[int]:
        kept = []
        for i in members:
            u = theirs["utterances"][i]
            if u["samples"] not in index:
                index[u["samples"]] = len(utterances)
                utterances.append(u)
            kept.append(index[u["samples"]])
        return kept

    root, their_root = tree["root"], theirs["root"]
    rename = {their_root["name"]: root["name"]}
    added = []
    for child in their_root.get("children", []):
        if len(root["children"]) >= int(tree.get("max_children", len(root["children"]) + 1)):
            added.append(f"not added: sound class {child['name']} (the root holds its max_children classes)")
            continue
        root["born"] = int(root.get("born", 0)) + 1
        new = f"{root['name']}/{root['born']}"

        def graft(node: dict[str, Any], name: str) -> dict[str, Any]:
            rename[node["name"]] = name
            return {"name": name, "born": node.get("born", 0), "members": take(node.get("members", [])),
                    "children": [graft(c, name + c["name"][len(node["name"]):]) for c in node.get("children", [])]}

        root["children"].append(graft(child, new))
        added.append(f"sound class {new} (was {child['name']}: {len(child.get('members', []))} exemplars)")
    ours = set(root.get("members", []))
    root["members"] = root.get("members", []) + [i for i in take(their_root.get("members", [])) if i not in ours]
    renamed = lambda name: rename.get(name, name)  # noqa: E731 - a trigger outside the tree keeps its name
    for group, tuples in src.get("tuples", {}).items():
        if group not in dst.get("tuples", {}):
            added.append(f"not added: the tuples of group {group!r}, which the target has not")
            continue
        names = {t[2] for t in dst["tuples"][group]} | set(values.get(group, {}))
        for trigger, action, name in tuples:
            if trigger not in rename and not (action.startswith("sing ") and action[5:] in rename):
                continue  # it names no class the merge brought
            trig = renamed(trigger)
            act = "sing " + renamed(action[5:]) if action.startswith("sing ") else action
            made = f"{trig}|{act}" if name == f"{trigger}|{action}" else name
            while made in names:
                made += " (merged)"
            names.add(made)
            dst["tuples"][group].append([trig, act, made])
            if name in src_values.get(group, {}):
                values.setdefault(group, {})[made] = src_values[group][name]
            added.append(f"tuple {made} (was {name})")
    return added


def _merge_memories(src: dict[str, Any], dst: dict[str, Any]) -> tuple[dict[str, Any], list[str]]:
    """A three_creatures creature's remembered sounds (its learned phrases, thesis *three
    creatures*: the sounds it imitates): the source's sounds the target lacks are appended after
    the target's own; its ``memory_size`` keeps the first ones when it restores, so what the
    target knew stays before anything merged."""
    merged = json.loads(json.dumps(dst))
    memory = merged.setdefault("memory", [])
    added = []
    for sound in src.get("memory", []):
        if sound not in memory:
            memory.append(sound)
            added.append(f"sound {len(memory) - 1} (from {sound.get('origin', '?')}, "
                         f"{len(str(sound.get('samples', '')))} characters of samples)")
    return merged, added


MERGERS = {"authored": _merge_authored, "three_creatures": _merge_memories}
"""Kinds whose repertoire can be merged, and how."""

UNMERGED = {
    "curve": "it learns tuple values only (no percepts, phrases or motor material to carry)",
    "duncan": "it learns tuple values and one begging strength only (no phrases or motor material)",
    "sandstone": "its state is the song it is singing now and a running average of what it heard, not "
                 "a repertoire",
    "ozymandias": "its percept tree clusters its own utterances (members, radius, children); two trees "
                  "merge only by clustering again, which a saved-state edit cannot do",
    "listen": "its phrase population and pose models are fitted statistics of its own hearing; adding "
              "another's would need refitting, not a union",
}
"""Kinds with no repertoire merge, and why (said when a merge of one is refused)."""
