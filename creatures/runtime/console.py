"""The remote console: a running colony asked and told over OSC, request by request.

IViHumans' minds and graphics speak a request/reply protocol (its "sense"/"act" messages):
every request carries an id the client chose, and is answered by exactly one reply carrying
that id, with the values asked for or an error. The console does the same over OSC (UDP):

``/console/<verb> id:int [secret:str] args...`` is answered to the address it came from with
``/console/reply id:int json:str`` or ``/console/error id:int message:str`` (id -1 when the
request had none). Each message of an OSC bundle is a request of its own. The verbs (``docs/stream.md`` lists their arguments): ``status``,
``drives``, ``values``, ``percepts``, ``state``, ``set``, ``trigger``, ``reward``, ``pause``,
``resume``, ``save``.

Threads. A thread of the console's own reads the socket and checks each request's form
(OSC, a known verb, an int id, the secret, the arguments' count and types); what fails is
answered there with an error and counted, so a flood of garbage costs the creatures nothing
but the interpreter's share. A well-formed request is queued (bounded: beyond ``queue`` it is
answered ``busy``) and applied on the creatures' thread at a tick boundary
(:attr:`TickLoop.boundary <creatures.runtime.ticking.TickLoop.boundary>`: after a tick, or at
a look between two), where no tick is half done and no lock is needed. At most ``max_rate``
requests a second are answered; beyond, they are counted and dropped (the network is no
amplifier). Off unless ``[console] port`` is set; loopback unless ``host`` says otherwise.
"""

from __future__ import annotations

import hmac
import json
import queue
import select
import socket
import threading
import time
from collections import Counter
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Callable

from pythonosc.osc_message import OscMessage

from creatures.kinds.spec_keys import SpecKeyError, read, with_key
from creatures.runtime.inspect import Tree, knowledge
from creatures.runtime.osc_wire import message
from creatures.runtime.schema import ConsoleSection
from midi.peer_table import Bucket

if TYPE_CHECKING:
    from creatures.kinds.base import CreatureKind
    from creatures.runtime.session import Session

PREFIX = "/console/"
MAX_REQUEST = 4096
"""Bytes a request may take (a datagram beyond is malformed): every request here is short."""

BUNDLE = b"#bundle\x00"
"""How an OSC bundle begins (its 8-byte time tag follows, then size-prefixed elements)."""

MAX_REPLY = 60_000
"""Bytes a reply may take (one UDP datagram); a larger answer is an error saying so."""

REWARD_LIMIT = 1000.0
"""Largest reward, either sign (as the input map's)."""

REWARD_WINDOW, REWARD_RATE = 1.5, 0.2
"""A console reward's window and blend rate: the input map's defaults (``[[input]]``)."""

ID_MIN, ID_MAX = -(2**31), 2**31 - 1
"""The ids a reply can carry (an OSC int32). python-osc reads an int64 (``h``) as an int too: a
status with an id of 2**40 raised on the creatures' thread while its reply was encoded and ended
the run with a traceback, and a malformed one ended the console's thread, deaf from then on."""

Arity = tuple[type, ...]
VERBS: dict[str, Arity] = {
    "status": (), "pause": (), "resume": (), "save": (),
    "drives": (str,), "values": (str,), "percepts": (str,), "state": (str,),
    "set": (str, str, object), "trigger": (str, str), "reward": (str, float),
}
"""Each verb's arguments after the id (and secret): a creature's name first where it takes one."""


class Refused(Exception):
    """A request the colony will not do; the message is the reply's."""


class Malformed(Exception):
    """A datagram that is no request: its id (-1 if it has none), the counter it goes to, why."""

    def __init__(self, rid: int, cause: str, why: str) -> None:
        super().__init__(why)
        self.rid, self.cause, self.why = rid, cause, why


@dataclass(frozen=True)
class Request:
    id: int
    verb: str
    args: tuple
    sender: tuple[str, int]


def _fits(value: Any, kind: type) -> bool:
    if kind is object:
        return isinstance(value, (int, float, str, bool))
    if kind is float:
        return isinstance(value, (int, float)) and not isinstance(value, bool)
    return isinstance(value, kind)


def requests_in(data: bytes) -> list[bytes]:
    """The requests a datagram holds: itself, or each message of an OSC bundle, nested bundles
    opened (TouchDesigner's OSC Out, SuperCollider's sendBundle and liblo send bundles). The time
    tag is not kept: a bundled request is applied at the creatures' next look, as any other. A
    bundle that holds none, or whose sizes do not add up, is returned whole for :func:`parse`
    to refuse."""
    if not data.startswith(BUNDLE) or len(data) > MAX_REQUEST:
        return [data]
    found, index = [], len(BUNDLE) + 8
    while index + 4 <= len(data):
        size = int.from_bytes(data[index:index + 4], "big", signed=True)
        element = data[index + 4:index + 4 + size]
        if size <= 0 or len(element) < size:
            return [data]
        found.extend(requests_in(element))
        index += 4 + size
    return found if found and index == len(data) else [data]


