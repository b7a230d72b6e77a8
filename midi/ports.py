"""MIDI ports: an in-memory pair needing no backend, port lookup by name or pattern, and a
port that survives its device going away.

An installation runs for weeks; a USB interface gets unplugged, a JACK client restarts. A
:class:`ResilientPort` reports the loss once, keeps the creature's loop running (no exception
escapes), looks for the device again at a bounded rate measured in elapsed clock time, and
reports once more when it is back. Device access goes through a small :class:`PortFactory`
so tests can use a fake backend that fails and recovers on cue.

Listing ports can be slow: mido's rtmidi backend opens two new clients per listing, and under
JACK one listing took ~2.5 s on a loaded machine (issue 14). So :class:`MidoInputs` lists
through one probe client kept open (a fraction of a millisecond), and a live run gives every
:class:`ResilientPort` a :class:`~creatures.supervisor.Supervisor`: presence checks and
reopening then run on the supervisor's thread, and the creature's thread only sends (a send
that fails hands the port to the supervisor, which looks again at once).

A JACK server that dies takes every rtmidi client of the process with it, silently: a
:class:`~midi.jack.JackPulse` notices, and a client of the lost server is then abandoned, never
closed (:mod:`midi.jack`).
"""

from __future__ import annotations

import logging
import re
from typing import Callable, Protocol

import mido
from mido.ports import BaseInput, BaseOutput, BasePort

from creatures.clock import Clock
from creatures.supervisor import Supervisor
from midi.jack import JackPulse, abandon, jack_pulse
from midi.polled import PolledInput, api_id

logger = logging.getLogger(__name__)

BACKEND_HINT = "on Linux without ALSA start a JACK server and set MIDO_BACKEND=mido.backends.rtmidi/UNIX_JACK"
"""What to do when the backend cannot list ports at all (rtmidi with no ALSA sequencer: a
container, a machine with JACK MIDI only), where its own error names only a C++ call."""


class MemoryInput(BaseInput):
    """An input port whose messages are put there by a :class:`MemoryOutput` (or a test)."""

    def _receive(self, block: bool = True) -> None:
        """Nothing to fetch: senders append straight to the port's queue."""

    def inject(self, msg: mido.Message) -> None:
        """Deliver ``msg`` as if a device had sent it (thread-safe: a deque append)."""
        self._messages.append(msg)


class MemoryOutput(BaseOutput):
    """An output port that delivers every message to a :class:`MemoryInput`, if given."""

    def __init__(self, name: str = "", into: MemoryInput | None = None, **kwargs) -> None:
        self.into = into
        super().__init__(name, **kwargs)

    def _send(self, msg: mido.Message) -> None:
        if self.into is not None:
            self.into.inject(msg)


def memory_pair(name: str = "memory") -> tuple[MemoryInput, MemoryOutput]:
    """A connected (input, output) pair: what is sent on the output arrives at the input."""
    inport = MemoryInput(name)
    return inport, MemoryOutput(name, into=inport)


class MemoryPorts:
    """A :class:`PortFactory` over in-memory ports (tests, benchmarks): lists them by name and
    opens the port itself, so a run's configured port name finds it like a device."""

    def __init__(self, *ports: BasePort) -> None:
        self.ports = {port.name: port for port in ports}

    def names(self) -> list[str]:
        return list(self.ports)

    def open(self, name: str, *, virtual: bool = False) -> BasePort:
        return self.ports[name]


class PortFactory(Protocol):
    """Lists and opens ports of one direction; mido's backends or a fake one in tests. A
    factory may also say which of its ports are ``stale(port)``: lost with their server, to
    be abandoned rather than closed (:class:`MidoInputs` under JACK)."""

    def names(self) -> list[str]: ...

    def open(self, name: str, *, virtual: bool = False) -> BasePort: ...


