"""The open input map: any OSC address or MIDI message from outside the colony becomes a
heard note, a sensor reading, a reward or a drive perturbation (``[[input]]`` tables).

An installation meets the tools artists already use (TouchDesigner, Max, Pd, a light sensor on
an Arduino, a visitor's clicker) without code: each ``[[input]]`` table names what it hears
(``osc = "/pattern"`` with OSC 1.0 wildcards, or ``midi = "cc"`` and filters) and what it
becomes (``to``):

* ``note``: a note heard from outside, like one played on a keyboard;
* ``sensor``: a reading pushed into a named :class:`StateObject` in ``World.sensors`` — history,
  saliency and habituation for any creature that models it as a percept (thesis: "state
  objects and decaying memory traces");
* ``reward``: the clicker (thesis: clicker training, "credit assignment"): the tuples that were
  active within ``window`` seconds before the click take it (:meth:`ActionGroup.reward`);
* ``drive``: an impulse to, or a new level of, a drive of the creatures' motivation.

Nothing is dropped in silence. A message no map takes is *unmapped*; one a map takes but
cannot read (an argument missing or of the wrong type, a pitch out of range) is *malformed*;
one over its map's ``limit`` of messages a second (10 for rewards unless set: a flood of clicks
is a retraining, :data:`creatures.runtime.input_routes.CLICKS_PER_SECOND`) is *throttled*, as is
one from the live MIDI input beyond ``[midi] max_rate`` (:mod:`midi.gate`).
Both are counted, and logged as one cause per source: a line (and an event) the first time,
then at most every :data:`LOG_EVERY` seconds with the count since and a few of the addresses
(2,000 distinct addresses once made 1,023 lines in under a second: one per address), and at
the end of the run whatever was counted since a cause's last line; the counters are logged
at the end of the run (``inputs``). Every message is applied at the time
it is polled, on the creature's thread.

Every number read from a message meets a bound before it reaches a value, the way a config
number does (:mod:`creatures.bounds`): a reading, a drive's amount or level, and a reading
after its ``range`` scaling must be finite and within ±:data:`~creatures.bounds.LARGEST_RATE`;
a reward's amount within ±:data:`REWARD_LIMIT`; a note's duration within
:data:`~midi.notes.LONGEST_NOTE`. Beyond, the message is refused as malformed,
not clamped: a sender that says 1e308 means something the map does not know, and a clamped
value would credit a tuple with the largest reward there is for it.
"""

from __future__ import annotations

import math
from collections import Counter
from typing import TYPE_CHECKING, Any, Callable

import mido

from creatures.behaviour.state_object import Habituation, StateObject
from creatures.bounds import LARGEST_RATE
from creatures.log_limit import INTERVAL
from creatures.runtime.input_routes import MIDI, MIDI_KIND, MIDI_SPAN, Route
from creatures.runtime.schema import Arg, InputMap, Number, named_pitch
from midi.notes import LONGEST_NOTE, NoteEvent, is_note_off
from midi.peer_table import Bucket

if TYPE_CHECKING:
    from creatures.runtime.world import World

HEARD_LENGTH = 0.25
"""Seconds assumed for a heard note whose length is not known (a MIDI note heard at its note-on)."""

LOG_EVERY = INTERVAL
"""Seconds between two log lines of one cause (unmapped, or malformed, from one source): the
rule of every rate-limited log line (:data:`creatures.log_limit.INTERVAL`), not a second one."""

EXAMPLES = 3
"""Distinct addresses a cause's log line names (of those seen since its last line)."""

SENSOR_LOG_EVERY = 0.1
"""Seconds between two ``sensor`` log lines of one sensor (a 100 Hz controller must not
flood the events log; every reading still reaches the sensor)."""

REWARD_LIMIT = 1e3
"""Largest magnitude of one reward from outside. A click moves a credited value by at most
``rate·amount``; at this bound a year of clicks every second stays far inside the
:data:`~creatures.bounds.LARGEST_VALUE` that saved values are read back within."""

class Unreadable(ValueError):
    """A message a map matched but cannot read (counted as malformed)."""


