"""Every parser of outside data, fuzzed: whatever a file or a datagram holds, the only
exception is the parser's own clear error type (or the input is accepted). MIDI bytes are
fuzzed in ``test_midi_fuzz.py``."""

from __future__ import annotations

import io
import json
import socket
import tempfile
from pathlib import Path

import numpy as np
import pytest
import soundfile
from hypothesis import HealthCheck, given, reject, settings
from hypothesis import strategies as st
from pythonosc.osc_message import ParseError as OscParseError
from pythonosc.osc_message_builder import BuildError, OscMessageBuilder

import installations
from audio.sources import AudioFileError, load_audio
from creatures.behaviour.creature import Creature
from creatures.clock import SimulatedClock
from creatures.config import ConfigError
from creatures.events import EventLog
from creatures.motor.bvh import BVHError, parse_bvh
from creatures.persist import StateFileError, load_json, load_npz, save_json, save_npz
from creatures.runtime.schema import load_installation
from creatures.runtime.session import Session
from midi.osc import MAX_PACKET, OscListener
from midi.sinks import MemorySink
from test_creature_persistence import build, live
from test_motor_files import GOOD_BVH

FUZZ = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
EXCHANGE = installations.path("exchange").read_text()


@pytest.fixture(scope="module")
def scratch():
    with tempfile.TemporaryDirectory() as directory:
        yield Path(directory)


def _mutate_bytes(data: bytes, edits: list[tuple[int, int]], cut: int | None) -> bytes:
    """Overwrite bytes at (position, value) pairs, then optionally truncate."""
    out = bytearray(data)
    for position, value in edits:
        out[position % len(out)] = value
    return bytes(out[:cut] if cut is not None else out)


EDITS = st.lists(st.tuples(st.integers(0, 1 << 16), st.integers(0, 255)), max_size=8)
CUTS = st.none() | st.integers(0, 1 << 16)


# -- installation configs ---------------------------------------------------------------------
TOML_VALUES = st.one_of(
    st.integers(-(1 << 70), 1 << 70).map(str),
    st.floats().map(repr),  # nan, inf and -inf are TOML too
    st.text(max_size=12).map(json.dumps),
    st.sampled_from(["true", "false", "[]", "[1, 'a']", "{}", "{ kind = 1 }", "[[1]]", "1979-05-27", '"exchange"',
                     '"../../etc/passwd"', "-0.0", "1e400", "[ { name = 'x' } ]"]),
)


@FUZZ
@given(text=st.text(max_size=300))
def test_random_toml_text_gives_only_config_errors(scratch, text):
    path = scratch / "random.toml"
    path.write_bytes(text.encode("utf-8", "surrogatepass"))
    try:
        load_installation(path)
    except ConfigError as exc:
        assert "random.toml" in str(exc)


@FUZZ
@given(data=st.data())
def test_mutated_installation_keys_and_values_give_only_config_errors(scratch, data):
    """Change a value, rename a key, drop or repeat a line of the shipped exchange config."""
    lines = EXCHANGE.splitlines()
    for _ in range(data.draw(st.integers(1, 3))):
        i = data.draw(st.integers(0, len(lines) - 1))
        how = data.draw(st.sampled_from(["value", "key", "drop", "repeat"]))
        key, eq, _ = lines[i].partition("=")
        if how == "value" and eq:
            lines[i] = f"{key}= {data.draw(TOML_VALUES)}"
        elif how == "key" and eq:
            lines[i] = f"{data.draw(st.from_regex(r'[a-z_]{1,12}', fullmatch=True))} ={lines[i].partition('=')[2]}"
        elif how == "drop":
            del lines[i]
        elif how == "repeat":
            lines.insert(i, lines[i])
    path = scratch / "mutated.toml"
    path.write_text("\n".join(lines))
    try:
        load_installation(path)
    except ConfigError as exc:
        assert "mutated.toml" in str(exc)


