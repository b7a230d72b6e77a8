"""What a gallery machine on a network must not do: execute code from a file, listen beyond
the machine unless told to, or read unbounded input. The bounds, in one place:

* OSC datagram: ``midi.osc.MAX_PACKET`` = 1024 bytes (larger ones are dropped and counted);
* MIDI sysex: ``midi.parser.MAX_SYSEX`` = 64 KiB;
* state file (JSON) and unpacked NPZ arrays: ``creatures.persist.MAX_STATE_BYTES`` = 256 MiB;
* config file: ``creatures.config.MAX_CONFIG_BYTES`` = 1 MiB;
* sound file: a declared rate below ``audio.sources.MIN_FILE_RATE`` = 1 kHz is refused (so
  resampling grows a file at most 22×, not 22,050×), and one above ``MAX_FILE_RATE`` = 768 kHz
  (a damaged header; tests/test_audio_sources.py);
* events log: ``EventLog(max_bytes=64 MiB, backups=5)``, rotated (see ``test_soak.py``).
"""

from __future__ import annotations

import io
import pickle
import socket
import zipfile

import numpy as np
import pytest
import soundfile

from audio.sources import MIN_FILE_RATE, AudioFileError, load_audio
from creatures import persist
from creatures.clock import SimulatedClock
from creatures.config import MAX_CONFIG_BYTES, ConfigError
from creatures.motor.animations import creature_skeleton, strike
from creatures.motor.graph import MotorGraph
from creatures.persist import MAX_STATE_BYTES, StateFileError, load_json, load_npz, save_json
from creatures.runtime.schema import OscSection, load_installation
from midi.osc import MAX_PACKET, OscListener
from test_creature_persistence import build, live


class Payload:
    """Unpickling this writes a marker file: proof that a loader executed code."""

    def __init__(self, marker) -> None:
        self.marker = str(marker)

    def __reduce__(self):
        return (open, (self.marker, "w"))


def test_npz_with_an_object_array_is_refused_without_running_it(tmp_path):
    marker = tmp_path / "executed"
    path = tmp_path / "evil.npz"
    np.savez(path, ok=np.arange(3.0), evil=np.array([Payload(marker)], dtype=object))
    with pytest.raises(StateFileError, match="evil.npz"):
        load_npz(path)
    assert not marker.exists()


def test_a_pickle_is_not_a_state_file(tmp_path):
    marker = tmp_path / "executed"
    path = tmp_path / "state.json"
    path.write_bytes(pickle.dumps(Payload(marker)))
    with pytest.raises(StateFileError, match="state.json"):
        load_json(path, kind="creature")
    assert not marker.exists()


def test_state_and_graph_files_load_without_unpickling(tmp_path, monkeypatch):
    creature = build()()
    live(creature, 2.0)
    creature.save(tmp_path / "singer.json")
    graph = MotorGraph.build(strike(creature_skeleton()), k=3)
    graph.save(tmp_path / "graph.json")

    def refuse(*args, **kwargs):
        raise AssertionError("a loader unpickled something")

    for name in ("load", "loads", "Unpickler"):
        monkeypatch.setattr(pickle, name, refuse)
    type(creature).load(tmp_path / "singer.json", build())
    assert len(MotorGraph.load(tmp_path / "graph.json")) == len(graph)


def test_listeners_bind_loopback_by_default():
    assert OscSection().host == "127.0.0.1"
    listener = OscListener(SimulatedClock())
    try:
        assert listener.socket.getsockname()[0] == "127.0.0.1"
    finally:
        listener.close()


def test_oversize_datagrams_are_dropped_and_counted():
    listener = OscListener(SimulatedClock())
    sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        for size in (MAX_PACKET + 1, 8 * MAX_PACKET, 60_000):
            sender.sendto(b"/" + bytes(size - 1), ("127.0.0.1", listener.port))
        while listener.oversize < 3 and listener.wait(2.0):
            listener.poll()
        assert (listener.oversize, listener.received, listener.malformed) == (3, 0, 0)
    finally:
        listener.close()
        sender.close()


def _sparse(path, size: int) -> None:
    """A file of ``size`` bytes that costs no disk and no time to make."""
    with open(path, "wb") as handle:
        handle.truncate(size)


def test_oversize_state_and_config_files_are_refused_before_reading(tmp_path):
    _sparse(tmp_path / "huge.json", MAX_STATE_BYTES + 1)
    with pytest.raises(StateFileError, match="huge.json: state file larger than"):
        load_json(tmp_path / "huge.json", kind="creature")
    _sparse(tmp_path / "huge.toml", MAX_CONFIG_BYTES + 1)
    with pytest.raises(ConfigError, match="huge.toml: config file larger than"):
        load_installation(tmp_path / "huge.toml")
    save_json(tmp_path / "fine.json", {"x": 1}, kind="creature")
    assert load_json(tmp_path / "fine.json", kind="creature")["x"] == 1


def test_an_npz_that_unpacks_beyond_the_bound_stays_packed(tmp_path, monkeypatch):
    monkeypatch.setattr(persist, "MAX_STATE_BYTES", 1 << 20)
    path = tmp_path / "bomb.npz"
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        buffer = io.BytesIO()
        np.save(buffer, np.zeros(1 << 18))  # 2 MiB of zeros, a few KiB packed
        archive.writestr("zeros.npy", buffer.getvalue())
    assert path.stat().st_size < 64 * 1024
    with pytest.raises(StateFileError, match="bomb.npz: arrays unpack to"):
        load_npz(path)


def test_an_npz_whose_array_claims_more_than_it_holds_is_refused_before_allocating(tmp_path):
    """numpy allocates what a ``.npy`` header's shape claims before reading the data: 90 bytes
    claiming 10**13 floats raised MemoryError (a traceback, no StateFileError); a claim within
    memory would have been allocated in full, however few bytes followed."""
    path = tmp_path / "liar.npz"
    for shape in [(10**13,), (1 << 16,)]:
        header = io.BytesIO()
        np.lib.format.write_array_header_1_0(header, {"descr": "<f8", "fortran_order": False, "shape": shape})
        with zipfile.ZipFile(path, "w") as archive:
            archive.writestr("ok.npy", _npy(np.arange(3.0)))
            archive.writestr("samples.npy", header.getvalue() + bytes(64))
        with pytest.raises(StateFileError, match=rf"liar.npz: array 'samples' claims {shape[0] * 8} bytes .* holds 64"):
            load_npz(path)
    with zipfile.ZipFile(path, "w") as archive:  # what it claims, held: read as ever
        archive.writestr("ok.npy", _npy(np.arange(3.0)))
        archive.writestr("empty.npy", _npy(np.zeros((4, 0))))
    assert {name: array.shape for name, array in load_npz(path).items()} == {"ok": (3,), "empty": (4, 0)}


def _npy(array: np.ndarray) -> bytes:
    buffer = io.BytesIO()
    np.save(buffer, array)
    return buffer.getvalue()


def test_a_sound_file_claiming_a_tiny_rate_is_refused_not_inflated(tmp_path):
    path = tmp_path / "one-hertz.wav"
    soundfile.write(path, np.zeros(22050, dtype=np.float32), 1)  # 44 kB that would become 2 GB
    with pytest.raises(AudioFileError, match="one-hertz.wav: sample rate 1 Hz is below"):
        load_audio(path)
    soundfile.write(path, np.zeros(100, dtype=np.float32), MIN_FILE_RATE)
    assert len(load_audio(path)) == round(100 * 22050 / MIN_FILE_RATE)
