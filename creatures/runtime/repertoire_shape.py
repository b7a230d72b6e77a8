"""The shape a merge needs of a saved creature (``creatures state merge``), checked before it reads.

A merge reads two state files without building the creatures (no config at hand), so what a
kind's restore would have refused reached the merge as plain Python: a hand-edited file with
``"phrases": "…"`` or ``"values": []`` ended the command in a traceback, and a damaged target
was written back merged, damage and all. Each check here reads exactly the keys the merge of
its kind reads, with :mod:`creatures.bounds`, whose messages name the key path; the caller adds
the file.
"""

from __future__ import annotations

from typing import Any, Callable

from creatures.bounds import LARGEST_COUNT, count, table, text


def _list(value: Any, what: str, *, shortest: int = 0) -> list[Any]:
    """``value`` as a list of at least ``shortest`` entries (no upper bound of its own here, as
    :func:`creatures.bounds.items` asks: the file's size bound, ``MAX_STATE_BYTES``, is the bound)."""
    if not isinstance(value, list):
        raise ValueError(f"{what}: must be a list, found {type(value).__name__}")
    if len(value) < shortest:
        raise ValueError(f"{what}: must hold at least {shortest} entries, found {len(value)}")
    return value


def _counts(value: Any, what: str, *, shortest: int = 0, below: int = LARGEST_COUNT) -> list[int]:
    return [count(n, f"{what}.{i}", high=below - 1) for i, n in enumerate(_list(value, what, shortest=shortest))]


def authored(state: dict[str, Any]) -> None:
    """An authored creature's phrases, their numbering and values, its aural tree and its
    dispatched gestures: :class:`ValueError` naming the first key that is not as saved."""
    for k, phrase in enumerate(_list(state.get("phrases", []), "phrases")):
        for i, note in enumerate(_list(phrase, f"phrases.{k}")):
            if not isinstance(note, list) or len(note) != 4:
                raise ValueError(f"phrases.{k}.{i}: must be a note [time, pitch, velocity, duration], found "
                                 f"{str(note)[:40]}")
            count(note[1], f"phrases.{k}.{i}.1 (its pitch)", high=127)
    if "phrases_made" in state:
        count(state["phrases_made"], "phrases_made")
    _counts(state.get("learnt", []), "learnt")
    for group, values in table(state.get("values", {}), "values").items():
        table(values, f"values.{group}")
    table(state.get("shaping", {}), "shaping")
    for k, gesture in enumerate(_list(state.get("gestures", []), "gestures")):
        table(gesture, f"gestures.{k}")
        for key in ("shaping", "program", "name"):
            text(gesture.get(key), f"gestures.{k}.{key}")
        _counts(gesture.get("core"), f"gestures.{k}.core", shortest=1)
    if "aural" in state:
        _aural(table(state["aural"], "aural"))


def _aural(aural: dict[str, Any]) -> None:
    tree = table(aural.get("tree"), "aural.tree")
    if "max_children" in tree:
        count(tree["max_children"], "aural.tree.max_children")
    utterances = _list(tree.get("utterances", []), "aural.tree.utterances")
    for i, utterance in enumerate(utterances):
        text(table(utterance, f"aural.tree.utterances.{i}").get("samples"), f"aural.tree.utterances.{i}.samples")
    nodes = [(tree.get("root"), "aural.tree.root")]
    while nodes:  # a stack, not recursion: a hand-made tree may nest deeper than Python recurses
        node, where = nodes.pop()
        table(node, where)
        text(node.get("name"), f"{where}.name")
        if "born" in node:
            count(node["born"], f"{where}.born")
        _counts(node.get("members", []), f"{where}.members", below=len(utterances))
        children = _list(node.get("children"), f"{where}.children")  # every saved node has one
        nodes += [(child, f"{where}.children.{i}") for i, child in enumerate(children)]
    for group, tuples in table(aural.get("tuples", {}), "aural.tuples").items():
        for i, row in enumerate(_list(tuples, f"aural.tuples.{group}")):
            if not isinstance(row, list) or len(row) != 3:
                raise ValueError(f"aural.tuples.{group}.{i}: must be [trigger, action, name], found {str(row)[:40]}")
            for j, part in enumerate(row):
                text(part, f"aural.tuples.{group}.{i}.{j}")


def three_creatures(state: dict[str, Any]) -> None:
    """A three_creatures creature's remembered sounds: a list of tables."""
    for i, sound in enumerate(_list(state.get("memory", []), "memory")):
        table(sound, f"memory.{i}")


SHAPES: dict[str, Callable[[dict[str, Any]], None]] = {"authored": authored, "three_creatures": three_creatures}
"""The check of each kind :data:`creatures.runtime.repertoire.MERGERS` merges."""
