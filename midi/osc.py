"""A colony over the network: creatures in separate processes exchange notes and state as
OSC over UDP (thesis, "exchange": creatures hear each other "through MIDI, or, more robustly,
though a UDP protocol"; "listen" creatures use the same protocol).

Address space. Every creature speaks under its own name (``[A-Za-z0-9_.-]``, at most 64
characters), so a colony of three sends from three addresses:

``/creature/<name>/hello port:int [token:int]``
    "I am here; reach me at my sender address on ``port``." Sent on start and twice a second
    after, so a restarted creature is found again without configuration. A colony that does
    not know the address answers with an ``ask``; the hello is believed once it carries the
    asked ``token`` (:mod:`midi.peer_table`: the network is not an amplifier).
``/creature/<name>/ask token:int``
    "I hear you; to be heard, say hello to me (at the address this comes from: a colony's
    listening socket) with ``token``." Never larger than the hello it answers.
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

Every argument is bounded at the door (:func:`decode`), because a number that enters here
ends up in a creature's state and in its saved files (two notes of 1e308 seconds once made a
sand:stone creature's ear infinite and its state unsavable). What can be clamped without
changing what the message means is clamped and counted (a velocity above 127, a duration
above :data:`MAX_DURATION`, a state number beyond :data:`MAX_STATE_VALUE`); what cannot is
refused and counted (a pitch or channel out of range, a velocity of 0 — a note-off —, a
negative or non-finite number, a name or text longer than :data:`MAX_TEXT`). A listener reads
at most ``max_rate`` packets a second (a flood must not starve the creatures; the kernel drops
the rest, and those are counted too), and checks each packet's type tags and lengths before python-osc
sees it (python-osc logs a warning per unknown tag: one 1 KB packet made 1,000 lines; it
zero-pads an argument cut short, so a cut packet would be heard with made-up numbers).
"""

from __future__ import annotations

import logging
import math
import re
import select
import socket
import struct
import time
from collections import Counter
from dataclasses import dataclass
from typing import Callable

from pythonosc.osc_bundle_builder import IMMEDIATELY, OscBundleBuilder
from pythonosc.osc_message_builder import OscMessageBuilder
from pythonosc.osc_packet import OscPacket

from creatures.clock import Clock
from midi.notes import NoteEvent
from midi.peer_table import Bucket, PeerTable

logger = logging.getLogger(__name__)

MAX_PACKET = 1024  # bytes; every message of this protocol is far smaller
NAME = re.compile(r"[A-Za-z0-9_.\-]{1,64}")
_ADDRESS = re.compile(r"/creature/([^/]+)/(hello|ask|note|state|bye)")

MAX_DURATION = 60.0
"""Seconds: a heard note longer than this is heard as this long (a drone of a minute is
already longer than any creature's memory of what it heard)."""

MAX_STATE_VALUE = 1e6
"""A state number beyond ±this is clamped to it (drives live in 0..1; a count of a million
is still a count)."""

MAX_TEXT = 128
"""Characters: the longest state text (``action`` joins active action names) accepted."""

MAX_RATE = 1_000
"""Packets a second a listener reads by default: far above what a colony says (a few dozen a
second per creature) and a small share of one core (about 25 µs a packet: 2.5 %); a flood
beyond it is left to the kernel (at 2,000 a second a sand:stone run on a loaded machine still
lost a second now and then under a flood; at 1,000 it did not)."""

BURST = 2_500
"""Packets read at once after a quiet spell, whatever ``max_rate`` (a burst of 2,000 notes is
taken whole)."""

_TAGS = frozenset(b"ifsdh")  # int32, float32, string, float64, int64: all this protocol uses
_ANY_TAGS = frozenset(b"ifsdhbrmtTFN[]")  # every type python-osc decodes (it logs on any other)
MAX_ELSEWHERE_ARGS = 64
"""Arguments a message for the input map may carry (``[[input]] args`` goes up to 64)."""
_BUNDLE = b"#bundle\x00"
_NOT_MALFORMED = ("oversize", "kernel", "at stop")  # drops that say nothing of what was sent
_RXQ_OVFL = getattr(socket, "SO_RXQ_OVFL", 40)  # Linux: count of datagrams the kernel dropped
_SO_MEMINFO = getattr(socket, "SO_MEMINFO", 55)  # Linux: the socket's memory and drop counters (u32s)
_SK_MEMINFO_DROPS = 8  # SK_MEMINFO_DROPS: the index of the drop count in SO_MEMINFO's array