def parse(data: bytes, sender: tuple[str, int], secret: str | None) -> Request:
    """A request from a datagram (a message: :func:`requests_in` opens bundles), or :class:`Malformed`."""
    if len(data) > MAX_REQUEST:
        raise Malformed(-1, "malformed", f"request larger than {MAX_REQUEST} bytes")
    if data.startswith(BUNDLE):
        raise Malformed(-1, "malformed", "an OSC bundle that holds no request, or whose elements' sizes do not add up")
    try:
        msg = OscMessage(data)
        params = list(msg.params)
    except Exception:  # python-osc raises ParseError, and struct/index/unicode errors on garbage
        raise Malformed(-1, "malformed", "not an OSC message (a request is /console/<verb> id ...)") from None
    rid = params[0] if params and isinstance(params[0], int) and not isinstance(params[0], bool) else None
    if rid is None:
        raise Malformed(-1, "malformed", "a request's first argument is its id (an int)")
    if not ID_MIN <= rid <= ID_MAX:  # an OSC int64 ('h') id: the reply's int32 could not carry it back
        raise Malformed(-1, "malformed", f"a request's id is a 32-bit int ({ID_MIN} to {ID_MAX}), got {rid}")
    verb = msg.address[len(PREFIX):] if msg.address.startswith(PREFIX) else None
    if verb not in VERBS:
        raise Malformed(rid, "malformed", f"unknown request {msg.address!r} (verbs: {', '.join(sorted(VERBS))})")
    args = params[1:]
    if secret is not None:
        given = args[0] if args and isinstance(args[0], str) else ""
        if not hmac.compare_digest(given.encode(), secret.encode()):
            raise Malformed(rid, "secret", "wrong or missing secret (it follows the id)")
        args = args[1:]
    arity = VERBS[verb]
    if len(args) != len(arity) or not all(_fits(a, k) for a, k in zip(args, arity)):
        names = " ".join(k.__name__ if k is not object else "value" for k in arity)
        raise Malformed(rid, "malformed", f"{verb} takes: id{' secret' if secret else ''} {names}".rstrip())
    return Request(rid, verb, tuple(args), sender)


def tree_json(tree: Tree) -> dict:
    return {"name": tree.name, "size": tree.size, "children": [tree_json(c) for c in tree.children]}


def spec_value(text: Any) -> Any:
    """A ``set`` value: a string that reads as JSON (``"[1, 2]"``, ``"true"``) is that value."""
    if isinstance(text, str):
        try:
            return json.loads(text)
        except ValueError:
            return text
    return text


class ColonyHandle:
    """What the console acts on: the session and the run's hands (pause, save, status)."""

    def __init__(self, session: "Session", *, pause: Callable[[bool], None],
                 save: Callable[[float], str] | None, status: Callable[[], dict]) -> None:
        self.session, self.pause, self.save, self.status = session, pause, save, status
        self.by_name = {c.name: (i, c) for i, c in enumerate(session.creatures)}

    def creature(self, name: str) -> tuple[int, "CreatureKind"]:
        try:
            return self.by_name[name]
        except KeyError:
            raise Refused(f"no creature named {name!r} (creatures: {', '.join(self.by_name)})") from None

    def apply(self, request: Request, t: float) -> Any:
        """The answer to ``request`` at clock time ``t`` (on the creatures' thread), or :class:`Refused`."""
        verb, args = request.verb, request.args
        if verb == "status":
            return self.status()
        if verb in ("pause", "resume"):
            self.pause(verb == "pause")
            return {"paused": verb == "pause"}
        if verb == "save":
            if self.save is None:
                raise Refused("this run keeps no state (set state = DIR or run with --state)")
            return {"saving": self.save(t)}
        index, creature = self.creature(args[0])
        if verb == "drives":
            motivation = getattr(creature, "motivation", None)
            if motivation is None:
                return {}
            return dict(zip(motivation.names, motivation.levels_at(max(t, motivation.time)).tolist()))
        if verb == "state":
            return creature.state()
        if verb in ("values", "percepts"):
            known = knowledge(creature.name, creature.spec.kind, creature.state())
            if verb == "values":
                return {"values": known.values, "confidence": known.confidence}
            return [tree_json(tree) for tree in known.trees]
        if verb == "set":
            return self.set(index, creature, args[1], spec_value(args[2]))
        if verb == "trigger":
            return self.trigger(creature, args[1], t)
        amount = float(args[1])
        if not abs(amount) <= REWARD_LIMIT:
            raise Refused(f"reward {amount} is beyond ±{REWARD_LIMIT:g}")
        if not creature.reward_groups():
            raise Refused(f"{creature.name} has no action-group a reward can reach")
        return {"credited": creature.reward(amount, t, REWARD_WINDOW, REWARD_RATE)}

    def set(self, index: int, creature: "CreatureKind", key: str, value: Any) -> dict:
        """Spec key ``key`` (dotted for a nested table: ``voice.gain``) set to ``value``,
        validated by the kind's schema as a config would be; refused with the schema's message
        (:func:`creatures.kinds.spec_keys.with_key`, which says what changes at once)."""
        try:
            spec = with_key(creature.spec, key, value, creature.name, literal=False)  # a toggle's 0/1
        except SpecKeyError as exc:
            raise Refused(str(exc)) from None
        creature.spec = spec
        if key in ("gain", "pan"):
            self.session.mixer.set(index, gain=spec.gain, pan=spec.pan)
        taken = read(spec, key)  # as the schema took it: a toggle's 1 is true, "0.5" is 0.5
        creature.world.emit("console set", creature=creature.name, key=key, value=taken)
        return {"set": key, "value": taken}

    def trigger(self, creature: "CreatureKind", name: str, t: float) -> dict:
        for group in creature.reward_groups():
            if any(tp.name == name for tp in group.tuples):
                group.force(name, t)
                return {"active": [tp.name for tp in group.active]}
        tuples = [tp.name for group in creature.reward_groups() for tp in group.tuples]
        raise Refused(f"{creature.name} has no action-tuple named {name!r} (tuples: {', '.join(tuples) or 'none'})")