class MidoInputs:
    """Input ports of a mido backend: by default the one ``MIDO_BACKEND`` names (python-rtmidi
    if unset), or e.g. ``mido.Backend("mido.backends.rtmidi/UNIX_JACK")``.

    rtmidi inputs open as :class:`midi.polled.PolledInput` (no Python on the driver's thread);
    other backends open as mido opens them. With rtmidi, names are listed by one probe client
    made on the first listing and kept (see the module docstring for why). Under JACK (named,
    or the API RtMidi took when told none), a listing while the server is gone raises, and
    :meth:`stale` says which ports it took with it; ``pulse`` is the process's
    :func:`jack_pulse` unless a test gives its own.
    """

    def __init__(self, backend: mido.Backend | None = None, *, pulse: JackPulse | None = None) -> None:
        self.backend = backend or mido.backend
        self._probe = None
        self._probe_generation = 0
        self._pulse = pulse
        self._chose_jack = False  # rtmidi, told no API, took JACK's (:meth:`_took_jack`)

    def names(self) -> list[str]:
        probe = self._rtmidi_probe()
        return list(probe.get_ports()) if probe is not None else list(self.backend.get_input_names())

    def stale(self, port: BasePort) -> bool:
        """Whether ``port``'s JACK server is gone: it must be neither used nor closed. A port
        opened on JACK's API is JACK's still after RtMidi, told no API, chose another."""
        generation = getattr(port, "jack_generation", None)
        return generation is not None and self._pulse is not None and generation != self._pulse.generation

    def _jack(self) -> JackPulse | None:
        if self.backend.name != "mido.backends.rtmidi" or self._api() != "UNIX_JACK":
            return None
        if self._pulse is None:
            self._pulse = jack_pulse()
        return self._pulse

    def _stamp(self, port: BasePort) -> BasePort:
        pulse = self._jack()
        if pulse is not None:
            port.jack_generation = pulse.generation
        return port

    def _rtmidi_probe(self, kind: str = "MidiIn"):
        """The kept rtmidi client that lists ports, or None for other backends; under JACK, a
        new one once the server it listed went away. Where RtMidi took JACK's API, told none,
        it is told none again then, and takes the first API that has ports now: an engineer
        who named no API meant whichever has the synth (a USB synth on ALSA's sequencer with
        JACK gone), and JACK's taken for good left the run saying the server was not running
        until it came back, the synth beside it unplayed."""
        if self.backend.name != "mido.backends.rtmidi":
            return None
        pulse = self._jack()
        if pulse is not None:
            alive = pulse.alive()
            if self._probe is not None and self._probe_generation != pulse.generation:
                abandon(self._probe)
                self._probe = None
                if self.backend.api is None:  # chosen by RtMidi: chosen again, below
                    self._chose_jack, pulse = False, None
            if pulse is not None and not alive:
                raise OSError("the JACK server is not running")
        if self._probe is None:
            import rtmidi

            self._probe = getattr(rtmidi, kind)(rtapi=api_id(self.backend.api), name="creatures-probe")
            self._probe_generation = pulse.generation if pulse is not None else 0
        if self.backend.api is None and not self._chose_jack:
            self._took_jack(self._probe)
        return self._probe

    def _took_jack(self, probe) -> None:
        """Told no API, RtMidi takes the first that has ports: JACK's where ALSA's sequencer
        offers none (no sound card's, no Midi Through). Where no API has any, it keeps the last
        it tried, JACK's perhaps with no server, which says nothing: JACK is taken to be chosen
        once the probe lists JACK ports, its pulse starting then, and ports open on JACK's API."""
        import rtmidi

        if probe.get_current_api() != rtmidi.API_UNIX_JACK or not probe.get_port_count():
            return
        self._chose_jack = True
        pulse = self._jack()
        pulse.alive()  # the pulse starts with the first listing of ports, as under a named JACK
        self._probe_generation = pulse.generation

    def _api(self) -> str | None:
        """The RtMidi API ports open on: the backend's, or JACK's where RtMidi took it."""
        return self.backend.api or ("UNIX_JACK" if self._chose_jack else None)

    def open(self, name: str, *, virtual: bool = False) -> BasePort:
        if self.backend.name == "mido.backends.rtmidi":
            return self._stamp(PolledInput(name, api=self._api(), virtual=virtual))
        return self.backend.open_input(name, virtual=virtual)


class MidoOutputs(MidoInputs):
    """Output ports of a mido backend (see :class:`MidoInputs`)."""

    def names(self) -> list[str]:
        probe = self._rtmidi_probe("MidiOut")
        return list(probe.get_ports()) if probe is not None else list(self.backend.get_output_names())

    def open(self, name: str, *, virtual: bool = False) -> BasePort:
        took = {"api": self._api()} if self.backend.api is None and self._chose_jack else {}
        return self._stamp(self.backend.open_output(name, virtual=virtual, **took))


def match_port(names: list[str], pattern: str) -> str | None:
    """The port called exactly ``pattern``, else the first whose name the regular expression
    ``pattern`` finds (or, if it is not a valid expression, contains it as a substring)."""
    if pattern in names:
        return pattern
    try:
        regex = re.compile(pattern, re.IGNORECASE)
    except re.error:
        return next((n for n in names if pattern.lower() in n.lower()), None)
    return next((n for n in names if regex.search(n)), None)