class Refused(ValueError):
    """A message this protocol does not take; ``cause`` names why, for the drop counters."""

    def __init__(self, cause: str, message: str) -> None:
        super().__init__(message)
        self.cause = cause


@dataclass(frozen=True, slots=True)
class Heard:
    """One message from another creature: ``kind`` is hello/ask/note/state/bye; ``note`` is set
    for notes, ``args`` holds the decoded (bounded) arguments, ``sender`` the UDP source
    address; ``clamped`` says an argument was brought into bounds."""

    creature: str
    kind: str
    time: float
    args: tuple
    sender: tuple[str, int]
    note: NoteEvent | None = None
    clamped: bool = False
    size: int = 0  # bytes of the message on the wire (an answer to it must not be larger)


PREFIX = "/creature/"
"""Addresses under this prefix are the creature address space; the rest is for ``elsewhere``."""

_STATE_KEY = re.compile(r"[^\x00-\x1f]{1,64}")


def _whole(x: object) -> object:
    """A float with a whole value as the int it stands for; anything else unchanged."""
    return int(x) if type(x) is float and math.isfinite(x) and x == int(x) else x


def decode(address: str, args: list, time: float, sender: tuple[str, int], size: int = 0) -> Heard:
    """Check one OSC message against the address space and bound its arguments;
    :class:`Refused` (a ValueError) if it does not fit."""
    match = _ADDRESS.fullmatch(address)
    if match is None or NAME.fullmatch(match[1]) is None:
        raise Refused("address", f"address {address!r} is not in the creature address space")
    creature, kind = match[1], match[2]
    if kind in ("hello", "note"):  # pitch, velocity, channel, port: ints, sent as floats by many tools
        args = [_whole(a) if i != 2 or kind == "hello" else a for i, a in enumerate(args)]
    types = tuple(type(a) for a in args)
    note = None
    clamped = False
    if kind == "hello":
        if types not in ((int,), (int, int)) or not 0 < args[0] < 65536:
            raise Refused("arguments", f"{address}: expects one port number [token], got {args!r}")
    elif kind == "ask":
        if types != (int,):
            raise Refused("arguments", f"{address}: expects one token, got {args!r}")
    elif kind == "note":
        if types not in ((int, int, float), (int, int, float, int), (int, int, int), (int, int, int, int)):
            raise Refused("arguments", f"{address}: expects pitch velocity duration [channel], got {args!r}")
        velocity, duration = args[1], float(args[2])
        if not 0 <= duration < math.inf:
            raise Refused("arguments", f"{address}: duration must be finite and >= 0, got {args[2]!r}")
        if velocity > 127 or duration > MAX_DURATION:
            velocity, duration, clamped = min(velocity, 127), min(duration, MAX_DURATION), True
        try:
            note = NoteEvent(time, args[0], velocity, args[3] if len(args) == 4 else 0, duration)
        except ValueError as exc:  # pitch or channel out of range, velocity <= 0: not clampable
            raise Refused("arguments", f"{address}: {exc}") from None
        args = [args[0], velocity, duration, note.channel]
    elif kind == "state":
        if len(args) != 2 or not isinstance(args[0], str) or types[1] not in (int, float, str):
            raise Refused("arguments", f"{address}: expects key value, got {args!r}")
        key, value = args
        if _STATE_KEY.fullmatch(key) is None:
            raise Refused("arguments", f"{address}: a state key is 1..64 printable characters, got {key!r}")
        if isinstance(value, str):
            if len(value) > MAX_TEXT:
                raise Refused("arguments", f"{address}: state text longer than {MAX_TEXT} characters")
        elif not math.isfinite(value):
            raise Refused("arguments", f"{address}: state value must be finite, got {value!r}")
        elif abs(value) > MAX_STATE_VALUE:
            value, clamped = type(value)(math.copysign(MAX_STATE_VALUE, value)), True
        args = [key, value]
    elif args:
        raise Refused("arguments", f"{address}: expects no arguments, got {args!r}")
    return Heard(creature, kind, time, tuple(args), sender, note, clamped, size)


