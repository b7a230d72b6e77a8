"""Whom a colony speaks to: the peers the config names, and those learned from hellos.

A hello costs its sender 40 bytes and used to earn it, for ever, every note and twice a
second every creature's hello and state: 154,000 hellos with random names in 10 s made a
colony of 27,193 peers that then sent 20 times what it received (a UDP amplifier, aimable at
other hosts by forging the hello's source address). So what a hello can earn is bounded:

- **Proof first.** A hello from an address the config does not name earns one ``ask``
  (``/creature/<name>/ask token``, from the colony's listening socket), sent only when it is
  no larger than the hello that provoked it, and at most :data:`ASK_RATE` a second: "say
  hello again with this token".
  Only a hello that carries the token (:meth:`PeerTable.token`, keyed by a secret of this
  run) makes a peer, so an address that does not hear us — a forged source — never gets more
  than it sent. The colony asked does this itself: an ``ask`` from a peer it speaks to is kept
  (:attr:`PeerTable.echo`) and goes with its hellos to that peer. (So a colony that is
  reached at another address than the one it sends from must be named in both configs.)
- **Bounded.** At most ``max_peers`` learned creatures (:data:`MAX_PEERS`), admitted at most
  :data:`ADMIT_RATE` a second after a burst of :data:`ADMIT_BURST` (a colony of six
  restarting is met at once); the rest are refused.
- **Forgotten when silent.** A learned creature that says nothing for :data:`PEER_TIMEOUT`
  seconds is forgotten (a colony says hello twice a second).

Refusals are counted (``refused``: ``rate`` — asks and admissions too fast —, ``full``,
``large`` — an ask would have been larger than its hello) for the events log and the
end-of-run summary. Configured addresses are trusted: never asked, and always spoken to
(the names heard from them still count against ``max_peers``).
"""

from __future__ import annotations

import hashlib
import os
from collections import Counter
from typing import Iterable

Address = tuple[str, int]

MAX_PEERS = 64
"""Learned remote creatures kept at once (ten colonies of six, with room)."""

ADMIT_RATE = 2.0
"""New remote creatures admitted per second, after a burst of :data:`ADMIT_BURST`."""

ADMIT_BURST = 16

PEER_TIMEOUT = 30.0
"""Seconds without a hello after which a learned creature is forgotten (60 missed hellos)."""

ASK_RATE = 20.0
"""Asks (answers to hellos from unknown addresses) sent per second at most, in bursts of as many."""


class Bucket:
    """A token bucket: ``rate`` tokens a second, at most ``burst`` held."""

    def __init__(self, rate: float, burst: float) -> None:
        self.rate, self.burst = rate, burst
        self.tokens = float(burst)
        self._filled: float | None = None

    def fill(self, t: float) -> float:
        """The tokens held at ``t`` (seconds; a time before the last one seen refills nothing
        and is not remembered, so out-of-order times cannot refill the bucket twice)."""
        if self._filled is not None:
            self.tokens = min(self.burst, self.tokens + max(0.0, t - self._filled) * self.rate)
        self._filled = t if self._filled is None else max(self._filled, t)
        return self.tokens

    def take(self, t: float) -> bool:
        if self.fill(t) < 1.0:
            return False
        self.tokens -= 1.0
        return True


def key(address: Address) -> str:
    return f"{address[0]}:{address[1]}"


class PeerTable:
    """Learned and configured peers; ``targets`` (``host:port`` → address) is the dict every
    :class:`~midi.osc.OscSender` of the colony sends to, changed in place."""

    def __init__(self, configured: Iterable[Address] = (), *, max_peers: int = MAX_PEERS,
                 admit_rate: float = ADMIT_RATE, admit_burst: int = ADMIT_BURST,
                 timeout: float = PEER_TIMEOUT) -> None:
        self.configured = set(configured)
        self.targets: dict[str, Address] = {key(a): a for a in self.configured}
        self.where: dict[str, Address] = {}  # remote creature -> the address its hello gave
        self.seen: dict[str, float] = {}  # remote creature -> time of its last hello
        self.echo: dict[str, int] = {}  # target -> the token its colony asked us to say hello with
        self.max_peers = max_peers
        self.timeout = timeout
        self.refused: Counter[str] = Counter()  # "full", "rate", "large"
        self.asked = 0
        self._admit = Bucket(admit_rate, admit_burst)
        self._ask = Bucket(ASK_RATE, ASK_RATE)
        self._secret = os.urandom(16)

    def token(self, address: Address) -> int:
        """What a hello from ``address`` must carry to be believed (an OSC int32, ≥ 0)."""
        digest = hashlib.blake2b(key(address).encode(), key=self._secret, digest_size=4).digest()
        return int.from_bytes(digest, "big") & 0x7FFFFFFF

    def hello(self, name: str, address: Address, token: int | None, t: float) -> str:
        """A hello from ``name`` at ``address`` carrying ``token``: :meth:`meet` when the
        address is configured, already ``name``'s, or proved by the token; else ``"ask"``
        (send :meth:`token` there in an ask) or ``"refused"`` (asking too fast)."""
        if address in self.configured or self.where.get(name) == address or token == self.token(address):
            return self.meet(name, address, t)
        if not self._ask.take(t):
            self.refused["rate"] += 1
            return "refused"
        return "ask"

    def was_asked(self, address: Address, token: int) -> None:
        """An ask from the colony at ``address``: our hellos to it carry ``token`` from now on
        (kept only for addresses we speak to, so this table is bounded with theirs)."""
        if key(address) in self.targets:
            self.echo[key(address)] = token

    def meet(self, name: str, address: Address, t: float) -> str:
        """A believed hello from ``name`` at ``address``: ``"known"``, ``"new"``, ``"moved"``
        (a known creature at a new address) or ``"refused"`` (table full, or admitting too fast)."""
        before = self.where.get(name)
        if before is None:
            if len(self.where) >= self.max_peers:
                self.refused["full"] += 1
                return "refused"
            if not self._admit.take(t):
                self.refused["rate"] += 1
                return "refused"
        self.seen[name] = t
        if before == address:
            return "known"
        self.where[name] = address
        self.targets[key(address)] = address
        if before is None:
            return "new"
        self._forget(before)
        return "moved"

    def part(self, name: str) -> bool:
        """``name`` said bye (or fell silent); True if it was known."""
        self.seen.pop(name, None)
        address = self.where.pop(name, None)
        if address is None:
            return False
        self._forget(address)
        return True

    def expire(self, t: float) -> list[str]:
        """Forget every learned creature silent for longer than ``timeout``; their names."""
        silent = [name for name, seen in self.seen.items() if t - seen > self.timeout]
        for name in silent:
            self.part(name)
        return silent

    def _forget(self, address: Address) -> None:
        """Stop speaking to ``address`` unless the config names it or another creature is there."""
        if address not in self.configured and address not in self.where.values():
            self.targets.pop(key(address), None)
            self.echo.pop(key(address), None)