# -- reading values from a message ---------------------------------------------------------------
def as_number(x: Any, what: str, bound: float = LARGEST_RATE) -> float:
    """An argument as a finite number within ±``bound``: int, float, bool (1/0) or a
    numeric string."""
    if isinstance(x, str):
        try:
            x = float(x)
        except ValueError:
            raise Unreadable(f"{what}: {x!r} is not a number") from None
    if not isinstance(x, (int, float)):
        raise Unreadable(f"{what}: {x!r} is not a number")
    return within(x, what, bound)


def within(x: float, what: str, bound: float = LARGEST_RATE) -> float:
    """``x`` as a float if it is finite and within ±``bound``, else :class:`Unreadable`."""
    try:
        value = float(x)
    except OverflowError:  # an integer beyond any float
        value = math.inf
    if not (math.isfinite(value) and abs(value) <= bound):
        raise Unreadable(f"{what}: {str(x)[:40]} is not a finite number within ±{bound:g}")
    return value


def as_pitch(x: Any) -> int:
    """A MIDI pitch from a number or a note name (``C4`` = 60, ``F#3``, ``Bb2``); not from an
    OSC truth value (``T`` was heard as pitch 1), which a sensor reads as 1 or 0."""
    if isinstance(x, bool):
        raise Unreadable(f"pitch: a truth value is not a pitch ({x})")
    if isinstance(x, str) and (number := named_pitch(x)) is not None:
        x = number
    pitch = round(as_number(x, "pitch"))
    if not 0 <= pitch <= 127:
        raise Unreadable(f"pitch {pitch} is outside 0..127")
    return pitch


def read(value: Number | None, args: tuple, fallback: Number) -> Any:
    """``value`` (a constant or an :class:`Arg`) read from ``args``; ``fallback`` if unset."""
    value = fallback if value is None else value
    if not isinstance(value, Arg):
        return value
    if value.arg < len(args):
        return args[value.arg]
    if value.default is None:
        raise Unreadable(f"no argument {value.arg} (the message has {len(args)})")
    return value.default


