"""A colony over the network: creatures in separate processes exchange notes and state as
OSC over UDP (thesis, "exchange": creatures hear each other "through MIDI, or, more robustly,
though a UDP protocol"; "listen" creatures use the same protocol).

Address space. Every creature speaks under its own name (``[A-Za-z0-9_.-]``, at most 64
characters), so a colony of three sends from three addresses:

``/creature/<name>/hello port:int``
    "I am here; reach me at my sender address on ``port``." Sent on start and twice a second
    after, so a restarted creature is found again without configuration.
``/creature/<name>/note pitch:int velocity:int duration:float [channel:int]``
    A note the creature plays now: pitch 0–127, velocity 1–127, duration in seconds ≥ 0,
    MIDI channel 0–15 (default 0). The hearer stamps it with its own clock.
``/creature/<name>/state key:str value:int|float|str``
    One named quantity of the creature's state, sent for each key twice a second: each drive
    of its motivation by name (``boredom 0.42``, ``hunger 0.1``, ``desire``, ``breath`` …,
    floats) and ``action`` (what it is doing: the names of its active action-tuples joined
    by ``+``, e.g. ``"seek note"``, or ``"none"``). A hearing colony keeps the latest value
    of every key per creature for its own creatures to read (``World.peers``). A creature's
    keys travel together as one OSC bundle (one datagram), so a hearer takes them in as one
    snapshot; single ``state`` messages from any other client are as welcome.
``/creature/<name>/bye``
    The creature is leaving; peers may forget it.

Any OSC client (SuperCollider, Max, Pd, TouchDesigner) can speak or listen. Where this
space takes an int it also takes a float with a whole value (``60.0``: TouchDesigner's and
Max's default number type). Listeners bind 127.0.0.1 unless told otherwise, read a
non-blocking socket that the creature polls (python-osc's threading server dropped burst
messages here, ENVIRONMENT.md), parse with ``pythonosc.osc_packet``, and drop and count
packets that are too large or not OSC. Messages outside ``/creature/…`` go to the listener's
``elsewhere`` (the colony's input map, :mod:`creatures.runtime.input_map`), or are dropped
and counted when it has none.
"""

from __future__ import annotations

import logging
import math
import re
import select
import socket
from dataclasses import dataclass
from typing import Callable

from pythonosc.osc_bundle_builder import IMMEDIATELY, OscBundleBuilder
from pythonosc.osc_message_builder import OscMessageBuilder
from pythonosc.osc_packet import OscPacket

from creatures.clock import Clock
from midi.notes import NoteEvent

logger = logging.getLogger(__name__)

MAX_PACKET = 1024  # bytes; every message of this protocol is far smaller
NAME = re.compile(r"[A-Za-z0-9_.\-]{1,64}")
_ADDRESS = re.compile(r"/creature/([^/]+)/(hello|note|state|bye)")


@dataclass(frozen=True, slots=True)
class Heard:
    """One message from another creature: ``kind`` is hello/note/state/bye; ``note`` is set
    for notes, ``args`` holds the decoded arguments, ``sender`` the UDP source address."""

    creature: str
    kind: str
    time: float
    args: tuple
    sender: tuple[str, int]
    note: NoteEvent | None = None


PREFIX = "/creature/"
"""Addresses under this prefix are the creature address space; the rest is for ``elsewhere``."""


def _whole(x: object) -> object:
    """A float with a whole value as the int it stands for; anything else unchanged."""
    return int(x) if type(x) is float and math.isfinite(x) and x == int(x) else x


def decode(address: str, args: list, time: float, sender: tuple[str, int]) -> Heard:
    """Check one OSC message against the address space; ValueError if it does not fit."""
    match = _ADDRESS.fullmatch(address)
    if match is None or NAME.fullmatch(match[1]) is None:
        raise ValueError(f"address {address!r} is not in the creature address space")
    creature, kind = match[1], match[2]
    if kind in ("hello", "note"):  # pitch, velocity, channel, port: ints, sent as floats by many tools
        args = [_whole(a) if i != 2 or kind == "hello" else a for i, a in enumerate(args)]
    types = tuple(type(a) for a in args)
    note = None
    if kind == "hello":
        if types != (int,) or not 0 < args[0] < 65536:
            raise ValueError(f"{address}: expects one port number, got {args!r}")
    elif kind == "note":
        if types not in ((int, int, float), (int, int, float, int), (int, int, int), (int, int, int, int)):
            raise ValueError(f"{address}: expects pitch velocity duration [channel], got {args!r}")
        if not math.isfinite(args[2]):
            raise ValueError(f"{address}: duration must be finite, got {args[2]!r}")
        note = NoteEvent(time, args[0], args[1], args[3] if len(args) == 4 else 0, float(args[2]))
    elif kind == "state":
        if len(args) != 2 or not isinstance(args[0], str) or not isinstance(args[1], (int, float, str)):
            raise ValueError(f"{address}: expects key value, got {args!r}")
    elif args:
        raise ValueError(f"{address}: expects no arguments, got {args!r}")
    return Heard(creature, kind, time, tuple(args), sender, note)


