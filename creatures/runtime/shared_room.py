"""A live run's side of a shared room (``[room.share]``): the socket, discovery and Link set up
before the first tick, attached to the session's stage, and closed (with a goodbye) after the
last. Offline runs have no shared room: their clock is not the others' (:func:`offline_note`).
"""

from __future__ import annotations

import errno
import socket
from typing import TYPE_CHECKING, Callable

from creatures.room.discovery import Discovery, DiscoveryUnavailable
from creatures.room.link import LinkBeat, LinkUnavailable
from creatures.room.share import PeerError, RoomShare

if TYPE_CHECKING:
    from creatures.config import ConfigError
    from creatures.runtime.schema import LoadedInstallation
    from creatures.runtime.session import Session


class SharedRoom:
    """The share, with its discovery and its Link session, for one live run."""

    def __init__(self, share: RoomShare, discovery: Discovery | None, link: LinkBeat | None) -> None:
        self.share, self.discovery, self.link = share, discovery, link

    def counts(self) -> dict[str, object]:
        counts = self.share.counts()
        if self.link is not None:
            counts.update(link_peers=self.link.peers, tempo=round(self.link.tempo, 3))
        if self.discovery is not None and self.discovery.error:
            counts["discovery"] = self.discovery.error
        return counts

    def close(self) -> None:
        self.share.close()
        if self.discovery is not None:
            self.discovery.close()
        if self.link is not None:
            self.link.close()


def open_shared_room(inst: "LoadedInstallation", session: "Session", epoch: float,
                     say: Callable[[str], None]) -> SharedRoom | None:
    """Join the room ``[room.share]`` names (None without one); a busy port or a host that
    cannot be bound is the config's error at its key, before anything runs."""
    room = inst.settings.room
    if room is None or room.share is None or session.stage is None:
        return None
    spec = room.share
    link = None
    if spec.link:
        try:
            link = LinkBeat(spec.tempo)
        except LinkUnavailable as exc:
            say(str(exc))
    try:
        share = RoomShare(spec, [c.name for c in session.creatures], epoch, timeline=link)
    except (OSError, PeerError) as exc:
        if link is not None:
            link.close()
        if isinstance(exc, PeerError):
            raise inst.error(("room", "share", "peers", exc.index), str(exc)) from None
        raise _where(inst, exc, spec.port) from None
    discovery = None
    if spec.discover:
        try:
            discovery = Discovery(spec.room, share.owner, spec.host, share.port)
            share.discovered = discovery.peers
        except DiscoveryUnavailable as exc:
            say(str(exc))
    session.stage.attach(share, session.world)
    say(f"room {spec.room!r} shared on {spec.host}:{share.port} as {share.owner}"
        f"{' (Ableton Link)' if link is not None else ''}")
    return SharedRoom(share, discovery, link)


def check_share_port(inst: "LoadedInstallation") -> None:
    """The ``[room.share]`` port bound and let go, so that one in use is said before ``creatures
    run`` makes and locks the state folder (it was said only once the run had set up its
    session, its devices and the folder); port 0 takes any free one and is not checked."""
    room = inst.settings.room
    spec = room.share if room is not None else None
    if spec is None or not spec.port:
        return
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        try:
            probe.bind((spec.host, spec.port))
        except OSError as exc:
            raise _where(inst, exc, spec.port) from None


def _where(inst: "LoadedInstallation", exc: OSError, port: int) -> "ConfigError":
    if exc.errno == errno.EADDRINUSE:
        return inst.error(("room", "share", "port"), f"port {port} is already in use (another process of the "
                                                     "room or another program listens there; choose another)")
    return inst.error(("room", "share", "host"), f"cannot listen on it ({exc.strerror or exc})")


def offline_note(inst: "LoadedInstallation") -> str | None:
    """What an offline run says of a ``[room.share]``: it is ignored, and why."""
    room = inst.settings.room
    if room is None or room.share is None:
        return None
    return ("[room.share] is for live runs: offline, the room holds only this run's creatures "
            "(its clock is not the other processes')")
