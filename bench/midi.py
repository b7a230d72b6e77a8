"""MIDI benchmarks: raw-byte parsing beside mido's own Parser, loading a 100,000-note file,
and MIDI-in → creature decision → MIDI-out latency through in-memory ports."""

from __future__ import annotations

import tempfile
import threading
import time
from pathlib import Path

import mido
import numpy as np

from bench import Row, best_of
from creatures.clock import WallClock
from midi.files import TempoMap, read_notes, write_notes
from midi.notes import NoteEvent
from midi.parser import StreamParser
from midi.ports import memory_pair
from midi.sinks import PortSink
from midi.sources import PortSource


def _channel_stream(rng: np.random.Generator, n: int) -> bytes:
    """``n`` note-on/off and control messages, each with its status byte (mido's Parser
    cannot read running status, so the comparison uses a stream both can read)."""
    status = rng.choice([0x80, 0x90, 0xB0], n) | rng.integers(0, 16, n)
    data = rng.integers(0, 128, (n, 2))
    return np.column_stack([status, data]).astype(np.uint8).tobytes()


def _parse_rows(rng: np.random.Generator, n: int) -> list[Row]:
    stream = _channel_stream(rng, n)

    def ours() -> None:
        parser = StreamParser()
        parser.feed(stream)
        assert len(parser.pending()) == n

    def theirs() -> None:
        parser = mido.Parser()
        parser.feed(stream)
        assert len(list(parser)) == n

    t_ours, t_theirs = best_of(ours), best_of(theirs)
    return [Row("parse raw bytes (running-status aware)", n / t_ours, "msgs/s", target=100_000,
                baseline="mido.Parser", ratio=t_theirs / t_ours)]


def _file_rows(rng: np.random.Generator, n: int) -> list[Row]:
    starts = np.cumsum(rng.uniform(0.0, 0.05, n))
    notes = [
        NoteEvent(float(t), int(p), int(v), int(c), float(d))
        for t, p, v, c, d in zip(starts, rng.integers(0, 128, n), rng.integers(1, 128, n),
                                 rng.integers(0, 16, n), rng.uniform(0.01, 1.0, n))
    ]
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "big.mid"
        write_notes(path, notes, tempo=TempoMap.from_seconds(480, [(starts[-1] / 3, 90.0), (starts[-1] / 2, 150.0)]))
        t_ours = best_of(lambda: read_notes(path), repeat=2)
        t_mido = best_of(lambda: mido.MidiFile(path), repeat=2)
    # The issue sets no target here; the ratio says how much pairing and the tempo map add to
    # mido's own parse (which is most of the time).
    return [Row(f"load .mid of {n:,} notes to NoteEvents", t_ours, "s",
                higher_is_better=False, baseline="mido.MidiFile parse only", ratio=t_mido / t_ours)]


def _latency_rows(rng: np.random.Generator, n: int) -> list[Row]:
    """A producer thread plays notes into an in-memory input at ~2–5 kHz; the creature loop
    polls it, decides (transpose a fifth), and sends to an in-memory output."""
    clock = WallClock()
    inport, player = memory_pair("ear")
    _, voice = memory_pair("voice")
    ear, sink = PortSource(inport, clock), PortSink(voice)
    sent_at = np.zeros(n)
    answered_at = np.zeros(n)
    gaps = rng.uniform(0.0001, 0.0004, n)

    def play() -> None:
        for i in range(n):
            sent_at[i] = time.perf_counter()
            player.send(mido.Message("note_on", note=int(i % 128), velocity=100))
            time.sleep(gaps[i])

    def decide(msg: mido.Message) -> mido.Message:
        return msg.copy(note=(msg.note + 7) % 128) if msg.type == "note_on" else msg

    producer = threading.Thread(target=play)
    producer.start()
    done = 0
    while done < n:
        heard = ear.poll()
        for t, msg in heard:
            sink.send(t, decide(msg))
            answered_at[done] = time.perf_counter()
            done += 1
        if not heard:
            time.sleep(0.00005)
    producer.join()
    latency_ms = (answered_at - sent_at) * 1e3
    return [
        Row(f"MIDI in → decision → out latency p50 ({n:,} events)", float(np.percentile(latency_ms, 50)), "ms",
            target=1.0, higher_is_better=False),
        Row(f"MIDI in → decision → out latency p99 ({n:,} events)", float(np.percentile(latency_ms, 99)), "ms",
            target=5.0, higher_is_better=False),
    ]


def run(quick: bool) -> list[Row]:
    rng = np.random.default_rng(2001)
    return [
        *_parse_rows(rng, 20_000 if quick else 200_000),
        *_file_rows(rng, 10_000 if quick else 100_000),
        *_latency_rows(rng, 1_000 if quick else 10_000),
    ]
