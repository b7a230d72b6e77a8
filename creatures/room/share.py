"""One room across processes and machines (``[room.share]``): each process owns some creatures,
tells the others where they stand and what they play (:mod:`creatures.room.wire`), and sees
and hears theirs (REACT: one organizer's room; IViHumans: minds that talk over a protocol).

Design:

* **Ownership.** Every process is an *owner* (host name and process id: a restarted process is
  a new owner). A remote creature belongs to the owner that last spoke of it, so a process
  that was killed and started again takes its creatures back at once, before the old owner's
  silence times out. The owner it was taken from does not take it back while the new one
  speaks of it: if it does speak of it again, two live processes claim one name (a config run
  twice), and its rows are dropped, counted (``owner clash``) and said once per name, rather
  than the creature jumping between two places with every datagram. An owner not heard for
  ``timeout`` seconds leaves the room with every creature still its own; a ``bye`` makes it
  leave at once.
* **Time.** Positions and notes are stamped with the sender's clock time as Unix time (the
  machines' clocks kept together by NTP), and with its beat on Ableton Link's timeline when
  ``link = true`` (:mod:`creatures.room.link`), which gives the colony one beat and tempo:
  each shared beat is heard by its pulse. A note from a process with Link is placed by its
  beat's phase on the hearer's timeline (:meth:`RoomShare._on_beat`), the Unix time only
  choosing which beat; positions by Unix time (:meth:`RoomShare._local` says why). A hearer
  places a remote creature where it is *now*: the stamped position moved on by its velocity
  for the stamp's age (dead reckoning), and every sub-step after that
  (:meth:`creatures.room.motion.Crowd.step`). At 25 updates a second the error is what a
  vehicle's force bends its path in 40 ms: millimetres.
* **Notes** travel time-tagged with their start (Unix time and Link beat); the hearer injects
  them at that time from the creature's remote place, so the room's distance law and delay
  apply as for its own.
* **Bounds.** Every datagram is checked and bounded (:mod:`.wire`); at most
  :data:`MOST_OWNERS` owners and :data:`MOST_REMOTE` remote creatures are kept; a remote name
  that is one of this process's own creatures is refused, and so is a datagram stamped more
  than ``timeout`` from now (a clock far off); each refusal is counted by cause.
* **Off the creature's thread.** The socket is non-blocking and read once a tick (a bounded
  number of datagrams); discovery (:mod:`creatures.room.discovery`, mDNS) and Link run on
  their own threads and hand over only a set of addresses and two numbers.
"""

from __future__ import annotations

import os
import socket
from collections import Counter
from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable, Protocol

import numpy as np

from creatures.clock import next_on_grid
from creatures.room import wire
from midi.notes import NoteEvent

if TYPE_CHECKING:
    from creatures.room.spec import ShareSpec

MOST_OWNERS = 64
"""Processes a room keeps track of (a gallery's machines, with room to spare)."""

MOST_REMOTE = 10_000
"""Remote creatures kept, all owners together."""

READS_PER_TICK = 1024
"""Datagrams read in one tick at most (the rest wait in the socket's buffer)."""


class Timeline(Protocol):
    """A shared beat (:class:`creatures.room.link.LinkBeat`)."""

    def beat_at(self, unix: float) -> float: ...

    @property
    def tempo(self) -> float: ...


@dataclass
class Remote:
    """One remote creature: who owns it, its row (x, y, vx, vy, hx, hy, radius) and when (local
    clock time) that row was true."""

    owner: str
    row: np.ndarray
    t: float


