"""Peers of a shared room found without configuration: mDNS / DNS-SD over zeroconf
(``[room.share] discover``; the issue: "peers find each other by mDNS/zeroconf").

Each process announces ``<owner>._creatures-room._udp.local.`` with the room's name and its
port, and browses for the others of the same room. Announcing probes the network for a name
clash and takes about 1.7 s, and resolving a found service waits on the network too, so all of
it runs on a thread of its own; the creature's thread only reads :meth:`Discovery.peers`, a set
copied under a lock.
"""

from __future__ import annotations

import queue
import socket
import threading

SERVICE = "_creatures-room._udp.local."
RESOLVE_MS = 1500
MOST_FOUND = 64
"""Peers kept (as many as a room keeps owners: creatures.room.share.MOST_OWNERS)."""


class DiscoveryUnavailable(RuntimeError):
    """zeroconf is not installed; the message says what to do."""


class Discovery:
    """Announce ``owner`` of ``room`` at ``host:port`` and collect the room's other addresses."""

    def __init__(self, room: str, owner: str, host: str, port: int) -> None:
        try:
            import zeroconf  # noqa: F401
        except ImportError:
            raise DiscoveryUnavailable("[room.share] discover = true needs the zeroconf package "
                                       "(pip install zeroconf); reaching only the configured peers") from None
        self.room, self.port = room, port
        self.name = f"{owner[:50]}.{SERVICE}"
        self.addresses = _addresses(host)
        self._found: dict[str, tuple[str, int]] = {}
        self._lock = threading.Lock()
        self._changes: queue.Queue = queue.Queue()
        self._stop = threading.Event()
        self.error: str | None = None
        self._thread = threading.Thread(target=self._run, name="room discovery", daemon=True)
        self._thread.start()

    def peers(self) -> set[tuple[str, int]]:
        with self._lock:
            return set(self._found.values())

    def _run(self) -> None:
        """Announce, then resolve what the browser finds until closed; any failure is kept in
        :attr:`error` (the run's summary says it) and the room goes on with its configured peers."""
        try:
            self._serve()
        except Exception as exc:  # noqa: BLE001 - a thread's failure must be said, never lost
            self.error = f"mDNS discovery stopped ({type(exc).__name__}: {exc}); reaching only the configured peers"

    def _serve(self) -> None:
        from zeroconf import IPVersion, ServiceBrowser, ServiceInfo, ServiceStateChange, Zeroconf
        try:
            zc = Zeroconf(ip_version=IPVersion.V4Only)
        except OSError as exc:  # no multicast route: say so once, run on configured peers
            self.error = f"mDNS unavailable ({exc}); reaching only the configured peers"
            return
        info = ServiceInfo(SERVICE, self.name, port=self.port, properties={"room": self.room},
                           addresses=[socket.inet_aton(a) for a in self.addresses])
        browser = ServiceBrowser(zc, SERVICE, handlers=[lambda zeroconf, service_type, name, state_change:
                                                        self._changes.put((name, state_change))])
        try:
            zc.register_service(info)
            while not self._stop.is_set():
                try:
                    name, change = self._changes.get(timeout=0.2)
                except queue.Empty:
                    continue
                if name == self.name:
                    continue
                if change is ServiceStateChange.Removed:
                    with self._lock:
                        self._found.pop(name, None)
                    continue
                found = zc.get_service_info(SERVICE, name, timeout=RESOLVE_MS)
                if found is None or found.properties.get(b"room") != self.room.encode() or not found.port:
                    continue
                addresses = sorted(found.parsed_addresses(), key=lambda a: a.startswith("127."))
                if addresses:  # another machine's own address before its loopback
                    with self._lock:
                        if name in self._found or len(self._found) < MOST_FOUND:
                            self._found[name] = (addresses[0], found.port)
        finally:
            browser.cancel()
            try:
                zc.unregister_service(info)
            finally:
                zc.close()

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=5.0)


def _addresses(host: str) -> list[str]:
    """What to announce: the bound host, or every IPv4 address of the machine for 0.0.0.0."""
    if host != "0.0.0.0":
        return [host]
    import ifaddr
    found = [ip.ip for adapter in ifaddr.get_adapters() for ip in adapter.ips if isinstance(ip.ip, str)]
    reachable = [a for a in found if not a.startswith("127.")]  # what another machine can reach
    return reachable or found or ["127.0.0.1"]
