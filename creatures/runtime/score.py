"""``out.mid`` as a DAW opens it: what was heard, each creature's part, the heard tempo.

A composer who drags ``out.mid`` into a DAW should find the run laid out as it happened: a
tempo map that follows the pulse the colony heard (:class:`~creatures.runtime.pulse.HeardPulse`,
so bars line up with the music rather than with 120 bpm), a track called ``input`` with the
notes heard from outside, then one track per creature named after it, opening with its
channel's setup (program, pan, volume: :mod:`midi.channel_setup`) so each part plays back in
the voice it had. Every track sounds a key once at a time: a key heard struck again before its
note ended is re-struck (:func:`midi.notes.restrike`), as the scheduler re-strikes the
creatures' own. Creatures that share a channel share a track (``ada+bo``). A track no creature
plays (messages sent on a channel no creature has) is named by its channel as the DAW that
opens the file counts them, 1–16: the config's ``channel = 9`` is the DAW's "channel 10".
"""

from __future__ import annotations

import os
from typing import Iterable

from creatures.runtime.world import World
from midi.files import TICKS_PER_BEAT, TempoMap, write_tracks
from midi.notes import TimedMessage, to_messages


def heard_tempo(world: World, origin: float = 0.0) -> TempoMap:
    """The tempo map of what the colony heard (120 bpm until its pulse was trusted), its
    times counted from ``origin``."""
    return TempoMap.from_seconds(TICKS_PER_BEAT, [(max(0.0, t - origin), bpm) for t, bpm in world.tempo])


def write_score(path: str | os.PathLike, world: World, played: Iterable[TimedMessage], origin: float = 0.0) -> None:
    """Write ``played`` (every message the colony sent, as its sink kept them) and the notes
    the world heard to ``path``; the world must have been recording (``world.recording``).
    Times count from ``origin`` (a live run's clock time when it began)."""
    names: dict[int, list[str]] = {}
    for creature in world.creatures:
        names.setdefault(creature.spec.channel, []).append(creature.name)
    parts: dict[int, list[TimedMessage]] = {channel: [] for channel in names}
    for t, msg in played:
        parts.setdefault(getattr(msg, "channel", 0), []).append((max(0.0, t - origin), msg))
    heard = sorted(world.heard, key=lambda note: note.time)
    tracks = [("input", [(max(0.0, t - origin), msg) for t, msg in to_messages(heard)])]
    tracks += [("+".join(names.get(channel, [f"channel {channel + 1}"])), parts[channel]) for channel in sorted(parts)]
    write_tracks(path, tracks, tempo=heard_tempo(world, origin))