# -- state files --------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def state_files(scratch):
    """A saved JSON document, NPZ, session state dir and Creature file to corrupt."""
    directory = scratch / "state"
    directory.mkdir()
    save_json(directory / "doc.json", {"values": [1.5, 2.5], "name": "ada"}, kind="fuzz")
    save_npz(directory / "arrays.npz", {"times": np.arange(50.0), "data": np.ones((5, 3))})
    sessions = {}
    for name in installations.names():  # every kind's state, as its own restore() reads it
        inst = load_installation(installations.path(name))
        clock, tick, sr = SimulatedClock(), inst.settings.tick, inst.settings.audio.sample_rate
        session = Session(inst, clock, EventLog(), MemorySink())
        hum = np.sin(np.arange(int(2.0 * sr)) * 0.05).astype(np.float32) * 0.3
        for step in range(1, int(2.0 / tick) + 1):
            a, b = int(round((step - 1) * tick * sr)), int(round(step * tick * sr))
            clock.advance_to(step * tick)
            session.step(step * tick, b - a, hum[a:b])
        session.save_state(directory / name)
        sessions[name] = session
    creature = build()()
    live(creature, 3.0)
    creature.save(directory / "singer.json")
    return directory, sessions


@FUZZ
@given(edits=EDITS, cut=CUTS)
def test_corrupted_json_and_npz_give_only_state_file_errors(state_files, edits, cut):
    directory, _ = state_files
    for name, load in (("doc.json", lambda p: load_json(p, kind="fuzz")), ("arrays.npz", load_npz)):
        broken = directory / f"broken-{name}"
        broken.write_bytes(_mutate_bytes((directory / name).read_bytes(), edits, cut))
        try:
            load(broken)
        except StateFileError as exc:
            assert broken.name in str(exc)


JSON_LEAVES = st.none() | st.booleans() | st.integers(-(1 << 65), 1 << 65) | st.floats(allow_nan=False) | \
    st.text(max_size=8) | st.sampled_from([[], {}, [1, "x"], {"kind": "scalar"}, float("nan"), float("inf")])


def _leaf_paths(node, prefix=()):
    items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
    for key, child in items:
        yield prefix + (key,)
        yield from _leaf_paths(child, prefix + (key,))


@settings(FUZZ, max_examples=400)
@given(data=st.data())
def test_corrupted_session_state_gives_only_state_file_errors(state_files, data):
    """Bytes flipped or cut, or any field of a creature's saved state (of any shipped kind)
    replaced by anything."""
    directory, sessions = state_files
    name = data.draw(st.sampled_from(sorted(sessions)))
    source = data.draw(st.sampled_from(sorted((directory / name).glob("*.json"))))
    target = directory / "fuzzed"
    target.mkdir(exist_ok=True)
    for old in target.iterdir():
        old.unlink()
    victim = target / source.name
    if data.draw(st.booleans()):
        victim.write_bytes(_mutate_bytes(source.read_bytes(), data.draw(EDITS), data.draw(CUTS)))
    else:
        document = json.loads(source.read_text())
        where = data.draw(st.sampled_from(list(_leaf_paths(document))))
        node = document
        for key in where[:-1]:
            node = node[key]
        node[where[-1]] = data.draw(JSON_LEAVES)
        victim.write_text(json.dumps(document))
    try:
        sessions[name].load_state(target)
    except StateFileError as exc:
        assert victim.name in str(exc)


@FUZZ
@given(edits=EDITS, cut=CUTS, which=st.sampled_from(["json", "npz"]))
def test_corrupted_creature_files_give_only_state_file_errors(state_files, edits, cut, which):
    directory, _ = state_files
    path = directory / "singer.json"
    npz = directory / json.loads(path.read_text())["arrays"]
    victim = path if which == "json" else npz
    original = victim.read_bytes()
    try:
        victim.write_bytes(_mutate_bytes(original, edits, cut))
        try:
            Creature.load(path, build())
        except StateFileError as exc:
            assert victim.name in str(exc) or path.name in str(exc)
    finally:
        victim.write_bytes(original)


# -- BVH --------------------------------------------------------------------------------------
BVH_TOKENS = st.sampled_from(["{", "}", "ROOT", "JOINT", "End", "Site", "OFFSET", "CHANNELS", "MOTION",
                              "Frames:", "Frame", "Time:", "Xrotation", "Zposition", "0", "-1", "7", "1e309",
                              "nan", "inf", "x", "", "\n"])


