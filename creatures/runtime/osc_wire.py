"""OSC 1.0 messages and bundles as bytes, built with ``struct`` and numpy.

python-osc's builders are the right tool for a note now and then (:mod:`midi.osc`), but they
cost some 20 µs a message in Python; the body stream sends a pose for every creature every
frame (50 creatures at 60 Hz: 3000 bundles a second), so its messages are put together here
from parts computed once (an address and its type tags are the same every frame) and arrays
packed in one call. What comes out is plain OSC 1.0: python-osc, liblo, TouchDesigner and
Max read it (the tests decode it with python-osc).
"""

from __future__ import annotations

import struct

import numpy as np

IMMEDIATELY = b"\x00\x00\x00\x00\x00\x00\x00\x01"
"""The OSC time tag meaning "at once"."""

BUNDLE = b"#bundle\x00"


def osc_string(text: str) -> bytes:
    """``text`` as an OSC string: UTF-8, a NUL, padded with NULs to a multiple of 4 bytes."""
    data = text.encode()
    return data + b"\x00" * (4 - len(data) % 4)


def head(address: str, tags: str) -> bytes:
    """The start of a message: its address and type tags (``tags`` without the comma)."""
    return osc_string(address) + osc_string("," + tags)


def message(address: str, *args: int | float | str) -> bytes:
    """One message of ints (``i``), floats (``f``) and strings (``s``), for what is sent rarely."""
    tags, body = [], []
    for arg in args:
        if isinstance(arg, str):
            tags.append("s")
            body.append(osc_string(arg))
        elif isinstance(arg, (int, np.integer)) and not isinstance(arg, bool):
            tags.append("i")
            body.append(struct.pack(">i", int(arg)))
        else:
            tags.append("f")
            body.append(struct.pack(">f", float(arg)))
    return head(address, "".join(tags)) + b"".join(body)


def floats(values: np.ndarray) -> bytes:
    """An array's values as big-endian float32 arguments, in one call."""
    return np.asarray(values, dtype=">f4").tobytes()


def bundle(messages: list[bytes]) -> bytes:
    """``messages`` in one bundle, time-tagged "immediately": one datagram, taken in as one."""
    parts = [BUNDLE, IMMEDIATELY]
    for m in messages:
        parts.append(struct.pack(">i", len(m)))
        parts.append(m)
    return b"".join(parts)
