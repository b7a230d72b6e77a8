"""Where a value sits in a JSON text, so a malformed motor file can name the line.

``json.loads`` keeps no positions, and searching the text for a value's spelling finds
the wrong line whenever that spelling repeats (two nodes with the same rotations). The
value is found instead by its path — object keys and list indices from the top — walking
the text with the stdlib decoder and skipping sibling values with ``raw_decode``. This
runs only when an error is being reported, so loading a good file costs nothing extra.
"""

from __future__ import annotations

import json
import re
from json.decoder import scanstring

_DECODER = json.JSONDecoder()
_SPACE = re.compile(r"[ \t\n\r]*")

JsonPath = tuple[str | int, ...]
"""Object keys and list indices from the top of a JSON document to one value."""


def line_at(text: str, path: JsonPath) -> int | None:
    """1-based line where the value at ``path`` starts in JSON ``text``.

    When the path leads nowhere (a missing key, an index past the end) the line of the
    deepest value that does exist is given instead: a node missing a key is reported on
    the node's own line. ``None`` only when ``text`` is not JSON at all.
    """
    try:
        start = _skip(text, 0)
        _DECODER.raw_decode(text, start)
        for step in path:
            child = _child(text, start, step)
            if child is None:
                break
            start = child
    except (ValueError, IndexError):
        return None
    return text.count("\n", 0, start) + 1


def _skip(text: str, pos: int) -> int:
    return _SPACE.match(text, pos).end()


def _child(text: str, pos: int, step: str | int) -> int | None:
    """Start of member ``step`` of the object or array starting at ``pos`` (the last of
    duplicate keys, as ``json.loads`` keeps), or ``None``."""
    opener = text[pos]
    if opener not in "{[" or (opener == "{") != isinstance(step, str):
        return None
    found = None
    pos = _skip(text, pos + 1)
    index = 0
    while text[pos] not in "]}":
        if opener == "{":
            key, pos = scanstring(text, pos + 1)
            pos = _skip(text, _skip(text, pos) + 1)  # past the colon
            hit = key == step
        else:
            hit = index == step
        if hit:
            found = pos
            if opener == "[":
                return found
        _, pos = _DECODER.raw_decode(text, pos)
        pos = _skip(text, pos)
        if text[pos] == ",":
            pos = _skip(text, pos + 1)
        index += 1
    return found
