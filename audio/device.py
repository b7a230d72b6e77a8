"""Optional access to PortAudio through sounddevice, with one clear failure message.

sounddevice raises ``OSError: PortAudio library not found`` at *import* time when the system
library is missing, which would otherwise take the whole program down. Live audio goes
through :func:`portaudio` so a missing library or device becomes an
:class:`AudioDeviceUnavailable` that names the fix, and offline paths never import it.

Live streams reach PortAudio through the small :class:`AudioBackend` protocol (the part of
sounddevice they use), so tests can stand a fake device in its place that vanishes and
returns on a simulated clock.
"""

from __future__ import annotations

import atexit
import sys
import weakref
from types import ModuleType
from typing import Any, Protocol

INSTALL_HINT = (
    "install PortAudio (Debian/Ubuntu: apt-get install libportaudio2; macOS: brew install "
    "portaudio), or start a JACK server, then list devices with `creatures devices`"
)


class AudioDeviceUnavailable(RuntimeError):
    """No usable audio backend or device; the offline paths still work."""


class AudioStream(Protocol):
    """A sounddevice stream as live audio uses it."""

    @property
    def active(self) -> bool: ...

    @property
    def closed(self) -> bool: ...

    def start(self) -> None: ...

    def stop(self) -> None: ...

    def close(self) -> None: ...


class AudioBackend(Protocol):
    """What live audio uses of sounddevice: the device list and callback streams.

    ``PortAudioError`` is the exception the backend raises for a device that fails.
    :meth:`refresh` re-reads the device list, so a device plugged in after start-up can be
    found.
    """

    PortAudioError: type[Exception]

    def query_devices(self, device: int | str | None = None, kind: str | None = None) -> Any: ...

    def OutputStream(self, **settings: Any) -> AudioStream: ...  # sounddevice's names

    def InputStream(self, **settings: Any) -> AudioStream: ...

    def refresh(self) -> None: ...


_streams: weakref.WeakSet = weakref.WeakSet()
"""Every stream opened through :class:`PortAudio` in this process (see :meth:`PortAudio.refresh`)."""


def abandoned() -> None:
    """A stream was abandoned, PortAudio never returning from stopping it (its JACK server
    died): ``Pa_Terminate``, which sounddevice calls at exit, would wait for it the same way, so
    that exit handler is dropped and the process can end once it has saved what it keeps."""
    handler = getattr(sys.modules.get("sounddevice"), "_exit_handler", None)  # sounddevice's own, since 0.3
    if handler is not None:
        atexit.unregister(handler)


class PortAudio:
    """sounddevice as an :class:`AudioBackend`.

    PortAudio reads its device list once, when it is initialised: a device unplugged stays
    listed and one plugged in later is not seen until PortAudio is terminated and
    initialised again (python-sounddevice issues #47, #125). Doing that closes every open
    stream, so :meth:`refresh` does it only while no stream opened here is open; a device
    that returns while another stream of the process keeps playing is found only if it
    opens under its old entry (ALSA opens devices by name, so a card that comes back in
    the same slot does).
    """

    def __init__(self, sd: ModuleType) -> None:
        self._sd = sd
        self.PortAudioError = sd.PortAudioError

    def query_devices(self, device: int | str | None = None, kind: str | None = None) -> Any:
        return self._sd.query_devices(device, kind)

    def OutputStream(self, **settings: Any) -> AudioStream:
        return self._track(self._sd.OutputStream(**settings))

    def InputStream(self, **settings: Any) -> AudioStream:
        return self._track(self._sd.InputStream(**settings))

    def refresh(self) -> None:
        """Re-read the device list (about 25 ms without devices), unless a stream is open."""
        if all(stream.closed for stream in _streams):
            self._sd._terminate()
            self._sd._initialize()

    @staticmethod
    def _track(stream: AudioStream) -> AudioStream:
        _streams.add(stream)
        return stream


def start_stream(backend: AudioBackend, kind: str, **settings: Any) -> AudioStream:
    """A started ``kind`` ('input'/'output') stream. One that opens but will not start is
    closed again before the error goes on: an open stream would block :meth:`PortAudio.refresh`."""
    stream = (backend.InputStream if kind == "input" else backend.OutputStream)(**settings)
    try:
        stream.start()
    except backend.PortAudioError:
        stream.close()
        raise
    return stream


def sounddevice_module() -> ModuleType:
    """Import and return :mod:`sounddevice`, or raise :class:`AudioDeviceUnavailable`."""
    try:
        import sounddevice
    except OSError as exc:  # PortAudio shared library missing
        raise AudioDeviceUnavailable(f"live audio unavailable: {exc}; {INSTALL_HINT}") from None
    return sounddevice


def portaudio() -> PortAudio:
    """The real backend, or :class:`AudioDeviceUnavailable` when PortAudio is missing."""
    return PortAudio(sounddevice_module())


def find_device(name: str | int | None, *, kind: str, backend: AudioBackend | None = None) -> int | None:
    """Resolve a device by index or case-insensitive name fragment for ``kind`` 'input'/'output'.

    ``None`` means the system default. Raises :class:`AudioDeviceUnavailable` naming the
    device and how to list devices when nothing matches.
    """
    backend = backend or portaudio()
    channels_key = "max_input_channels" if kind == "input" else "max_output_channels"
    devices = [d for d in backend.query_devices() if d[channels_key] > 0]
    if not devices:
        raise AudioDeviceUnavailable(f"no audio {kind} devices found; {INSTALL_HINT}")
    if name is None:
        return None
    if isinstance(name, int):
        if any(d["index"] == name for d in devices):
            return name
    else:
        for d in devices:
            if name.lower() in d["name"].lower():
                return int(d["index"])
    raise AudioDeviceUnavailable(
        f"audio {kind} device {name!r} not found (have: {[d['name'] for d in devices]}); "
        "list devices with `creatures devices`"
    )


def device_rate(name: str | int | None, *, kind: str, backend: AudioBackend | None = None) -> int | None:
    """The native sample rate of a device (``None`` = the default one), or None when there is
    no such device: JACK and most interfaces run at one rate and refuse others."""
    try:
        backend = backend or portaudio()
    except AudioDeviceUnavailable:
        return None
    try:
        index = find_device(name, kind=kind, backend=backend)
        return int(backend.query_devices(index, kind=kind)["default_samplerate"])
    except (AudioDeviceUnavailable, backend.PortAudioError):  # absent, or listed a moment ago and gone now
        return None
