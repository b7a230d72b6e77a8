"""``out.mid`` as a DAW opens it: what was heard, each creature's part, the heard tempo.

A composer who drags ``out.mid`` into a DAW should find the run laid out as it happened: a
tempo map that follows the pulse the colony heard (:class:`~creatures.runtime.pulse.HeardPulse`,
so bars line up with the music rather than with 120 bpm), a track called ``input`` with the
notes heard from outside, then one track per creature named after it, opening with its
channel's setup (program, pan, volume: :mod:`midi.channel_setup`) so each part plays back in
the voice it had. Creatures that share a channel share a track (``ada+bo``).
"""

from __future__ import annotations

import os

from creatures.runtime.world import World
from midi.files import TempoMap, write_tracks
from midi.notes import TimedMessage, to_messages

TICKS_PER_BEAT = 480


def heard_tempo(world: World) -> TempoMap:
    """The tempo map of what the colony heard (120 bpm until its pulse was trusted)."""
    return TempoMap.from_seconds(TICKS_PER_BEAT, world.tempo)


def write_score(path: str | os.PathLike, world: World, played: list[TimedMessage]) -> None:
    """Write ``played`` (every message the colony sent, as its sink kept them) and the notes
    the world heard to ``path``; the world must have been recording (``world.recording``)."""
    names: dict[int, list[str]] = {}
    for creature in world.creatures:
        names.setdefault(creature.spec.channel, []).append(creature.name)
    parts: dict[int, list[TimedMessage]] = {channel: [] for channel in names}
    for item in played:
        parts.setdefault(getattr(item[1], "channel", 0), []).append(item)
    tracks = [("input", to_messages(sorted(world.heard, key=lambda note: note.time)))]
    tracks += [("+".join(names.get(channel, [f"channel {channel + 1}"])), parts[channel]) for channel in sorted(parts)]
    write_tracks(path, tracks, tempo=heard_tempo(world))