class ResilientPort:
    """One port, found by name or pattern, kept open across device faults.

    ``pending()`` (input) and ``send()`` (output) never raise. While the device is gone,
    incoming messages cannot arrive and outgoing ones are dropped and counted. Presence is
    checked against ``factory.names()`` at most every ``retry_interval`` seconds: of clock
    time on the caller's thread, or, given a ``supervisor``, on the supervisor's thread, so
    ``send`` and ``pending`` never list, open or close anything.
    """

    def __init__(
        self,
        pattern: str,
        factory: PortFactory,
        clock: Clock,
        *,
        retry_interval: float = 1.0,
        report: Callable[[str], None] = logger.warning,
        supervisor: Supervisor | None = None,
    ) -> None:
        self.pattern = pattern
        self.factory = factory
        self.clock = clock
        self.retry_interval = retry_interval
        self.report = report
        self.port: BasePort | None = None
        self.faults = 0  # times the port was lost
        self.reopened = 0  # times it came back
        self.dropped = 0  # outgoing messages that found no port
        # What the input lost on the way in, over every port it opened (a polled input's
        # counters, midi/polled.py; other backends keep none): polls that found RtMidi's queue
        # full, so messages may have been lost, and bytes that belonged to no message.
        self.full_queues = 0
        self.malformed_bytes = 0
        self._missing_reported = False
        self._last_check = -float("inf")
        self._broken: list[tuple[BasePort, str]] = []  # failed on the creature's thread, to let go
        self._job = None
        self._check(force=True)  # before the run starts: the port is there from the first tick
        if supervisor is not None:
            self._job = supervisor.every(retry_interval, self._check_now, name=f"MIDI port {pattern}")

    @property
    def connected(self) -> bool:
        return self.port is not None

    def pending(self) -> list[mido.Message]:
        """Every message waiting on the input port; never blocks, never raises."""
        self._check()
        port = self.port
        if port is None:
            return []
        full, junk = getattr(port, "full_queues", 0), getattr(port, "malformed_bytes", 0)
        try:
            messages = list(port.iter_pending())
        except Exception as exc:  # any backend error means the device is gone
            self._failed(port, f"{exc}")
            return []
        self.full_queues += getattr(port, "full_queues", 0) - full
        self.malformed_bytes += getattr(port, "malformed_bytes", 0) - junk
        return messages

    def send(self, msg: mido.Message) -> bool:
        """Send ``msg`` if the port is there; return whether it went out."""
        self._check()
        port = self.port
        if port is not None:
            try:
                port.send(msg)
                return True
            except Exception as exc:
                self._failed(port, f"{exc}")
        self.dropped += 1
        return False

    def close(self) -> None:
        if self._job is not None:
            self._job.cancel()
        self._let_go_broken()
        if self.port is not None:
            self._close_quietly(self.port)
            self.port = None

    def _failed(self, port: BasePort, why: str) -> None:
        """A port that raised is dropped at once; letting it go (closing may block) and looking
        again is the supervisor's, when there is one."""
        if self.port is not port:
            return
        self.port = None
        self._broken.append((port, why))
        if self._job is not None:
            self._job.wake()
        else:
            self._let_go_broken()

    def _check(self, *, force: bool = False) -> None:
        if self._job is not None and not force:
            return  # the supervisor looks
        now = self.clock.now()
        if not force and now - self._last_check < self.retry_interval:
            return
        self._last_check = now
        self._check_now()

    def _check_now(self) -> None:
        try:
            names, why = self.factory.names(), "it is no longer listed"
        except Exception as exc:
            names, why = [], f"{exc}"
            logger.debug("listing MIDI ports failed: %s", exc)
        self._let_go_broken()  # after the listing: a send may have failed while it ran
        port = self.port
        if port is not None:
            if port.name not in names or self._stale(port):
                self.port = None
                self._lose(port, why if port.name not in names else "its JACK server went away")
            return
        name = match_port(names, self.pattern)
        if name is None:
            if not self._missing_reported and self.faults == 0:
                self.report(f"MIDI port {self.pattern!r} not found among {names}; will keep looking")
                self._missing_reported = True
            return
        try:
            opened = self.factory.open(name)
        except Exception as exc:
            if not self._missing_reported:
                self.report(f"MIDI port {name!r} could not be opened ({exc}); will keep trying")
                self._missing_reported = True
            return
        self.port = opened
        if self.faults or self._missing_reported:
            self.reopened += 1
            self.report(f"MIDI port {name!r} is back")
        self._missing_reported = False

    def _let_go_broken(self) -> None:
        while self._broken:
            port, why = self._broken.pop(0)
            self._lose(port, why)

    def _lose(self, port: BasePort, why: str) -> None:
        self._close_quietly(port)
        self.faults += 1
        self._missing_reported = True
        self.report(f"MIDI port {port.name!r} lost ({why}); will reopen it when it returns")

    def _stale(self, port: BasePort) -> bool:
        stale = getattr(self.factory, "stale", None)
        return stale is not None and stale(port)

    def _close_quietly(self, port: BasePort) -> None:
        if self._stale(port):
            abandon(port)  # closing it could crash the process
            return
        try:
            port.close()
        except Exception as exc:
            logger.debug("closing a lost MIDI port failed: %s", exc)