class Console:
    """The console's socket and thread; :meth:`serve` applies queued requests (creatures' thread)."""

    def __init__(self, section: ConsoleSection, colony: ColonyHandle) -> None:
        self.section = section
        self.colony = colony
        self.socket = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.socket.bind((section.host, section.port or 0))
        self.socket.setblocking(False)
        self.port: int = self.socket.getsockname()[1]
        self.requests: queue.Queue[Request] = queue.Queue(section.queue)
        self.counts: Counter[str] = Counter()
        self._budget = Bucket(section.max_rate, section.max_rate)
        self._running = True
        self._thread = threading.Thread(target=self._read, name="remote console", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def _read(self) -> None:
        while self._running:
            if not select.select([self.socket], [], [], 0.2)[0]:
                continue
            while True:
                try:
                    data, sender = self.socket.recvfrom(MAX_REQUEST + 1)
                except (BlockingIOError, InterruptedError):
                    break
                except OSError:  # an ICMP error queued on the socket (a client gone); the next read is fine
                    continue
                for request in requests_in(data):
                    self._take(request, sender)

    def _take(self, data: bytes, sender: tuple[str, int]) -> None:
        self.counts["received"] += 1
        if not self._budget.take(time.monotonic()):
            self.counts["over rate"] += 1
            return
        try:
            request = parse(data, sender, self.section.secret)
        except Malformed as bad:
            self.counts[bad.cause] += 1
            self._error(sender, bad.rid, bad.why)
            return
        try:
            self.requests.put_nowait(request)
        except queue.Full:
            self.counts["busy"] += 1
            self._error(sender, request.id, "busy: too many requests waiting for the creatures")

    def serve(self, t: float) -> None:
        """Apply every queued request at clock time ``t`` and answer it (a tick boundary)."""
        while True:
            try:
                request = self.requests.get_nowait()
            except queue.Empty:
                return
            try:
                answer = self.colony.apply(request, t)
                text = json.dumps(answer, allow_nan=False)
            except Refused as refused:
                self.counts["refused"] += 1
                self._error(request.sender, request.id, str(refused))
                continue
            except Exception as exc:  # a kind's code that trips on a request must not stop the show
                self.counts["failed"] += 1
                self._error(request.sender, request.id, f"{request.verb} failed ({type(exc).__name__}: {exc})")
                continue
            reply = message("/console/reply", request.id, text)
            if len(reply) > MAX_REPLY:
                self.counts["refused"] += 1
                self._error(request.sender, request.id, f"the answer takes {len(reply)} bytes, more than "
                                                        f"{MAX_REPLY} (one datagram): ask for drives, values or percepts")
                continue
            self.counts["answered"] += 1
            self._send(reply, request.sender)

    def _error(self, sender: tuple[str, int], rid: int, why: str) -> None:
        self._send(message("/console/error", rid, why), sender)

    def _send(self, dgram: bytes, sender: tuple[str, int]) -> None:
        try:
            self.socket.sendto(dgram, sender)
        except OSError:
            self.counts["send errors"] += 1

    def summary(self) -> dict[str, int]:
        return dict(sorted(self.counts.items()))

    def close(self) -> None:
        """Stop reading, answer what still waits (:meth:`_turn_away`), let the port go."""
        self._running = False
        if self._thread.is_alive():
            self._thread.join(2)
        self._turn_away()
        self.socket.close()

    def _turn_away(self) -> None:
        """Requests queued after the creatures' last look (the run was ending) are answered and
        counted as ``ending``: they were dropped unanswered and uncounted, and a client waited
        out its timeout for the one reply every request is promised."""
        while True:
            try:
                request = self.requests.get_nowait()
            except queue.Empty:
                return
            self.counts["ending"] += 1
            self._error(request.sender, request.id, f"the run is ending: {request.verb} not done")
