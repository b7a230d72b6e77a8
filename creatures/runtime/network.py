"""A live colony on the network: its creatures speak and listen over OSC (:mod:`midi.osc`).

Each creature speaks under its own name: every note it plays (``/creature/<name>/note``) and,
twice a second (:data:`STATE_EVERY`), a hello saying where the colony listens and its state —
each drive of its motivation and the action it is doing (``/creature/<name>/state``), so a
colony elsewhere can see that ``bo`` is bored and seeking notes. What comes back is heard like
any other input: notes join the note bus under the remote creature's name; state is kept in
:attr:`World.peers <creatures.runtime.world.World.peers>` (``world.peers["bo"]["boredom"]``)
for creatures to read and logged (``peer state``); hellos and byes keep the table of whom to
speak to (``peer``, ``peer left``), so a colony that restarts elsewhere is found again.

A note from a sender that never said hello (``oscsend``, a Max patch speaking the creature
protocol) is outside input, like a keyboard's: creatures with ``hears_input = false`` do not
hear it. Every message outside ``/creature/…`` goes to the colony's input map.
"""

from __future__ import annotations

import dataclasses
import socket
from typing import TYPE_CHECKING, Callable

from creatures.behaviour.action_group import ActionGroup
from creatures.behaviour.motivation import Motivation
from creatures.clock import Clock
from creatures.runtime.input_map import InputRouter
from creatures.runtime.schema import OscSection
from creatures.runtime.world import INPUT
from midi.notes import NoteEvent
from midi.osc import Heard, OscListener, OscSender

if TYPE_CHECKING:
    from creatures.kinds.base import CreatureKind
    from creatures.runtime.world import World

STATE_EVERY = 0.5
"""Seconds between a creature's hello-and-state messages: a bounded rate (2 Hz) whatever the tick."""

Address = tuple[str, int]


def shown_state(creature: "CreatureKind", t: float) -> dict[str, float | str]:
    """What a creature shows other colonies at ``t``: its drives' levels and what it is doing.

    Read from the parts kinds are composed of (a :class:`Motivation` as ``motivation``, an
    :class:`ActionGroup` as ``group``), so every kind shows what it has with no code of its own.
    """
    state: dict[str, float | str] = {}
    motivation = getattr(creature, "motivation", None)
    if isinstance(motivation, Motivation):
        levels = motivation.levels_at(max(t, motivation.time))
        state.update((name, round(float(level), 4)) for name, level in zip(motivation.names, levels))
    group = getattr(creature, "group", None)
    if isinstance(group, ActionGroup):
        state["action"] = "+".join(tp.name for tp in group.active) or "none"
    return state


def _key(address: Address) -> str:
    return f"{address[0]}:{address[1]}"


class Network:
    """The OSC side of a live run: one sender per creature, one listener for the colony."""

    def __init__(self, osc: OscSection, world: "World", clock: Clock, say: Callable[[str], None], *,
                 elsewhere: InputRouter | None = None, epoch: float | None = None) -> None:
        """``elsewhere``: the input map that takes messages outside the creature address space;
        ``epoch``: the Unix time of clock time 0; given, each note goes out time-tagged with
        when it sounds (:meth:`OscSender.note`), else marked "immediately"."""
        self.world = world
        self.elsewhere = elsewhere
        self.epoch = epoch
        self._outside: list[tuple[str, list]] = []  # messages for the input map, taken in at poll
        self.listener = OscListener(clock, host=osc.host, port=osc.port or 0,
                                    elsewhere=None if elsewhere is None else self._take)
        self.configured: set[Address] = set()
        for peer in osc.peers:
            host, _, port = peer.rpartition(":")
            try:
                self.configured.add((socket.gethostbyname(host or "127.0.0.1"), int(port)))
            except (OSError, ValueError) as exc:
                say(f"OSC peer {peer!r} ignored: not a reachable host:port ({exc})")
        self.peers: dict[str, Address] = {_key(a): a for a in self.configured}  # shared by every sender
        self.senders = {c.name: OscSender(c.name, peers=self.peers) for c in world.creatures}
        self.where: dict[str, Address] = {}  # remote creature -> the address its hello gave
        self._next_state = -float("inf")
        world.listeners.append(self._played)

    def _take(self, address: str, args: list, time: float) -> None:
        self._outside.append((address, args))

    def _played(self, creature: str, note: NoteEvent) -> None:
        self.senders[creature].note(note, at=None if self.epoch is None else self.epoch + note.time)

    def publish(self, t: float) -> None:
        """Hello and state from every creature, at most every :data:`STATE_EVERY` seconds."""
        if t < self._next_state:
            return
        self._next_state = t + STATE_EVERY
        for creature in self.world.creatures:
            sender = self.senders[creature.name]
            sender.hello(self.listener.port)
            sender.state(shown_state(creature, t))

    def poll(self, t: float) -> int:
        """Take in what other colonies said; returns how many notes joined the note bus."""
        notes = 0
        said: dict[str, dict[str, int | float | str]] = {}
        for heard in self.listener.poll():
            if heard.creature in self.senders:
                continue  # our own voice, sent back to us by a peer list that names this colony
            if heard.kind == "note":
                known = heard.creature in self.where  # a creature of a colony that said hello
                self.world.inject(dataclasses.replace(heard.note, time=t), heard.creature if known else INPUT,
                                  via=heard.creature)
                notes += 1
            elif heard.kind == "state":
                key, value = heard.args
                self.world.peers.setdefault(heard.creature, {})[key] = value
                said.setdefault(heard.creature, {})[key] = value
            elif heard.kind == "hello":
                self._meet(heard)
            else:
                self._part(heard.creature)
        for creature, state in said.items():
            self.world.emit("peer state", creature=creature, state=state)
        outside, self._outside = self._outside, []
        for address, args in outside:
            notes += self.elsewhere.osc(address, args, t)
        return notes

    def _meet(self, heard: Heard) -> None:
        address = (heard.sender[0], heard.args[0])
        before = self.where.get(heard.creature)
        if before == address:
            return
        self.where[heard.creature] = address
        self.peers[_key(address)] = address
        if before is not None:
            self._forget(before)
        self.world.emit("peer", creature=heard.creature, address=_key(address))

    def _part(self, creature: str) -> None:
        self.world.peers.pop(creature, None)
        address = self.where.pop(creature, None)
        if address is not None:
            self._forget(address)
            self.world.emit("peer left", creature=creature)

    def _forget(self, address: Address) -> None:
        """Stop speaking to ``address`` unless the config names it or another creature is there."""
        if address not in self.configured and address not in self.where.values():
            self.peers.pop(_key(address), None)

    def wait(self, timeout: float) -> None:
        """Sleep up to ``timeout`` seconds, waking at once when a packet arrives."""
        self.listener.wait(timeout)

    def close(self) -> None:
        """Every creature says goodbye; sockets close."""
        for sender in self.senders.values():
            sender.bye()
            sender.close()
        self.listener.close()