def check_wire(data: bytes, depth: int = 0, *, elsewhere: bool = False) -> None:
    """Refuse, before python-osc parses it, a datagram that is not a bundle of (at most 4 deep)
    or a message with at most 4 arguments of the types this protocol uses, under ``/creature/``.
    With ``elsewhere`` (an input map takes the other addresses) a message at any other address
    may carry up to :data:`MAX_ELSEWHERE_ARGS` arguments of any type python-osc decodes.

    Every length is checked too: python-osc zero-pads an argument cut short, so a note cut to
    38 of its 40 bytes was heard with its duration's low bytes made up; a datagram whose
    strings are not NUL-terminated and padded, whose length is not a multiple of 4, or whose
    arguments are not exactly what its type tags say is ``not osc``, and so is a bundle with no
    element. (A bundle cut exactly between two elements is a smaller bundle: OSC gives a bundle
    no length of its own, so that cut cannot be seen.)

    Cheap (no decoding of arguments), so a flood of junk costs little; and python-osc never
    meets an unknown type tag, on which it logs a warning per tag."""
    if len(data) % 4:
        raise Refused("not osc", f"{len(data)} bytes: not a multiple of 4")
    if data.startswith(_BUNDLE):
        if depth >= 4 or len(data) <= 16:  # nothing in it to take: a bundle cut to its header is counted
            raise Refused("not osc", "bundle nested too deep, or no element after its header")
        index = 16
        while index < len(data):
            size = struct.unpack_from(">i", data, index)[0]  # index + 4 <= len(data): both multiples of 4
            index += 4
            if size <= 0 or size % 4 or index + size > len(data):
                raise Refused("not osc", "bundle element of an impossible size")
            check_wire(data[index:index + size], depth + 1, elsewhere=elsewhere)
            index += size
        return
    if data[:1] != b"/":
        raise Refused("not osc", "neither a message nor a bundle")
    tags = _string_end(data, 0)
    if data[tags:tags + 1] != b",":
        raise Refused("not osc", "no type tag string")
    arguments = _string_end(data, tags)
    types = data[tags + 1:data.index(b"\x00", tags)]
    if data.startswith(b"/creature/"):
        if len(types) > 4 or not _TAGS.issuperset(types):
            raise Refused("type tags", "more than 4 arguments, or a type this protocol never sends")
    elif not elsewhere:
        raise Refused("address", "not in the creature address space")
    elif len(types) > MAX_ELSEWHERE_ARGS or not _ANY_TAGS.issuperset(types):
        raise Refused("type tags", f"more than {MAX_ELSEWHERE_ARGS} arguments, or a type python-osc cannot read")
    if _arguments_end(data, types, arguments) != len(data):
        raise Refused("not osc", "arguments not the length their type tags say")


_FIXED = {ord("i"): 4, ord("f"): 4, ord("r"): 4, ord("m"): 4, ord("d"): 8, ord("h"): 8, ord("t"): 8}
"""Bytes of each fixed-size OSC argument (``T F N [ ]`` take none)."""


def _string_end(data: bytes, start: int) -> int:
    """Where the OSC string at ``start`` ends: after its NUL and the NULs that pad it to a
    multiple of 4; :class:`Refused` if it has no NUL or its padding is cut or not NULs."""
    end = data.find(b"\x00", start)
    padded = (end + 4) & ~3
    if end < 0 or padded > len(data) or data[end:padded].strip(b"\x00"):
        raise Refused("not osc", "a string not NUL-terminated and padded to 4 bytes")
    return padded


def _arguments_end(data: bytes, types: bytes, index: int) -> int:
    """Where the arguments that ``types`` describe, starting at ``index``, end (beyond
    ``len(data)`` if the datagram is cut short of them)."""
    for tag in types:
        if tag in _FIXED:
            index += _FIXED[tag]
        elif tag == ord("s"):
            index = _string_end(data, index)
        elif tag == ord("b"):
            if index + 4 > len(data):
                return index + 4
            size = struct.unpack_from(">i", data, index)[0]
            if size < 0:
                raise Refused("not osc", "a blob of negative size")
            index += 4 + ((size + 3) & ~3)
        if index > len(data):
            return index
    return index


class _Sends:
    """A UDP socket's sends, counted: the bytes that left and the sends that raised (a peer that
    is gone, a send the kernel refused). One failed send must not stop the others, nor be lost."""

    socket: socket.socket
    sent_bytes: int
    send_errors: int

    def _send_to(self, dgram: bytes, address: tuple[str, int]) -> bool:
        """Send ``dgram`` to ``address``; whether it left."""
        try:
            self.sent_bytes += self.socket.sendto(dgram, address)
        except OSError:
            self.send_errors += 1
            return False
        return True


