"""A live colony on the network: its creatures speak and listen over OSC (:mod:`midi.osc`).

Each creature speaks under its own name: every note it plays (``/creature/<name>/note``) and,
twice a second (:data:`STATE_EVERY`), a hello saying where the colony listens and its state —
each drive of its motivation and the action it is doing (``/creature/<name>/state``), so a
colony elsewhere can see that ``bo`` is bored and seeking notes. What comes back is heard like
any other input: notes join the note bus under the remote creature's name; state is kept in
:attr:`World.peers <creatures.runtime.world.World.peers>` (``world.peers["bo"]["boredom"]``)
for creatures to read and logged (``peer state``); hellos and byes keep the table of whom to
speak to (``peer``, ``peer left``), so a colony that restarts elsewhere is found again. That
table is bounded in size and rate (:mod:`midi.peer_table`: the network is not an amplifier),
and the counters of what was dropped, refused and sent are logged (``network``) and shown at
the end of a run.

A message under one of this colony's own creatures' names is not heard: it is our own voice
sent back (counted ``own voice``) or another colony's creature of the same name (``name
clash``, said once per name: rename one).

A note from a sender that never said hello (``oscsend``, a Max patch speaking the creature
protocol) is outside input, like a keyboard's: creatures with ``hears_input = false`` do not
hear it. Every message outside ``/creature/…`` goes to the colony's input map.
"""

from __future__ import annotations

import dataclasses
import errno
import socket
from pathlib import Path
from typing import TYPE_CHECKING, Callable

from creatures import log_limit
from creatures.behaviour.action_group import ActionGroup
from creatures.behaviour.motivation import Motivation
from creatures.clock import Clock
from creatures.config import ConfigError
from creatures.runtime.input_map import InputRouter
from creatures.runtime.schema import OscSection, host_problem
from creatures.runtime.world import INPUT
from midi.notes import NoteEvent
from midi.osc import Heard, OscListener, OscSender, answer_hello
from midi.peer_table import Address, PeerTable
from midi.peer_table import key as peer_key

if TYPE_CHECKING:
    from creatures.kinds.base import CreatureKind
    from creatures.runtime.world import World

STATE_EVERY = 0.5
"""Seconds between a creature's hello-and-state messages: a bounded rate (2 Hz) whatever the tick."""


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
    action = doing(creature)
    if action is not None:
        state["action"] = action or "none"
    return state


def doing(creature: "CreatureKind") -> str | None:
    """What a creature is doing: the names of the active tuples of its ``group`` joined by
    ``+`` ("" when none is active), or None for a kind without an action-group."""
    group = getattr(creature, "group", None)
    return "+".join(tp.name for tp in group.active) if isinstance(group, ActionGroup) else None


MAX_STATE_KEYS = 32
"""State keys kept per remote creature (a creature shows a handful: its drives and action)."""

COUNTS_EVERY = 10.0
"""Seconds between ``network`` events in the log (when a counter changed): what came in, what
was dropped and why, what was refused, what went out."""


def open_listener(osc: OscSection, clock: Clock, where: Callable[[str, str], ConfigError], *,
                  elsewhere: Callable[[str, list, float], object] | None = None) -> OscListener:
    """The colony's OSC socket, or one clear :class:`ConfigError` naming the key: a host that
    does not resolve or is IPv6 (refused: every socket here is IPv4, and a colony on ::1 that
    peers on 127.0.0.1 would hear nothing), a port in use. ``elsewhere`` takes the messages
    outside the creature address space (:class:`OscListener`)."""
    host = osc.host
    problem = host_problem(host)
    if problem is not None:
        raise where("host", problem)
    try:
        return OscListener(clock, host=host, port=osc.port or 0, max_rate=osc.max_rate, elsewhere=elsewhere)
    except OSError as exc:
        if exc.errno == errno.EADDRINUSE:
            raise where("port", f"OSC port {osc.port} is already in use (another colony or program "
                                "listens there; choose another [osc] port)") from None
        raise where("host", f"cannot listen for OSC on {host}:{osc.port} ({exc.strerror or exc})") from None