class OscListener:
    """A non-blocking UDP socket read once a tick; never raises on what arrives."""

    def __init__(
        self,
        clock: Clock,
        *,
        host: str = "127.0.0.1",
        port: int = 0,
        max_packet: int = MAX_PACKET,
        receive_buffer: int = 1 << 20,
        elsewhere: Callable[[str, list, float], object] | None = None,
    ) -> None:
        """``elsewhere(address, args, time)`` takes every message outside ``/creature/…``."""
        self.clock = clock
        self.elsewhere = elsewhere
        self.max_packet = max_packet
        self.socket = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.socket.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, receive_buffer)
        # The kernel may grant less (Linux caps at net.core.rmem_max, often 208 KiB, and reports
        # double what it grants): a burst larger than the buffer between two polls is lost, so say so.
        self.receive_buffer: int = self.socket.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF)
        if self.receive_buffer < receive_buffer:
            logger.warning("OSC receive buffer is %d bytes, not the %d asked for; bursts of more than "
                           "a few hundred messages per tick may drop (raise net.core.rmem_max)",
                           self.receive_buffer, receive_buffer)
        self.socket.bind((host, port))
        self.socket.setblocking(False)
        self.port: int = self.socket.getsockname()[1]
        self.received = 0  # messages accepted
        self.malformed = 0  # packets or messages dropped as not OSC / not this protocol
        self.oversize = 0  # packets dropped for exceeding max_packet

    def wait(self, timeout: float) -> bool:
        """Block up to ``timeout`` seconds for a packet (for loops with nothing else to do)."""
        return bool(select.select([self.socket], [], [], max(0.0, timeout))[0])

    def poll(self, *, limit: int = 10_000) -> list[Heard]:
        """Everything that has arrived, at most ``limit`` packets per call."""
        heard: list[Heard] = []
        now = self.clock.now()
        for _ in range(limit):
            try:
                data, sender = self.socket.recvfrom(self.max_packet + 1)
            except (BlockingIOError, InterruptedError):
                break
            except OSError:  # e.g. an ICMP error queued on the socket; the next read is fine
                continue
            if len(data) > self.max_packet:
                self.oversize += 1
                continue
            try:
                messages = OscPacket(data).messages
            except Exception:  # python-osc raises ParseError, but also struct/index errors
                self.malformed += 1
                continue
            for timed in messages:
                if self.elsewhere is not None and not timed.message.address.startswith(PREFIX):
                    self.elsewhere(timed.message.address, list(timed.message.params), now)
                    continue
                try:
                    heard.append(decode(timed.message.address, list(timed.message.params), now, sender))
                except ValueError:
                    self.malformed += 1
                else:
                    self.received += 1
        return heard

    def close(self) -> None:
        self.socket.close()


class OscSender:
    """Speaks for creature ``name`` to its peers, keyed by peer name.

    ``peers`` may be a table shared by several senders (the creatures of one colony speak to
    the same peers); by default the sender has its own.
    """

    def __init__(self, name: str, *, peers: dict[str, tuple[str, int]] | None = None) -> None:
        if NAME.fullmatch(name) is None:
            raise ValueError(f"creature name {name!r} must match {NAME.pattern}")
        self.name = name
        self.peers: dict[str, tuple[str, int]] = {} if peers is None else peers
        self.send_errors = 0
        self.socket = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)

    def add_peer(self, name: str, address: tuple[str, int]) -> None:
        """Speak to ``address`` as peer ``name`` (a newer hello replaces an older address)."""
        self.peers[name] = address

    def hello(self, port: int) -> None:
        self._send("hello", [port])

    def note(self, note: NoteEvent, *, at: float | None = None) -> None:
        """Say ``note``; with ``at`` (when it sounds, seconds since the Unix epoch) the message
        goes in a bundle time-tagged with that instant, so a receiver that schedules (e.g.
        SuperCollider) plays it when it sounds here rather than when the packet lands."""
        message = self._message("note", [note.pitch, note.velocity, float(note.duration), note.channel])
        if at is None:
            self._deliver(message.dgram)
            return
        bundle = OscBundleBuilder(at)
        bundle.add_content(message)
        self._deliver(bundle.build().dgram)

    def state(self, values: dict[str, int | float | str]) -> None:
        """Every ``key value`` as a ``state`` message, all in one bundle."""
        bundle = OscBundleBuilder(IMMEDIATELY)
        for key, value in values.items():
            bundle.add_content(self._message("state", [key, value]))
        self._deliver(bundle.build().dgram)

    def bye(self) -> None:
        self._send("bye", [])

    def _message(self, kind: str, args: list):
        builder = OscMessageBuilder(f"/creature/{self.name}/{kind}")
        for arg in args:
            builder.add_arg(arg)
        return builder.build()

    def _send(self, kind: str, args: list) -> None:
        self._deliver(self._message(kind, args).dgram)

    def _deliver(self, dgram: bytes) -> None:
        for address in self.peers.values():
            try:
                self.socket.sendto(dgram, address)
            except OSError:  # a peer that is gone must not stop the others hearing us
                self.send_errors += 1

    def close(self) -> None:
        self.socket.close()
