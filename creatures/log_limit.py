"""Library log output under attack stays small: one line per cause per interval, with a count.

python-osc logs a warning for every unknown type tag it meets, so one 1 KB packet made about
1,000 lines and 2,000 such packets a second wrote 48 MB to stderr in 5 s, and the loop that
wrote them lost two ticks in three. Whatever a library logs, the first record of a cause (its
logger and the line of code that logged it) is shown; more of the same cause within
:data:`INTERVAL` seconds are counted, not shown, and the next line of that cause says how many
were left out. The CLI installs this (:func:`install`) for its runs; the total left out is in
the end-of-run summary and the ``network`` events (:func:`suppressed`).
"""

from __future__ import annotations

import logging
import sys
import time
from typing import Callable

INTERVAL = 10.0
"""Seconds during which further lines of one cause are counted instead of shown."""

Cause = tuple[str, str, int]


class RateLimit(logging.Filter):
    """A handler filter: one record per cause per ``interval`` seconds of ``clock``."""

    def __init__(self, interval: float = INTERVAL, clock: Callable[[], float] = time.monotonic) -> None:
        super().__init__()
        self.interval = interval
        self.clock = clock
        self.suppressed = 0  # records left out, in all
        self._windows: dict[Cause, list] = {}  # cause -> [end of its window, left out in it]

    def filter(self, record: logging.LogRecord) -> bool:
        cause = (record.name, record.pathname, record.lineno)
        now = self.clock()
        window = self._windows.get(cause)
        if window is not None and now < window[0]:
            window[1] += 1
            self.suppressed += 1
            return False
        if window is not None and window[1]:
            record.msg = f"{record.getMessage()} (and {window[1]} more like it in {self.interval:g} s, not shown)"
            record.args = None
        self._windows[cause] = [now + self.interval, 0]
        return True

    def reset(self) -> None:
        """Start counting afresh (a new command in the same process: what an earlier one left
        out is not this one's to report)."""
        self.suppressed = 0
        self._windows.clear()

    def pending(self) -> list[str]:
        """What was left out since each cause's last shown line (for the end of a run)."""
        return [f"{n} more log line(s) from {name} ({path.rsplit('/', 1)[-1]}:{line}) not shown"
                for (name, path, line), (_, n) in self._windows.items() if n]


class _Stderr(logging.StreamHandler):
    """Writes to whatever ``sys.stderr`` is when a record comes (tests and embedding programs
    swap it; a handler holding the stream of its creation would write to a closed file)."""

    @property
    def stream(self):  # type: ignore[override]
        return sys.stderr

    @stream.setter
    def stream(self, _: object) -> None:
        pass


_installed: RateLimit | None = None


def install(interval: float = INTERVAL) -> RateLimit:
    """Send every warning and error to stderr through one :class:`RateLimit` (once per process;
    the root logger gets this handler, so python-osc's ``logging.warning`` adds no other)."""
    global _installed
    if _installed is None:
        _installed = RateLimit(interval)
        handler = _Stderr()
        handler.setFormatter(logging.Formatter("%(levelname)s %(name)s: %(message)s"))
        handler.addFilter(_installed)
        logging.getLogger().addHandler(handler)
    return _installed


def suppressed() -> int:
    """Log records left out so far by the installed limit (0 when none is installed)."""
    return _installed.suppressed if _installed is not None else 0