class RoomShare:
    """This process's side of a shared room.

    ``epoch`` is the Unix time of clock time 0 (``t``); ``timeline`` a shared beat, or None;
    ``peers`` the addresses discovery has found so far (called each time it is needed).
    """

    def __init__(self, spec: "ShareSpec", own: list[str], epoch: float, *,
                 timeline: Timeline | None = None,
                 peers: Callable[[], set[tuple[str, int]]] = set) -> None:
        self.spec, self.own, self.epoch, self.timeline = spec, set(own), epoch, timeline
        self.discovered = peers
        self.owner = f"{socket.gethostname()[:64]}-{os.getpid()}"
        self.configured = {_address(i, p) for i, p in enumerate(spec.peers)}
        self.socket = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self.socket.bind((spec.host, spec.port))
        except OSError:
            self.socket.close()
            raise
        self.socket.setblocking(False)
        self.port: int = self.socket.getsockname()[1]
        self.remote: dict[str, Remote] = {}
        self.owners: dict[str, float] = {}  # owner -> local time last heard
        self.dropped: Counter[str] = Counter()
        self.received = self.sent = self.send_errors = 0
        self._seq = 0
        self._next_send = -np.inf
        self.joined: list[str] = []  # owners met since last asked (for the events log)
        self.left: list[tuple[str, str]] = []  # (owner, why)
        self.clashes: list[tuple[str, str, str]] = []  # (creature, its owner, the other claimant), once a name
        self._taken_from: dict[str, str] = {}  # creature -> the owner it was last taken from
        self._clashed: set[str] = set()  # creatures whose clash was said

    # -- time ------------------------------------------------------------------------------
    def beat(self, t: float) -> float:
        """Link's shared beat at clock time ``t`` (−1 without Link)."""
        return -1.0 if self.timeline is None else self.timeline.beat_at(self.epoch + t)

    def _local(self, at: float, t: float) -> float:
        """Local clock time of a stamp (``at``, Unix time), or now for a client that cannot say
        when (``at`` ≤ 0).

        Not by Link's beat alone: Link shares tempo and phase, not beat numbers (a peer that
        joins late counts from its own start, 170 beats off in the four-process test), so a
        beat says where in a beat, not which beat (:meth:`_on_beat`); and a timeline jumps
        while sessions merge (one process's beat strayed 23 ms rms from a straight line of Unix
        time as the others joined), so for where a creature was (dead reckoning at 25 updates
        a second) the Unix clocks, kept together by NTP across machines, are the steadier ruler."""
        return at - self.epoch if at > 0 else t

    def _on_beat(self, start: float, beat: float) -> float:
        """Local clock time of a note the sender tagged with Link ``beat``, near ``start`` (its
        Unix stamp, or now): the moment within half a beat of ``start`` at which the local
        timeline is at the same phase (Link keeps the peers' phases together, not their beat
        counts; the issue: notes time-tagged against the shared beat). So two machines whose
        Unix clocks disagree by less than half a beat (250 ms at 120 BPM; NTP keeps them within
        milliseconds) place a note on the same instant of the shared beat; the price is that a
        note sent while Link merges sessions is placed by a timeline still moving."""
        assert self.timeline is not None
        off = (beat - self.timeline.beat_at(self.epoch + start) + 0.5) % 1.0 - 0.5  # beats, in [-0.5, 0.5)
        return start + off * 60.0 / self.timeline.tempo

    # -- out -------------------------------------------------------------------------------
    def targets(self) -> set[tuple[str, int]]:
        here = {(self.spec.host, self.port), ("127.0.0.1", self.port)}
        return (self.configured | self.discovered()) - here

    def _send(self, datagrams: list[bytes]) -> None:
        for address in self.targets():
            for data in datagrams:
                try:
                    self.socket.sendto(data, address)
                    self.sent += 1
                except OSError:  # a peer that is gone must not stop the others hearing us
                    self.send_errors += 1

    def publish(self, t: float, names: list[str], rows: np.ndarray) -> None:
        """Where this process's creatures stand at ``t`` (rows (n, COLUMNS)), at most ``rate`` times a second."""
        if t + 1e-9 < self._next_send:
            return
        self._next_send = next_on_grid(self._next_send, 1.0 / self.spec.rate, t)
        self._seq += 1
        self._send(wire.bodies(self.spec.room, self.owner, self._seq, self.epoch + t, self.beat(t), names, rows))

    def played(self, creature: str, note: NoteEvent) -> None:
        """A note one of this process's creatures plays, to every peer, stamped with its start."""
        if creature in self.own:
            self._send([wire.note(self.spec.room, self.owner, creature, note, self.epoch + note.time,
                                  self.beat(note.time))])

    # -- in --------------------------------------------------------------------------------
    def poll(self, t: float) -> list[tuple[str, NoteEvent]]:
        """Read what arrived; the remote notes (creature, note at local time) to inject."""
        notes = []
        for _ in range(READS_PER_TICK):
            try:
                data = self.socket.recv(wire.MAX_PACKET + 1)
            except (BlockingIOError, InterruptedError):
                break
            except OSError:  # an ICMP error queued on the socket: the next read is fine
                continue
            try:
                heard = wire.decode(data)
            except wire.Refused as refused:
                self.dropped[refused.cause] += 1
                continue
            if heard.room != self.spec.room:
                self.dropped["other room"] += 1
            elif heard.owner == self.owner:
                self.dropped["own"] += 1  # our own voice, sent back by a peer list naming us
            elif self._meet(heard.owner, t):
                self.received += 1
                if (note := self._take(heard, t)) is not None:
                    notes.append(note)
        self._expire(t)
        return notes

    def _meet(self, owner: str, t: float) -> bool:
        if owner not in self.owners:
            if len(self.owners) >= MOST_OWNERS:
                self.dropped["owners full"] += 1
                return False
            self.joined.append(owner)
        self.owners[owner] = t
        return True

    def _take(self, heard: wire.Bodies | wire.Note | wire.Bye, t: float) -> tuple[str, NoteEvent] | None:
        """Take in one message; a note to inject is returned."""
        if isinstance(heard, wire.Bye):
            self._leave(heard.owner, "bye")
            return None
        if isinstance(heard, wire.Note):
            return self._note(heard, t)
        when = self._local(heard.at, t)
        if abs(when - t) > self.spec.timeout:
            # A clock far off (NTP not running there): a stamp long past would leave the room at
            # once unsaid, one far ahead would never time out, so the datagram is dropped, as a
            # note so stamped is.
            self.dropped["time"] += 1
            return None
        for name, row in zip(heard.names, heard.rows):
            if name in self.own:
                self.dropped["name clash"] += 1
            elif name not in self.remote and len(self.remote) >= MOST_REMOTE:
                self.dropped["creatures full"] += 1
            elif not self._claimed(name, heard.owner):
                self.remote[name] = Remote(heard.owner, row, when)
        return None

    def _claimed(self, name: str, owner: str) -> bool:
        """Whether ``name`` is another live owner's, so ``owner``'s row for it is dropped: the
        owner it was last taken from speaks of it again (two processes claim one name). A new
        owner takes it (a restart), and so does anyone once its holder has left or gone silent."""
        held = self.remote.get(name)
        if held is None or held.owner == owner:
            return False
        if self._taken_from.get(name) != owner:
            self._taken_from[name] = held.owner
            return False
        self.dropped["owner clash"] += 1
        if name not in self._clashed:
            self._clashed.add(name)
            self.clashes.append((name, held.owner, owner))
        return True

    def _note(self, heard: wire.Note, t: float) -> tuple[str, NoteEvent] | None:
        if heard.creature in self.own:
            self.dropped["name clash"] += 1
            return None
        if heard.creature not in self.remote:  # heard from nowhere: it must stand in the room first
            self.dropped["unplaced"] += 1
            return None
        start = self._local(heard.at, t)
        if self.timeline is not None and heard.beat >= 0:  # both sides have Link
            start = self._on_beat(start, heard.beat)
        if abs(start - t) > self.spec.timeout:  # a clock far off, or a note long past: never a pile-up
            self.dropped["time"] += 1
            return None
        return heard.creature, NoteEvent(round(start, 6), heard.note.pitch, heard.note.velocity, 0, heard.note.duration)

    def _expire(self, t: float) -> None:
        """Owners not heard for ``timeout`` leave with their creatures; so does each creature
        its owner stopped speaking of (it left that process's config, or its datagram is lost)."""
        for owner, last in list(self.owners.items()):
            if t - last > self.spec.timeout:
                self._leave(owner, "silent")
        if any(t - r.t > self.spec.timeout for r in self.remote.values()):
            self.remote = {name: r for name, r in self.remote.items() if t - r.t <= self.spec.timeout}
            self._forget()

    def _leave(self, owner: str, why: str) -> None:
        self.owners.pop(owner, None)
        self.remote = {name: r for name, r in self.remote.items() if r.owner != owner}
        self._forget()
        self.left.append((owner, why))

    def _forget(self) -> None:
        """Handovers of creatures no longer in the room are forgotten: a name that comes back
        is anyone's to take again."""
        self._taken_from = {name: was for name, was in self._taken_from.items() if name in self.remote}

    def others(self, t: float) -> tuple[list[str], np.ndarray]:
        """Every remote creature's name and row as it stands at ``t`` (moved by its velocity from
        its stamp to ``t``, at most ``timeout`` seconds of it)."""
        names = list(self.remote)
        if not names:
            return names, np.zeros((0, wire.COLUMNS))
        rows = np.array([r.row for r in self.remote.values()])
        # Negative when the stamp is newer than ``t`` (the stage asks at its crowd's time, the
        # start of the sub-steps to come): moved back, so the sub-steps bring it to now.
        age = np.clip(t - np.array([r.t for r in self.remote.values()]), -self.spec.timeout, self.spec.timeout)
        rows[:, :2] += rows[:, 2:4] * age[:, None]
        return names, rows

    # -- accounting ----------------------------------------------------------------------
    def counts(self) -> dict[str, object]:
        """What came in (``received``, ``dropped`` by cause), who is here, what went out."""
        return {"received": self.received, "dropped": dict(self.dropped), "owners": len(self.owners),
                "remote": len(self.remote), "sent": self.sent, "send_errors": self.send_errors,
                "port": self.port, "peers": len(self.targets())}

    def close(self) -> None:
        """Say goodbye (creatures leave the others' rooms at once), then close."""
        self._send([wire.bye(self.spec.room, self.owner)])
        self.socket.close()


class PeerError(ValueError):
    """A configured peer whose host does not resolve; ``index`` is its place in ``peers``."""

    def __init__(self, index: int, message: str) -> None:
        super().__init__(message)
        self.index = index


def _address(index: int, peer: str) -> tuple[str, int]:
    """``host:port`` as an IPv4 address (the config loader checked the form)."""
    host, _, port = peer.rpartition(":")
    try:
        return socket.gethostbyname(host or "127.0.0.1"), int(port)
    except OSError as exc:
        raise PeerError(index, f"peer {peer!r}: {host!r} does not resolve to an IPv4 address ({exc})") from None
