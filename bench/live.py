"""The live show with its real parts: the shipped exchange colony (``creatures run``'s own
code, :func:`creatures.runtime.live.run_live`) for 60 s on JACK, playing its voices to JACK's
audio device and its notes to fluidsynth (a synth client on JACK), while a foreign OSC sender
(python-osc's client, its own process) plays it 20 notes a second.

Rows (the issue's targets): tick lateness p99 (≤ 2 ms), notes heard → answered p99 (≤ 5 ms),
audio underruns after the first second (0). ``--quick`` runs 15 s. Skips, saying why, when
JACK or fluidsynth is absent.

Heard → answered is the reflex's latency for a note the creature decides to answer: ada is
set to decide to answer every note (``answer = 1``, no ``strike_interval``, no
``refractory``, no mutation, as in bench/midi.py), so every heard note is one it has decided
to answer. It runs from the sender's Unix time just before its send to the first strike of
that pitch on ada's channel reaching the MIDI port (a note-on, or a swell of the note still
sounding), looked for only until the sender sends that pitch again (:func:`answer_latencies`):
a note is never matched to a later answer of its pitch (the sender's pitches recur every
1.8 s, which once read as 1.8 s answers). A note with no answer in its window is counted
(the unanswered row, target 0) and, in the percentiles, as infinitely late.
"""

from __future__ import annotations

import bisect
import os
import tempfile
import time
from collections import defaultdict
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

import mido
import numpy as np

import installations
from bench import Row
from bench._peers import skipped
from bench.live_parts import Synth, after_first_second, free_udp_port, missing_parts, send_notes, sent_notes
from creatures.events import read_events
from creatures.runtime import live
from creatures.runtime.schema import load_installation
from midi.sinks import PortSink

RATE = 20.0
"""Notes a second from the OSC sender."""


class _StampingSink(PortSink):
    """The live run's MIDI sink, also keeping the Unix time each strike reached the port: a
    struck note object sounds (note-on), or swells if it still sounds (polytouch)."""

    arrivals: dict[tuple[int, int], list[float]] = defaultdict(list)  # (channel, pitch) -> times

    def send(self, time_: float, msg: mido.Message) -> None:
        super().send(time_, msg)
        if msg.type == "polytouch" or (msg.type == "note_on" and msg.velocity > 0):
            self.arrivals[(msg.channel, msg.note)].append(time.time())


@contextmanager
def _stamped() -> Iterator[dict[tuple[int, int], list[float]]]:
    _StampingSink.arrivals = defaultdict(list)
    live.PortSink, kept = _StampingSink, live.PortSink
    try:
        yield _StampingSink.arrivals
    finally:
        live.PortSink = kept


UNANSWERED = 1e9
"""The latency (ms) an unanswered note counts as in the percentiles: practically infinite."""


def answer_latencies(sent: list[dict], arrivals: dict[tuple[int, int], list[float]], channel: int) -> np.ndarray:
    """Each sent note's answer latency (ms): from its ``sent`` time to the first arrival of its
    pitch on ``channel`` (``arrivals``: Unix times, ascending) before the next sent note of
    the same pitch; :data:`UNANSWERED` when none came in that window."""
    latency_ms = np.full(len(sent), UNANSWERED)
    next_same = [np.inf] * len(sent)
    last: dict[int, int] = {}
    for i, note in enumerate(sent):
        if note["pitch"] in last:
            next_same[last[note["pitch"]]] = note["sent"]
        last[note["pitch"]] = i
    for i, note in enumerate(sent):
        answers = arrivals.get((channel, note["pitch"]), [])
        k = bisect.bisect_left(answers, note["sent"])
        if k < len(answers) and answers[k] < next_same[i]:
            latency_ms[i] = (answers[k] - note["sent"]) * 1e3
    return latency_ms


def run(quick: bool) -> list[Row]:
    reason = missing_parts()
    if reason:
        return [skipped("live show on JACK", reason)]
    seconds = 15.0 if quick else 60.0
    os.environ.setdefault("MIDO_BACKEND", "mido.backends.rtmidi/UNIX_JACK")
    inst = load_installation(installations.path("exchange"))
    ada = inst.specs[0]
    ada.space.answer, ada.space.strike_interval, ada.space.refractory, ada.space.mutation = 1.0, 0.0, 0.0, 0.0
    port = free_udp_port()
    inst.settings.osc.port = port
    synth = Synth("creatures-bench-")
    inst.settings.midi.output_port = synth.midi_port
    with tempfile.TemporaryDirectory() as tmp, _stamped() as arrivals:
        log = Path(tmp) / "events.jsonl"
        count = int(RATE * (seconds - 3.0))
        sender = None

        def start_sender(message: str) -> None:
            nonlocal sender
            if "running; Ctrl-C" in message:  # said just before the loop starts
                sender = send_notes(port, count, RATE, Path(tmp) / "sent.jsonl")

        try:
            summary = live.run_live(inst, duration=seconds, log_path=log, say=start_sender)
            sent = sent_notes(sender, Path(tmp) / "sent.jsonl", timeout=30)
        finally:
            if sender is not None and sender.poll() is None:
                sender.kill()
            synth.close()
        events = read_events(log)
    heard = [e["pitch"] for e in events if e["kind"] == "heard" and e["source"] == "visitor"]
    # A loaded machine can make the sender fall behind: notes it sent after the run had ended
    # were never heard and are not counted (the heard ones are the first, in order).
    sent = sent[:len(heard)]
    latency_ms = answer_latencies(sent, arrivals, ada.channel)
    after = after_first_second(events, inst.settings.tick)
    what = f"{seconds:g} s on JACK, fluidsynth, OSC {RATE:g} notes/s"
    return [
        Row(f"live ({what}): tick lateness p99", summary.lateness_p99 * 1e3, "ms", target=2.0,
            higher_is_better=False),
        Row("  ticks more than 5 ms late", 100.0 * summary.late / max(summary.ticks, 1), "%", higher_is_better=False),
        Row("  notes heard → answered (OSC send → MIDI port) p99", float(np.percentile(latency_ms, 99)), "ms",
            target=5.0, higher_is_better=False),
        Row("  notes heard → answered p50", float(np.percentile(latency_ms, 50)), "ms", higher_is_better=False),
        Row("  notes ada decided to answer left unanswered", float((latency_ms >= UNANSWERED).sum()), "",
            target=0.0, higher_is_better=False),
        Row("  sent notes heard, in order", 100.0 * (heard == [n["pitch"] for n in sent]), "%"),
        Row("  notes the sender got out while the colony ran", float(len(sent)), f"of {count}"),
        Row("  audio underruns after the first second", float(after["underruns"]), "", target=0.0,
            higher_is_better=False),
        Row("  audio gaps put in after the first second (the output's lead ran out)", float(after["gaps"]), "",
            target=0.0, higher_is_better=False),
        Row("  audio skips after the first second (JACK stalled, the surplus left out)", float(after["skips"]), "",
            higher_is_better=False),
        Row("  notes late at the MIDI port (> 10 ms)", float(summary.late_notes), "", higher_is_better=False),
    ]