# -- the router ---------------------------------------------------------------------------------
class InputRouter:
    """Applies the colony's routes to every message from outside, counting what none takes."""

    def __init__(self, routes: list[Route], world: "World", say: Callable[[str], None] = lambda m: None) -> None:
        self.routes = routes
        self.osc_routes = [r for r in routes if r.pattern is not None]
        self.midi_routes = [r for r in routes if r.midi is not None]
        self.world = world
        self.say = say
        self.counts: Counter[str] = Counter()  # mapped / unmapped / malformed, and by source
        # (what, via) -> when last logged, messages since, a few of their addresses, the latest's address, why
        # and where it was read
        self._logged: dict[tuple[str, str], tuple[float, int, tuple[str, ...], str, str, str]] = {}
        self._sensor_logged: dict[str, float] = {}
        # each map's ``limit``: a bucket of ``limit`` messages (at least one) refilled at ``limit`` a
        # second of the run's clock; the session's, not the Route's (the installation's routes are
        # shared by every session built from it: a rehearsal's clicks must not empty the run's)
        self._throttles = {id(route): Bucket(route.limit, max(1.0, route.limit)) for route in routes
                           if route.limit is not None}
        for route in routes:
            if route.spec.to == "sensor":
                self._make_sensor(route.spec)

    def _make_sensor(self, spec: InputMap) -> None:
        if spec.name not in self.world.sensors:
            # A reading's saliency is its size (a brighter light is more stimulating); repeated
            # readings habituate the way a startle does (Habituation's defaults).
            self.world.sensors[spec.name] = StateObject(spec.name, history=1024, habituation=Habituation())

    # -- sources --------------------------------------------------------------------------
    def osc(self, address: str, args: list | tuple, t: float, via: str = "osc", at: str = "") -> int:
        """An OSC message (or a serial line or rehearsal row read as one); notes heard. ``at``
        is where it was read (a rehearsal file's line), said with what cannot be taken."""
        args = tuple(args)
        matched = [r for r in self.osc_routes if r.matches_osc(address, args)]
        if not matched:
            self.miss("unmapped", via, address, t, "no [[input]] map takes it", at=at)
            return 0
        return self._apply(matched, args, t, via, address, at)

    def midi(self, msg: mido.Message, t: float, via: str = "midi", at: str = "") -> int:
        """A MIDI message: mapped ones go where their map says; unmapped note-ons are heard
        as notes (a keyboard needs no map) and note-offs end them; anything else is unmapped."""
        kind = "note_off" if is_note_off(msg) else MIDI_KIND.get(msg.type)
        matched = [r for r in self.midi_routes if kind is not None and r.matches_midi(kind, msg)]
        if matched:
            return self._apply(matched, tuple(getattr(msg, field) for field in MIDI[kind][1]), t, via, kind, at)
        if kind not in ("note", "note_off"):
            self.miss("unmapped", via, msg.type, t, "no [[input]] map takes it", at=at)
            return 0
        self.mapped(via)  # by the default map of a keyboard
        if kind == "note_off":
            return 0
        # A player expects creatures to react when a key goes down, not when it is
        # released: heard at note-on, with a nominal length (the real one is not known yet).
        self.world.inject(NoteEvent(t, msg.note, msg.velocity, msg.channel, HEARD_LENGTH), via=via)
        return 1

    def midi_bytes(self, data: bytes | list[int], t: float, via: str, at: str = "") -> int:
        """Raw MIDI bytes (a rehearsal row, a fuzzer): one message, or malformed."""
        try:
            msg = mido.Message.from_bytes(list(data))
        except (ValueError, TypeError, IndexError) as exc:
            self.miss("malformed", via, "midi", t, f"not one MIDI message ({exc})", at=at)
            return 0
        return self.midi(msg, t, via, at)

    # -- targets ----------------------------------------------------------------------------
    def _apply(self, routes: list[Route], args: tuple, t: float, via: str, address: str, at: str = "") -> int:
        """Every matching route within its ``limit`` takes the message; it counts once: mapped,
        malformed if any route could not read it, or throttled if every route was over its limit."""
        # a message spends its map's allowance before it is read: a flood of unreadable ones is a flood all the same
        notes, failed, taken = 0, None, [route for route in routes if self._within(route, t)]
        for route in taken:
            try:
                notes += getattr(self, f"_{route.spec.to}")(route, args, t, via)
            except Unreadable as exc:
                failed = failed or str(exc)
        if failed is not None:
            self.miss("malformed", via, address, t, failed, at=at)
        elif not taken:
            self.miss("throttled", via, address, t, f"over its map's limit of {routes[0].limit:g} a second")
        else:
            self.mapped(via)
        return notes

    def _within(self, route: Route, t: float) -> bool:
        throttle = self._throttles.get(id(route))
        return throttle is None or throttle.take(t)

    def mapped(self, via: str) -> None:
        self.counts["mapped"] += 1
        self.counts[f"mapped {via}"] += 1

    def _note(self, route: Route, args: tuple, t: float, via: str) -> int:
        spec = route.spec
        midi_note = route.midi in ("note", "note_off", "polytouch")
        pitch = as_pitch(read(spec.pitch, args, Arg(arg=0)))
        velocity = round(as_number(read(spec.velocity, args, Arg(arg=1) if midi_note else 100.0), "velocity"))
        duration = as_number(read(spec.duration, args, HEARD_LENGTH), "duration", LONGEST_NOTE)
        if not 1 <= velocity <= 127 or duration < 0:
            raise Unreadable(f"velocity {velocity} (1..127) or duration {duration} (>= 0) out of range")
        channel = args[-1] if route.midi else 0
        self.world.inject(NoteEvent(t, pitch, velocity, channel, duration), via=via)
        return 1

    def _sensor(self, route: Route, args: tuple, t: float, via: str) -> int:
        spec = route.spec
        value = as_number(read(spec.value, args, Arg(arg=0)), "value")
        if spec.range is not None:
            lo, hi = spec.input_range or MIDI_SPAN.get(route.midi or "", (0.0, 127.0) if route.midi else (0.0, 1.0))
            value = within(spec.range[0] + (value - lo) / (hi - lo) * (spec.range[1] - spec.range[0]), "scaled value")
        sensor = self.world.sensors[spec.name]
        saliency = sensor.push(max(t, sensor.times_array[-1]) if len(sensor) else t, value)
        if t >= self._sensor_logged.get(spec.name, -math.inf) + SENSOR_LOG_EVERY:
            self._sensor_logged[spec.name] = t
            self.world.emit("sensor", name=spec.name, value=value, saliency=saliency, via=via)
        return 0

    def _reward(self, route: Route, args: tuple, t: float, via: str) -> int:
        amount = as_number(read(route.spec.amount, args, 1.0), "amount", REWARD_LIMIT)
        for creature in self._reached(route, args):
            creature.reward(amount, t, route.spec.window, route.spec.rate)
        return 0

    def _drive(self, route: Route, args: tuple, t: float, via: str) -> int:
        spec = route.spec
        amount = None if spec.amount is None else as_number(read(spec.amount, args, 0.0), "amount")
        level = None if spec.set is None else as_number(read(spec.set, args, 0.0), "set")
        for creature in self._reached(route, args):
            creature.drive(t, spec.drive, amount=amount, level=level)
        return 0

    def _reached(self, route: Route, args: tuple) -> list:
        by_name = {c.name: c for c in self.world.creatures}
        if route.creatures is not None:
            return [by_name[name] for name in route.creatures]
        name = read(route.spec.creatures, args, route.spec.creatures)
        creature = by_name.get(name) if isinstance(name, str) else None
        if creature is None or creature.name not in self._able(route):
            raise Unreadable(f"{name!r} names no creature this map can reach")
        return [creature]

    def _able(self, route: Route) -> set[str]:
        if route.spec.to == "reward":
            return {c.name for c in self.world.creatures if c.rewardable(c.spec)}
        return {c.name for c in self.world.creatures if route.spec.drive in c.drive_names(c.spec)}

    # -- what nothing takes ----------------------------------------------------------------
    def miss(self, what: str, via: str, address: str, t: float, why: str, count: int = 1, at: str = "") -> None:
        """Count an unmapped, malformed or throttled message (or ``count`` of them, the last at
        ``address``: a flood's drops counted at once); log its cause (``what`` from ``via``) the
        first time, then at most every :data:`LOG_EVERY` seconds with the count since and up
        to :data:`EXAMPLES` of the addresses, however many distinct addresses there are. ``at``
        is where the message was read, when that is known (a rehearsal file's line: in a file
        of a hundred rows of one address, the author looked for the one row)."""
        self.counts[what] += count
        self.counts[f"{what} {via}"] += count
        last, since, examples, *_ = self._logged.get((what, via), (-math.inf, 0, ()))
        address = address[:80]
        if address not in examples and len(examples) < EXAMPLES:
            examples += (address,)
        if t - last < LOG_EVERY:
            self._logged[(what, via)] = (last, since + count, examples, address, why, at)
            return
        self._line(what, via, address, t, last, since + count, examples, why, at)

    def flush(self, t: float) -> None:
        """Say what each cause counted since its last line: at the end of a run, or the messages
        of the last ``LOG_EVERY`` seconds before it would be counted and never said."""
        for (what, via), (last, since, examples, address, why, at) in list(self._logged.items()):
            if since:
                self._line(what, via, address, t, last, since, examples, why, at)

    def _line(self, what: str, via: str, address: str, t: float, last: float, count: int,
              examples: tuple[str, ...], why: str, at: str) -> None:
        """One log line (and event) of a cause: ``count`` messages since ``last``, the latest
        one's ``address``, ``why`` and ``at``."""
        self._logged[(what, via)] = (t, 0, (), address, why, at)
        self.world.emit(what, via=via, address=address, why=why, count=count, examples=list(examples),
                        **({"at": at} if at else {}))
        why += f", at {at}" if at else ""
        if last == -math.inf:
            self.say(f"{via} input {address!r} {what} ({why}); counted, logged at most every {LOG_EVERY:.0f} s")
        else:
            self.say(f"{via} input {what}: {count} messages in {t - last:.0f} s, e.g. "
                     f"{', '.join(map(repr, examples))} (last: {why})")

    def summary(self) -> dict[str, int]:
        """The counters, for the run's summary and its last ``inputs`` event."""
        return dict(sorted(self.counts.items()))
