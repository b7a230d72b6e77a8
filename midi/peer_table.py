"""Whom a colony speaks to: the peers the config names, and those learned from hellos.

A hello costs its sender 40 bytes and used to earn it, for ever, every note and twice a
second every creature's hello and state: 154,000 hellos with random names in 10 s made a
colony of 27,193 peers that then sent 20 times what it received (a UDP amplifier, aimable at
other hosts when the colony listens on 0.0.0.0). So what hellos can earn is bounded:

- at most ``max_peers`` learned creatures (:data:`MAX_PEERS`); a hello beyond is refused;
- new creatures are admitted at most :data:`ADMIT_RATE` a second (bursts of
  :data:`ADMIT_BURST`: a colony of six restarting is met at once), the rest refused;
- a learned creature that says nothing for :data:`PEER_TIMEOUT` seconds is forgotten (a
  colony says hello twice a second), so a squatter must keep paying to stay.

What the colony sends is then at most ``max_peers`` times its own traffic, whatever arrives;
refusals are counted (``refused``) for the events log and the end-of-run summary. Configured
peers are never refused nor forgotten.
"""

from __future__ import annotations

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
        self.max_peers = max_peers
        self.admit_rate = admit_rate
        self.admit_burst = admit_burst
        self.timeout = timeout
        self.refused: Counter[str] = Counter()  # "full", "rate"
        self._tokens = float(admit_burst)
        self._filled: float | None = None

    def meet(self, name: str, address: Address, t: float) -> str:
        """A hello from ``name`` at ``address``: ``"known"``, ``"new"``, ``"moved"`` (a known
        creature at a new address) or ``"refused"`` (table full, or admitting too fast)."""
        before = self.where.get(name)
        if before is None:
            if len(self.where) >= self.max_peers:
                self.refused["full"] += 1
                return "refused"
            if not self._admit(t):
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

    def _admit(self, t: float) -> bool:
        if self._filled is not None:
            self._tokens = min(self.admit_burst, self._tokens + (t - self._filled) * self.admit_rate)
        self._filled = t
        if self._tokens < 1.0:
            return False
        self._tokens -= 1.0
        return True

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
