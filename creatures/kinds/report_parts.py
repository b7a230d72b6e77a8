"""Writing a creature's inner life to the events log (DESIGN.md "Seeing inside").

Shared by the kinds that report through the same events as *exchange*: ``selection`` /
``interruption`` / ``stop`` / ``credit`` from an :class:`ActionGroup`, and periodic
``values`` and ``motivation`` snapshots, each tagged with the creature's name so the report
can plot creatures side by side.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Callable

if TYPE_CHECKING:
    from creatures.behaviour.action_group import ActionGroup
    from creatures.behaviour.motivation import Motivation
    from creatures.runtime.world import World


def selection_logger(world: "World", creature: str) -> Callable[[dict[str, Any]], None]:
    """An ``on_event`` sink for an :class:`ActionGroup` that logs under ``creature``'s name."""

    def log(event: dict[str, Any]) -> None:
        fields = dict(event)
        kind, t = fields.pop("event"), fields.pop("t")
        fields.pop("group", None)
        world.log.emit(t, kind, creature=creature, **fields)

    return log


def report_values(world: "World", t: float, creature: str, group: "ActionGroup",
                  motivation: "Motivation | None" = None) -> None:
    """One ``values`` (and ``motivation``) snapshot of ``group``'s tuples at time ``t``."""
    world.log.emit(t, "values", creature=creature, values={tp.name: tp.value.to_float() for tp in group.tuples})
    if motivation is not None:
        world.log.emit(t, "motivation", creature=creature,
                       drives=dict(zip(motivation.names, motivation.levels_at(t).tolist())))
