"""The installation config: what ``creatures run`` and ``creatures offline`` read.

Every key is documented in ``docs/config.md``; the field descriptions here are the source
of that page. Unknown keys are errors (a typo must never be silently ignored in a gallery).
"""

from __future__ import annotations

import difflib
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, Field

from creatures.authored.include import expand_includes, expand_likes
from creatures.authored.plugins import load_plugins
from creatures.authored.registry import PluginError
from creatures.config import ConfigError, config_error, read_toml, validate
from creatures.kinds import CreatureSpec, load_all


class Strict(BaseModel):
    model_config = ConfigDict(extra="forbid")


class AudioSection(Strict):
    """Sample rate, live audio devices, and whether creatures hear each other."""

    sample_rate: int = Field(22050, ge=8000, le=192000, description="rate of synthesis and analysis, Hz")
    block: int = Field(512, ge=32, le=16384, description="frames per audio block")
    input_device: str | int | None = Field(None, description="live input device (name fragment or index, or "
                                                            "'default' for the system's); none = no microphone")
    output_device: str | int | None = Field(None, description="live output device (name fragment or index)")
    air: bool = Field(False, description="creatures hear each other's voices (and their own) through "
                                         "the room, one tick late, as well as the input")
    transcribe: bool | None = Field(None, description="hear the pitched notes of the input audio (file or "
                                                      "microphone) as note events; unset = only when the "
                                                      "run has no MIDI note input")


class MidiSection(Strict):
    """Live MIDI ports (absent ports are reported and looked for again)."""

    input_port: str | None = Field(None, description="live MIDI input port name or pattern")
    output_port: str | None = Field(None, description="live MIDI output port name or pattern")


class OscSection(Strict):
    """OSC (UDP) between colonies and to other tools."""

    host: str = Field("127.0.0.1", description="address OSC listeners bind to (loopback by default)")
    port: int | None = Field(None, ge=1024, le=65535, description="UDP port to listen on; none = no OSC")
    peers: list[str] = Field(default_factory=list, description="host:port of other colonies to send notes to")


class InputSection(Strict):
    """What an offline run hears when the command line gives no files."""

    audio: str | None = Field(None, description="recorded audio fed offline (path relative to the config)")
    midi: str | None = Field(None, description="recorded MIDI fed offline (path relative to the config)")
    generate: str = Field("phrase", pattern="^(phrase|speech|none)$",
                          description="input generated when no file is given: 'phrase' (three note "
                                      "fragments, as notes and as tones), 'speech' (the poem Ozymandias "
                                      "read by formant voices, audio only) or 'none'")


class OutputSection(Strict):
    """What an offline run writes into its output directory."""

    midi: bool = Field(True, description="write out.mid")
    wav: bool = Field(True, description="write out.wav")
    frames: bool = Field(False, description="render the bodies to PNG frames (needs EGL or OSMesa)")
    video: bool = Field(False, description="also encode frames to out.mp4")
    fps: float = Field(12.0, gt=0, le=120, description="frame rate of rendered frames")
    width: int = Field(320, ge=16, le=3840, description="frame width, pixels")
    height: int = Field(240, ge=16, le=2160, description="frame height, pixels")
    report: bool = Field(True, description="write report/ (plots and index.html) after an offline run")


class Installation(Strict):
    title: str = Field(description="name of the installation")
    description: str = Field("", description="free text shown in reports")
    seed: int = Field(0, description="seed of every random choice in the run")
    tick: float = Field(0.02, gt=0.0005, le=0.5, description="behaviour tick, seconds")
    duration: float = Field(60.0, gt=0, description="offline run length in simulated seconds (default)")
    save_every: float = Field(60.0, gt=0, description="seconds between state saves in live runs")
    state: str | None = Field(None, description="directory for saved creature state (live runs)")
    audio: AudioSection = AudioSection()
    midi: MidiSection = MidiSection()
    osc: OscSection = OscSection()
    input: InputSection = InputSection()
    output: OutputSection = OutputSection()
    include: list[str] = Field(default_factory=list, description="creature files ([[creature]] tables) "
                                                                 "included, relative to this file")
    plugins: list[str] = Field(default_factory=list, description="Python files of actions, percepts, models "
                                                                 "or kinds to register, relative to this file")
    creature: list[dict[str, Any]] = Field(min_length=1, description="the creatures, one [[creature]] table each")


class LoadedInstallation:
    """A validated installation: its top-level settings and each creature's typed spec."""

    def __init__(self, path: Path, settings: Installation, specs: list[CreatureSpec]) -> None:
        self.path = path
        self.settings = settings
        self.specs = specs

    def resolve(self, relative: str | None) -> Path | None:
        """A path from the config, relative to the config's own directory."""
        return None if relative is None else (self.path.parent / relative).resolve()


def load_installation(path: str | Path) -> LoadedInstallation:
    """Read and validate an installation config; :class:`ConfigError` names key and line."""
    path = Path(path).resolve()
    data, where = read_toml(path)
    includes = data.get("include", [])
    expand_includes(data, where, path)
    expand_likes(data, where, path)
    data["include"] = includes
    settings = validate(Installation, data, where, path)
    load_plugins(settings.plugins, path, where)
    try:
        kinds = load_all()
    except PluginError as exc:  # an installed package's entry point that does not import
        raise ConfigError(path, str(exc)) from None
    specs: list[CreatureSpec] = []
    names: set[str] = set()
    for i, table in enumerate(settings.creature):
        kind = table.get("kind")
        if not isinstance(kind, str) or kind not in kinds:  # kind = [] must not crash the lookup
            close = difflib.get_close_matches(str(kind), list(kinds), n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else f" (choose from {sorted(kinds)})"
            raise config_error(path, where, ("creature", i, "kind"), f"unknown creature kind {kind!r}{hint}")
        spec = validate(kinds[kind].Spec, table, where, path, prefix=("creature", i))
        check = getattr(spec, "check_references", None)  # kinds that name parts resolve them now
        if check is not None:
            check(path, where, ("creature", i))
        if spec.name in names:
            raise config_error(path, where, ("creature", i, "name"), f"duplicate creature name {spec.name!r}")
        names.add(spec.name)
        specs.append(spec)
    for key in ("audio", "midi"):
        file = getattr(settings.input, key)
        if file is not None and not (path.parent / file).exists():
            raise config_error(path, where, ("input", key), f"file not found: {file}")
    return LoadedInstallation(path, settings, specs)


__all__ = ["ConfigError", "Installation", "LoadedInstallation", "load_installation"]
