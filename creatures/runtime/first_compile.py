"""Saying why the first run on a machine is slow to start.

numba compiles each ``@njit(cache=True)`` kernel the first time it is called and caches it
(beside the code, or in ``NUMBA_CACHE_DIR``); later runs load it. A first 60-second offline run
of a room piece took 25 s against 2–3 s after, and a new user saw nothing that said why (a
new-user trial). numba announces a compile, never a cache load, as its ``numba:compile``
event, so the first one in a run is said once, to a terminal only: a test's or a service's
captured stderr gets no line it did not ask for.
"""

from __future__ import annotations

import sys
from typing import Callable

from numba.core import event

NOTE = ("compiling the numeric kernels (numba) for this machine: the first run, or the first "
        "after an update, waits 20–30 s for it; later runs load them from the cache")


class _FirstCompile(event.Listener):
    """Says :data:`NOTE` at the first compile it hears of, then nothing."""

    def __init__(self, say: Callable[[str], None]) -> None:
        self.say = say
        self.said = False

    def on_start(self, ev: event.Event) -> None:
        if not self.said:
            self.said = True
            self.say(NOTE)

    def on_end(self, ev: event.Event) -> None:
        pass


def say_first_compile() -> Callable[[], None]:
    """Say the first compile of this command on a terminal's stderr; returns the undo."""
    if not sys.stderr.isatty():
        return lambda: None
    listener = _FirstCompile(lambda text: print(f"creatures: {text}", file=sys.stderr, flush=True))
    event.register("numba:compile", listener)
    return lambda: event.unregister("numba:compile", listener)
