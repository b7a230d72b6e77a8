"""Optional access to PortAudio through sounddevice, with one clear failure message.

sounddevice raises ``OSError: PortAudio library not found`` at *import* time when the system
library is missing, which would otherwise take the whole program down. Live audio goes
through :func:`sounddevice_module` so a missing library or device becomes an
:class:`AudioDeviceUnavailable` that names the fix, and offline paths never import it.
"""

from __future__ import annotations

from types import ModuleType

INSTALL_HINT = (
    "install PortAudio (Debian/Ubuntu: apt-get install libportaudio2; macOS: brew install "
    "portaudio), or start a JACK server, then list devices with `creatures devices`"
)


class AudioDeviceUnavailable(RuntimeError):
    """No usable audio backend or device; the offline paths still work."""


def sounddevice_module() -> ModuleType:
    """Import and return :mod:`sounddevice`, or raise :class:`AudioDeviceUnavailable`."""
    try:
        import sounddevice
    except OSError as exc:  # PortAudio shared library missing
        raise AudioDeviceUnavailable(f"live audio unavailable: {exc}; {INSTALL_HINT}") from None
    return sounddevice


def find_device(name: str | int | None, *, kind: str) -> int | None:
    """Resolve a device by index or case-insensitive name fragment for ``kind`` 'input'/'output'.

    ``None`` means the system default. Raises :class:`AudioDeviceUnavailable` naming the
    device and how to list devices when nothing matches.
    """
    sd = sounddevice_module()
    channels_key = "max_input_channels" if kind == "input" else "max_output_channels"
    devices = [d for d in sd.query_devices() if d[channels_key] > 0]
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


def device_rate(name: str | int | None, *, kind: str) -> int | None:
    """The native sample rate of a device (``None`` = the default one), or None when there is
    no such device: JACK and most interfaces run at one rate and refuse others."""
    try:
        index = find_device(name, kind=kind)
        return int(sounddevice_module().query_devices(index, kind=kind)["default_samplerate"])
    except AudioDeviceUnavailable:
        return None
