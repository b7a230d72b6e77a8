"""State saved by a class-based kind that a shipped authored creature replaced (issue 15: the
shipped pieces are authored creatures now), taken into the authored creature.

A state folder written before the change holds ``{"kind": "listen", "state": …}``; the
creature the same config builds now is ``kind = "authored"``. Each retired kind names how its
state maps onto the authored parts that took over its work, found by part *type* (not by
the name the shipped document gives them): what it learnt is kept, and nothing is guessed —
a creature that lacks the part to take something is refused with a message saying what to do,
never half-restored.
"""

from __future__ import annotations

import itertools
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable

from creatures.persist import StateFileError, atomic_write

if TYPE_CHECKING:
    from creatures.authored.creature import Authored

Migration = Callable[[dict[str, Any], "Authored"], dict[str, Any]]

RETIRED: dict[str, Migration] = {}
"""Retired kind → its saved state, as the authored creature's (raises ValueError saying why not)."""


def retired(kind: str) -> Callable[[Migration], Migration]:
    def add(migration: Migration) -> Migration:
        RETIRED[kind] = migration
        return migration

    return add


def _part(creature: "Authored", type_: str, kind: str) -> str:
    """The name of the creature's one percept of ``type_`` (what takes the retired kind's state)."""
    names = [name for name, p in creature.spec.percepts.items() if p.type == type_]
    if len(names) != 1:
        raise ValueError(f"it was saved by the class-based {kind!r}, whose learning an authored creature keeps in one "
                         f"{type_!r} percept; this creature has {len(names) or 'no'} {type_!r} percepts")
    return names[0]


def from_retired(path: Path, saved_kind: object, state: dict[str, Any], creature: Any) -> dict[str, Any]:
    """``state`` (saved for ``saved_kind``) as ``creature``'s own, or :class:`StateFileError`
    naming the file and what to do."""
    if not isinstance(saved_kind, str) or saved_kind not in RETIRED or getattr(creature.spec, "kind", None) != "authored":
        raise StateFileError(f"{path}: saved for kind {saved_kind!r}, config says {creature.spec.kind!r}")
    try:
        return RETIRED[saved_kind](state, creature)
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise StateFileError(f"{path}: cannot take this state into {creature.name!r} ({exc}); move {path.name} out "
                             f"of the state folder to start {creature.name!r} afresh, or run the config it was "
                             f"saved with") from None


def keep_original(path: Path, saved_kind: str) -> Path:
    """Copy the state file ``path``, saved by the retired ``saved_kind``, to
    ``NAME.json.KIND`` beside it (atomically, never over another original) and return where.

    The run that took it in saves the creature as authored over ``path``: without the copy,
    the class-based original was gone after the first save, and with it the way back to the
    release that wrote it. The copy's name does not end in ``.json``, so no creature takes it."""
    raw = path.read_bytes()
    names = (path.with_name(f"{path.name}.{saved_kind}" + (f".{n}" if n else "")) for n in itertools.count())
    # The first free name, or the copy an earlier run made of this same file (it did not save).
    kept = next(k for k in names if not k.exists() or k.is_file() and k.read_bytes() == raw)
    if not kept.exists():
        atomic_write(kept, lambda handle: handle.write(raw), "wb")
    return kept


def keep_originals(migrated: list[tuple[Path, str]], say: Callable[[str], None]) -> None:
    """Keep each state file a session took in from a retired kind (``Session.migrated``)
    before a run saves over it, saying where; a copy that cannot be written is an
    :class:`OSError`, and the run is refused rather than the original lost."""
    for path, saved_kind in migrated:
        kept = keep_original(path, saved_kind)
        say(f"{path}: saved by the class-based {saved_kind!r} and taken into its authored creature; "
            f"the original is kept as {kept.name}")


@retired("listen")
def _listen(state: dict[str, Any], creature: "Authored") -> dict[str, Any]:
    """The class's drives, poses, model population and expected match go to the drives and
    the ``population`` percept. Its values are left behind: the class ignored them on reload
    too (they were authored, and a state saved while credit assignment still decayed them
    must not bring the decay back)."""
    heard = _part(creature, "population", "listen")
    return {"motivation": state.get("motivation"),
            "parts": {"percepts": {heard: {k: state[k] for k in ("poses", "population", "expected match") if k in state}}}}


def _tuple(creature: "Authored", action: str, kind: str) -> str:
    """The name of the creature's one tuple whose action is ``action``."""
    def type_of(tp) -> str:
        return tp.action if isinstance(tp.action, str) else tp.action.type

    names = [name for name, tp in creature.spec.tuples.items() if type_of(tp) == action]
    if len(names) != 1:
        raise ValueError(f"it was saved by the class-based {kind!r}, whose song an authored creature sings with one "
                         f"{action!r} tuple; this creature has {len(names) or 'no'} {action!r} tuples")
    return names[0]


@retired("sandstone")
def _sandstone(state: dict[str, Any], creature: "Authored") -> dict[str, Any]:
    """The class's values (sing, pause, listen: the same tuples) go to the group that holds
    them, its drives (desire, boredom, breath, pulse) to the same drives, its place in the
    song to the ``sing_phrases`` tuple, its ear to the ``discord`` percept and the last rock
    reading to the ``script`` percept (the class refused a state missing any of them)."""
    for key in ("values", "motivation", "song", "heard", "sensed"):
        if key not in state:
            raise ValueError(f"the class-based sandstone state is missing {key!r}")
    song = _tuple(creature, "sing_phrases", "sandstone")
    group = next(name for name, g in creature.spec.groups.items() if song in g.tuples)
    return {"values": {group: state["values"]}, "motivation": state["motivation"],
            "parts": {"tuples": {song: state["song"]},
                      "percepts": {_part(creature, "discord", "sandstone"): state["heard"],
                                   _part(creature, "script", "sandstone"): state["sensed"]}}}
