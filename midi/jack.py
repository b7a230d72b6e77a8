"""Whether the JACK server behind this process's rtmidi clients still runs, and what to do
with the clients of one that died.

A JACK server that dies takes every rtmidi client of the process with it, silently: the kept
client still lists the old ports, a send still succeeds, the port still says it is open
(measured with a dummy server killed by SIGKILL). :class:`JackPulse` notices, and a client of
the lost server is then abandoned, never closed (:func:`abandon`). :mod:`midi.ports` asks it
before each listing of a JACK backend's ports.
"""

from __future__ import annotations

import ctypes
import itertools
import logging
import os
import time
from typing import Callable

from midi.polled import api_id

logger = logging.getLogger(__name__)

MISSED = 2
"""Pulses in a row not back within ``patience`` that mean the server is gone."""


def abandon(obj: object) -> None:
    """Keep ``obj`` (an rtmidi client, or a port holding one) whose JACK server died, for the
    life of the process, never closed nor freed.

    Once a JACK server has gone, the next client the process opens makes libjack free every
    client of the dead one; closing or deleting one of those afterwards crashed the process
    (segfault, 3 of 3 trials), and closing an output before that waited 1 s. Python would close
    it when collecting it, even at exit, so one reference is leaked on purpose: a few hundred
    bytes per server restart.
    """
    ctypes.pythonapi.Py_IncRef(ctypes.py_object(obj))


class JackPulse:
    """Whether the JACK server behind this process's rtmidi clients still runs.

    A client of a server that died still lists the old ports, takes every message and says its
    port is open; only a new client finds the server gone, and making one holds the GIL ~45 ms
    (measured: too long to do every second beside a creature's tick). So two clients of our
    own pass an active-sensing byte round the server's graph (one cycle, ~12 ms) from one look
    to the next; two in a row not back after ``patience`` seconds mean the server is gone (one
    may be a live server stalled by a loaded machine, and a server judged gone costs every
    client of the process: they are abandoned, not closed, for the process's life). Every rtmidi
    client made before is then stale: :attr:`generation` counts the servers lost, and a client
    stamped with an older one must be neither used nor closed (:func:`abandon`). While the
    server is away each look tries a new pair, which fails in ~4 ms.
    """

    _tags = itertools.count()

    def __init__(self, api: str = "UNIX_JACK", *, patience: float = 0.5,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.api = api
        self.patience = patience
        self.clock = clock
        self.generation = 0  # servers lost so far
        self._pair = None  # (MidiOut, MidiIn) connected through the server
        self._sent: float | None = None  # when the pulse still out was sent
        self._missed = 0  # pulses in a row not back in time

    def alive(self) -> bool:
        """Look once (never waits): False from the look that finds a pulse lost until a new
        pair of clients can be made."""
        if self._pair is None:
            try:
                self._pair = self._open_pair()
            except Exception as exc:
                logger.debug("no JACK server: %s", exc)
                return False
            self._sent = None
        out, ear = self._pair
        while ear.get_message() is not None:
            self._sent, self._missed = None, 0
        now = self.clock()
        if self._sent is not None and now - self._sent >= self.patience:
            self._missed += 1
            if self._missed >= MISSED:
                self._missed = 0
                for client in self._pair:
                    abandon(client)
                self._pair = None
                self.generation += 1
                return False
            self._sent = None  # late: another goes out
        if self._sent is None:
            out.send_message([0xFE])
            self._sent = now
        return True

    def _open_pair(self):
        import rtmidi

        tag = f"pulse-{os.getpid()}-{next(self._tags)}"
        made = []
        try:
            made.append(rtmidi.MidiOut(rtapi=api_id(self.api), name="creatures-pulse"))
            made[0].open_virtual_port(tag)
            made.append(rtmidi.MidiIn(rtapi=api_id(self.api), name="creatures-pulse", queue_size_limit=64))
            made[1].ignore_types(sysex=True, timing=True, active_sense=False)
            names = made[1].get_ports()
            made[1].open_port(next(i for i, n in enumerate(names) if n.endswith(":" + tag)))
        except Exception:
            for client in made:  # the server may have died meanwhile: closing is not safe
                abandon(client)
            raise
        return tuple(made)


_pulses: dict[str, JackPulse] = {}


def jack_pulse(api: str = "UNIX_JACK") -> JackPulse:
    """The process's one :class:`JackPulse` for ``api`` (libjack's state is the process's)."""
    return _pulses.setdefault(api, JackPulse(api))