@FUZZ
@given(data=st.data())
def test_mutated_bvh_gives_only_bvh_errors(data):
    tokens = GOOD_BVH.split(" ")
    for _ in range(data.draw(st.integers(1, 4))):
        i = data.draw(st.integers(0, len(tokens) - 1))
        how = data.draw(st.sampled_from(["replace", "drop", "insert"]))
        if how == "replace":
            tokens[i] = data.draw(BVH_TOKENS | st.text(max_size=6))
        elif how == "drop":
            del tokens[i]
        else:
            tokens.insert(i, data.draw(BVH_TOKENS))
    text = " ".join(tokens)
    if data.draw(st.booleans()):
        text = text[: data.draw(st.integers(0, len(text)))]
    try:
        parse_bvh(text, source="fuzz.bvh")
    except BVHError as exc:
        assert "fuzz.bvh" in str(exc)


# -- OSC datagrams ------------------------------------------------------------------------------
OSC_ARGS = st.lists(st.one_of(st.integers(-(1 << 31), (1 << 31) - 1), st.floats(width=32), st.text(max_size=10),
                              st.binary(min_size=1, max_size=10), st.booleans(), st.none()), max_size=5)
OSC_ADDRESSES = st.sampled_from(["/creature/ada/note", "/creature/ada/hello", "/creature/ada/state",
                                 "/creature/ada/bye", "/creature/" + "x" * 80 + "/note", "/creature//note"]) | \
    st.text(max_size=30).map(lambda s: "/" + s.replace("\x00", ""))


def _message(address: str, args: list) -> bytes:
    builder = OscMessageBuilder(address)
    for arg in args:
        builder.add_arg(arg)
    try:
        return builder.build().dgram
    # python-osc cannot write it (it re-parses what it built, and fails on some blobs), so
    # no peer could send it
    except (BuildError, UnicodeError, OscParseError):
        reject()


@st.composite
def datagrams(draw) -> bytes:
    kind = draw(st.sampled_from(["random", "message", "bundle", "cut message"]))
    if kind == "random":
        return draw(st.binary(min_size=1, max_size=MAX_PACKET + 64))
    message = _message(draw(OSC_ADDRESSES), draw(OSC_ARGS))
    if kind == "cut message":
        return message[: draw(st.integers(1, len(message)))]
    if kind == "message":
        return message
    parts = [_message(draw(OSC_ADDRESSES), draw(OSC_ARGS)) for _ in range(draw(st.integers(0, 3)))]
    return b"#bundle\x00" + bytes(7) + b"\x01" + b"".join(len(p).to_bytes(4, "big") + p for p in parts)


@pytest.fixture(scope="module")
def osc():
    listener = OscListener(SimulatedClock())
    sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    yield listener, sender
    listener.close()
    sender.close()


@FUZZ
@given(packets=st.lists(datagrams(), min_size=1, max_size=20))
def test_random_datagrams_are_dropped_and_counted(osc, packets):
    listener, sender = osc
    counted = lambda: listener.received + listener.malformed + listener.oversize  # noqa: E731
    before = counted()
    # Each packet counts at least once — accepted, malformed or oversize — except an empty
    # bundle, which is valid OSC holding nothing (a bundle may hold several messages).
    expected = len(packets) - sum(p.startswith(b"#bundle") and len(p) == 16 for p in packets)
    for packet in packets:
        sender.sendto(packet, ("127.0.0.1", listener.port))
    heard = []
    while counted() - before < expected and listener.wait(2.0):
        heard += listener.poll()
    heard += listener.poll()
    assert counted() - before >= expected
    assert len(heard) <= listener.received


# -- WAV headers ----------------------------------------------------------------------------------
def _wav(subtype: str) -> bytes:
    buffer = io.BytesIO()
    tone = 0.3 * np.sin(2 * np.pi * 440 * np.arange(2205) / 22050)
    soundfile.write(buffer, tone, 22050, format="WAV", subtype=subtype)
    return buffer.getvalue()


WAVS = {subtype: _wav(subtype) for subtype in ("PCM_16", "FLOAT")}


@FUZZ
@given(subtype=st.sampled_from(sorted(WAVS)), edits=st.lists(st.tuples(st.integers(0, 60), st.integers(0, 255)),
                                                              min_size=1, max_size=6), cut=CUTS)
def test_mutated_wav_headers_give_only_audio_file_errors(scratch, subtype, edits, cut):
    path = scratch / "mutated.wav"
    path.write_bytes(_mutate_bytes(WAVS[subtype], edits, cut))
    try:
        samples = load_audio(path)
    except AudioFileError as exc:
        assert "mutated.wav" in str(exc)
    else:
        assert samples.dtype == np.float32 and samples.ndim == 1 and np.isfinite(samples).all()