class Network:
    """The OSC side of a live run: one sender per creature, one listener for the colony.

    ``where(key, message)`` makes the config error for ``[osc] key`` (file and line); the
    listener is opened before anything runs, so a bad host or busy port stops the run at once.
    ``elsewhere``: the input map that takes messages outside the creature address space;
    ``epoch``: the Unix time of clock time 0; given, each note goes out time-tagged with when it
    sounds (:meth:`OscSender.note`), else marked "immediately".
    """

    def __init__(self, osc: OscSection, world: "World", clock: Clock, say: Callable[[str], None], *,
                 where: Callable[[str, str], ConfigError] | None = None,
                 elsewhere: InputRouter | None = None, epoch: float | None = None) -> None:
        self.world = world
        self.elsewhere = elsewhere
        self.epoch = epoch
        self._outside: list[tuple[str, list]] = []  # messages for the input map, taken in at poll
        self.listener = open_listener(osc, clock, where or (lambda k, m: ConfigError(Path("[osc]"), m, key=k)),
                                      elsewhere=None if elsewhere is None else self._take)
        configured: set[Address] = set()
        for peer in osc.peers:
            host, _, port = peer.rpartition(":")
            try:
                configured.add((socket.gethostbyname(host or "127.0.0.1"), int(port)))
            except (OSError, ValueError) as exc:
                say(f"OSC peer {peer!r} ignored: not a reachable host:port ({exc})")
        self.table = PeerTable(configured, max_peers=osc.max_peers)
        self.peers = self.table.targets  # shared by every sender
        self.senders = {c.name: OscSender(c.name, peers=self.peers) for c in world.creatures}
        self._asker = min(self.senders, key=len)  # the shortest name makes the shortest ask
        self.refused_state = 0  # state values refused: too many remote creatures or keys
        self.say = say
        self.own_voice = 0  # messages under our creatures' names from our own sockets (a peer list naming us)
        self.name_clash = 0  # messages under our creatures' names from another colony: not heard
        self._clashed: set[str] = set()  # our names another colony was found using (said once each)
        self._next_state = -float("inf")
        self._next_counts = 0.0
        self._last_counts: dict[str, object] = {}
        world.listeners.append(self._played)

    def _take(self, address: str, args: list, time: float) -> None:
        self._outside.append((address, args))

    @property
    def where(self) -> dict[str, Address]:
        """Remote creature -> the address its hello gave."""
        return self.table.where

    def _played(self, creature: str, note: NoteEvent) -> None:
        self.senders[creature].note(note, at=None if self.epoch is None else self.epoch + note.time)

    def publish(self, t: float) -> None:
        """Hello and state from every creature, at most every :data:`STATE_EVERY` seconds; the
        counters into the log every :data:`COUNTS_EVERY` seconds when they changed."""
        if t >= self._next_counts:
            self._next_counts = t + COUNTS_EVERY
            self.log_counts()
        if t < self._next_state:
            return
        self._next_state = t + STATE_EVERY
        for name in self.table.expire(t):
            self._left(name, "silent")
        for creature in self.world.creatures:
            sender = self.senders[creature.name]
            sender.hello(self.listener.port, self.table.echo)
            sender.state(shown_state(creature, t))

    def poll(self, t: float) -> int:
        """Take in what other colonies said; returns how many notes joined the note bus."""
        notes = 0
        said: dict[str, dict[str, int | float | str]] = {}
        for heard in self.listener.poll():
            if heard.creature in self.senders:
                self._own_name(heard)
                continue
            if heard.kind == "note":
                known = heard.creature in self.where  # a creature of a colony that said hello
                self.world.inject(dataclasses.replace(heard.note, time=t), heard.creature if known else INPUT,
                                  via=heard.creature)
                notes += 1
            elif heard.kind == "state":
                key, value = heard.args
                if self._keep_state(heard.creature, key, value):
                    said.setdefault(heard.creature, {})[key] = value
            elif heard.kind == "hello":
                self._meet(heard, t)
            elif heard.kind == "ask":
                self.table.was_asked(heard.sender, heard.args[0])
            elif self.table.part(heard.creature):
                self._left(heard.creature, "bye")
            else:
                self.world.peers.pop(heard.creature, None)
        for creature, state in said.items():
            self.world.emit("peer state", creature=creature, state=state)
        outside, self._outside = self._outside, []
        for address, args in outside:
            notes += self.elsewhere.osc(address, args, t)
        return notes

    def _own_name(self, heard: Heard) -> None:
        """A message under one of our creatures' names: our own voice, sent back by a peer list
        that names this colony (it comes from our senders' sockets), or another colony with a
        creature of the same name (two machines running one config), whose every message
        would be taken for our own and not heard: counted, and said once per name, since
        renaming one is the cure."""
        if heard.sender[1] in {s.socket.getsockname()[1] for s in self.senders.values()}:
            self.own_voice += 1
            return
        self.name_clash += 1
        if heard.creature not in self._clashed:
            self._clashed.add(heard.creature)
            where = f"{heard.sender[0]}:{heard.sender[1]}"
            self.world.emit("peer name clash", creature=heard.creature, address=where)
            self.say(f"OSC: a creature named {heard.creature!r} speaks from {where}, another colony: its messages "
                     "are not heard (as this colony's own); give one of them another name")

    def _keep_state(self, creature: str, key: str, value: int | float | str) -> bool:
        """Keep a remote creature's state value unless that would grow ``world.peers`` past
        ``max_peers`` creatures or :data:`MAX_STATE_KEYS` keys (state needs no hello: any OSC
        client may send it, so this table is bounded on its own)."""
        peers = self.world.peers
        known = peers.get(creature)
        if (known is None and len(peers) >= self.table.max_peers) or (
                known is not None and key not in known and len(known) >= MAX_STATE_KEYS):
            self.refused_state += 1
            return False
        peers.setdefault(creature, {})[key] = value
        return True

    def _meet(self, heard: Heard, t: float) -> None:
        if answer_hello(self.table, self.listener, self._asker, heard, t) in ("new", "moved"):
            self.world.emit("peer", creature=heard.creature, address=peer_key(self.table.where[heard.creature]))

    def _left(self, creature: str, why: str) -> None:
        self.world.peers.pop(creature, None)
        self.world.emit("peer left", creature=creature, why=why)

    def counts(self) -> dict[str, object]:
        """Every network counter: what came in (``received``, bytes, ``clamped``, ``dropped``
        by cause, ``own voice`` and ``name clash`` among them: messages under our creatures'
        names, from us or from another colony), whom it asked to prove a hello (``asked``) and refused (``refused``: hellos
        when full or too fast, asks too large, state values),
        how many peers it has, what went out (``sent_bytes``, ``send_errors``), and how many
        library log lines were left out (:mod:`creatures.log_limit`)."""
        refused = dict(self.table.refused)
        if self.refused_state:
            refused["state"] = self.refused_state
        heard = self.listener.counts()
        if self.own_voice or self.name_clash:  # under our own names: not heard, so dropped, not taken
            heard["received"] -= self.own_voice + self.name_clash
            heard["dropped"] = dict(sorted({**heard["dropped"], "own voice": self.own_voice,
                                            "name clash": self.name_clash}.items()))
        return {**heard, "refused": refused, "asked": self.table.asked,
                "peers": len(self.table.where),
                "sent_bytes": self.listener.sent_bytes + sum(s.sent_bytes for s in self.senders.values()),
                "send_errors": self.listener.send_errors + sum(s.send_errors for s in self.senders.values()),
                "log_suppressed": log_limit.suppressed()}

    def log_counts(self) -> None:
        """A ``network`` event with :meth:`counts`, unless nothing changed since the last."""
        counts = self.counts()
        if counts != self._last_counts:
            self._last_counts = counts
            self.world.emit("network", **counts)

    def wait(self, timeout: float) -> None:
        """Sleep up to ``timeout`` seconds, waking at once when a packet arrives."""
        self.listener.wait(timeout)

    def close(self) -> None:
        """Every creature says goodbye; sockets close, the listener first so that the last
        counts logged hold its final drops (:meth:`OscListener.close`)."""
        for sender in self.senders.values():
            sender.bye()
            sender.close()
        self.listener.close()
        self.log_counts()


def describe(counts: dict[str, object]) -> str:
    """:meth:`Network.counts` in one line for the end-of-run summary."""
    dropped = counts["dropped"]
    refused = counts["refused"]
    causes = ", ".join(f"{n} {cause}" for cause, n in dropped.items() if n)
    return (f"OSC {counts['received']} messages between creatures taken ({counts['clamped']} clamped), "
            f"{sum(dropped.values())} dropped{f' ({causes})' if causes else ''}, "
            f"{counts['asked']} asked, {sum(refused.values())} refused, {counts['peers']} peers; "
            f"{counts['received_bytes']} bytes in, {counts['sent_bytes']} out; "
            f"{counts['log_suppressed']} log lines not shown")