class OscListener(_Sends):
    """A non-blocking UDP socket read once a tick; never raises on what arrives.

    ``dropped`` counts what was not taken, by cause: ``oversize``, ``not osc``, ``address``
    (outside the creature address space), ``type tags``, ``arguments`` (out of bounds) and
    ``kernel`` (datagrams the kernel dropped because the socket's buffer was full: beyond
    ``max_rate`` or between slow polls) and ``at stop`` (datagrams still queued when the listener
    closed). ``clamped`` counts messages taken with an argument brought into bounds.

    The kernel's count comes with each datagram read (``SO_RXQ_OVFL``), so drops after the last
    read would go unsaid: :meth:`close` reads the final count (``SO_MEMINFO``) and counts what is
    still queued (a flood stopped 0.2 s after its start said 53,445 of 142,526 drops).
    """

    def __init__(
        self,
        clock: Clock,
        *,
        host: str = "127.0.0.1",
        port: int = 0,
        max_packet: int = MAX_PACKET,
        receive_buffer: int = 1 << 20,
        elsewhere: Callable[[str, list, float], object] | None = None,
        max_rate: float = MAX_RATE,
    ) -> None:
        """``elsewhere(address, args, time)`` takes every message outside ``/creature/…``."""
        self.clock = clock
        self.elsewhere = elsewhere
        self.max_packet = max_packet
        self.max_rate = max_rate
        self.socket = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self._setup(host, port, receive_buffer)
        except BaseException:
            self.socket.close()
            raise
        self.port: int = self.socket.getsockname()[1]
        self.received = 0  # messages accepted
        self.received_bytes = 0  # every datagram read, taken or not (an oversize one: what was read of it)
        self.clamped = 0
        self.sent_bytes = 0  # asks (answers to hellos, midi.peer_table)
        self.send_errors = 0  # asks whose send raised (once in 3,000, on a loaded CI machine)
        self.dropped: Counter[str] = Counter()
        self._budget = Bucket(max_rate, max(BURST, max_rate / 4))

    def _setup(self, host: str, port: int, receive_buffer: int) -> None:
        self.socket.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, receive_buffer)
        # The kernel may grant less (Linux caps at net.core.rmem_max, often 208 KiB, and reports
        # double what it grants): a burst larger than the buffer between two polls is lost, so say so.
        self.receive_buffer: int = self.socket.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF)
        if self.receive_buffer < receive_buffer:
            logger.warning("OSC receive buffer is %d bytes, not the %d asked for; bursts of more than "
                           "a few hundred messages per tick may drop (raise net.core.rmem_max)",
                           self.receive_buffer, receive_buffer)
        try:
            self.socket.setsockopt(socket.SOL_SOCKET, _RXQ_OVFL, 1)
        except OSError:  # not Linux: kernel drops go uncounted
            pass
        self.socket.bind((host, port))
        self.socket.setblocking(False)

    @property
    def malformed(self) -> int:
        """Packets or messages dropped as not OSC or not this protocol (all causes but size)."""
        return sum(n for cause, n in self.dropped.items() if cause not in _NOT_MALFORMED)

    @property
    def oversize(self) -> int:
        return self.dropped["oversize"]

    def wait(self, timeout: float) -> bool:
        """Block up to ``timeout`` seconds for a packet (for loops with nothing else to do).

        While ``max_rate`` is nearly spent (less than 10 ms of it left) it first sleeps until
        it is back: under a flood the socket is always readable, and a loop woken by it at once,
        to read a packet or two each time, would spin on a full core."""
        missing = self.max_rate / 100 - self._budget.fill(time.monotonic())
        if missing > 0:
            slept = min(max(0.0, timeout), missing / self.max_rate)
            time.sleep(slept)
            timeout -= slept
        return bool(select.select([self.socket], [], [], max(0.0, timeout))[0])

    def poll(self, *, limit: int = 512) -> list[Heard]:
        """What has arrived, at most ``limit`` packets per call (and ``max_rate`` a second)."""
        heard: list[Heard] = []
        now = self.clock.now()
        # max_rate packets a second of real time: a flood costs the creatures a bounded share of the CPU
        allowed = min(limit, int(self._budget.fill(time.monotonic())))
        taken = 0
        while taken < allowed:
            try:
                data, ancillary, _, sender = self.socket.recvmsg(self.max_packet + 1, 64)
            except (BlockingIOError, InterruptedError):
                break
            except OSError:  # e.g. an ICMP error queued on the socket; the next read is fine
                continue
            taken += 1
            for _, kind, value in ancillary:
                if kind == _RXQ_OVFL and len(value) >= 4:  # the kernel's running count
                    self.dropped["kernel"] = struct.unpack("=I", value[:4])[0]
            self.received_bytes += len(data)
            if len(data) > self.max_packet:
                self.dropped["oversize"] += 1
                continue
            try:
                check_wire(data, elsewhere=self.elsewhere is not None)
                messages = OscPacket(data).messages
            except Refused as refused:
                self.dropped[refused.cause] += 1
                continue
            except Exception:  # python-osc raises ParseError, but also struct/index errors
                self.dropped["not osc"] += 1
                continue
            for timed in messages:
                if self.elsewhere is not None and not timed.message.address.startswith(PREFIX):
                    self.elsewhere(timed.message.address, list(timed.message.params), now)
                    continue
                try:
                    message = decode(timed.message.address, list(timed.message.params), now, sender,
                                     timed.message.size)
                except Refused as refused:
                    self.dropped[refused.cause] += 1
                else:
                    heard.append(message)
                    self.received += 1
                    self.clamped += message.clamped
        self._budget.tokens -= taken
        return heard

    def ask(self, address: tuple[str, int], name: str, token: int, *, at_most: int) -> str:
        """Ask ``address``, as creature ``name``, to say hello with ``token``: from this socket,
        so the asked colony knows where we listen; only if that takes no more than ``at_most``
        bytes (the size of the hello that provoked it). ``"sent"``, ``"large"`` (not sent), or
        ``"failed"``: the send raised (counted in :attr:`send_errors`: the machine's fault, not
        the hello's, so not a refusal of it)."""
        builder = OscMessageBuilder(f"/creature/{name}/ask")
        builder.add_arg(token, "i")
        dgram = builder.build().dgram
        if len(dgram) > at_most:
            return "large"
        return "sent" if self._send_to(dgram, address) else "failed"

    def counts(self) -> dict[str, object]:
        """The counters, for the events log and the end-of-run summary."""
        return {"received": self.received, "received_bytes": self.received_bytes, "clamped": self.clamped,
                "dropped": dict(sorted(self.dropped.items()))}

    def close(self) -> None:
        """Close the socket, first counting what it will never read: the datagrams still queued
        (``at stop``) and the kernel's final drop count (``kernel``), so that what was taken and
        what was dropped add up to what arrived. A flood that goes on while this drains is read
        at most a full buffer's worth more; what lands between the last read and the close is
        not seen by anyone."""
        if self.socket.fileno() < 0:
            return
        queued = 0
        for _ in range(BURST + self.receive_buffer // 64):  # a datagram takes far more than 64 bytes of it
            try:
                self.socket.recv(1)
            except (BlockingIOError, InterruptedError):
                break
            except OSError:  # an ICMP error queued on the socket
                continue
            queued += 1
        if queued:
            self.dropped["at stop"] += queued
        drops = self._kernel_drops()
        if drops is not None and drops > self.dropped["kernel"]:
            self.dropped["kernel"] = drops
        self.socket.close()

    def _kernel_drops(self) -> int | None:
        """The kernel's count of datagrams it dropped for this socket (Linux ``SO_MEMINFO``);
        None where it cannot say (then the last count read with a datagram stands)."""
        try:
            meminfo = self.socket.getsockopt(socket.SOL_SOCKET, _SO_MEMINFO, 4 * (_SK_MEMINFO_DROPS + 1))
        except OSError:
            return None
        if len(meminfo) < 4 * (_SK_MEMINFO_DROPS + 1):
            return None
        return struct.unpack_from("=I", meminfo, 4 * _SK_MEMINFO_DROPS)[0]


class OscSender(_Sends):
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
        self.sent_bytes = 0  # bytes that left, to every peer
        self.socket = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)

    def hello(self, port: int, tokens: dict[str, int] | None = None) -> None:
        """Hello to every peer; to those in ``tokens`` (peer key → token it asked for) with it."""
        plain = self._message("hello", [port]).dgram
        for peer, address in self.peers.items():
            token = tokens.get(peer) if tokens else None
            self._send_to(plain if token is None else self._message("hello", [port, token]).dgram, address)

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
            self._send_to(dgram, address)

    def close(self) -> None:
        self.socket.close()


def answer_hello(table: PeerTable, listener: OscListener, name: str, heard: Heard, t: float) -> str:
    """Take a hello into ``table`` (:meth:`PeerTable.hello`): an address not yet proved is asked
    for its token by ``listener`` as creature ``name``, if no larger than the hello; the verdict."""
    address = (heard.sender[0], heard.args[0])
    verdict = table.hello(heard.creature, address, heard.args[1] if len(heard.args) == 2 else None, t)
    if verdict == "ask":
        asked = listener.ask(address, name, table.token(address), at_most=heard.size)
        if asked == "sent":
            table.asked += 1
        elif asked == "large":
            table.refused["large"] += 1
    return verdict
