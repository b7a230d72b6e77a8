"""NoteScheduler: notes go out in order at their due time; nothing is ever left hanging."""

from __future__ import annotations

import mido
import numpy as np
import pytest

from midi.notes import NoteEvent, from_messages, is_note_off
from midi.scheduler import NoteScheduler
from midi.sinks import FileSink, MemorySink


def phrase(rng: np.random.Generator, n: int = 200) -> list[NoteEvent]:
    starts = np.cumsum(rng.uniform(0.0, 0.2, n))
    return [
        NoteEvent(float(t), int(p), int(v), int(c), float(d))
        for t, p, v, c, d in zip(
            starts, rng.integers(36, 96, n), rng.integers(1, 128, n), rng.integers(0, 4, n), rng.uniform(0.0, 1.0, n)
        )
    ]


def run_until(scheduler: NoteScheduler, clock, t_end: float) -> None:
    """Advance the simulated clock event by event, as fast as the work allows."""
    while (due := scheduler.next_due()) is not None and due <= t_end:
        clock.advance_to(due)
        scheduler.pump()
    clock.advance_to(max(clock.now(), t_end))
    scheduler.pump()


def open_notes(messages) -> dict[tuple[int, int], int]:
    """How many note-ons per (channel, pitch) have no note-off yet (CC 123 clears a channel)."""
    count: dict[tuple[int, int], int] = {}
    for _, msg in messages:
        if msg.type == "control_change" and msg.control == 123:
            count = {k: v for k, v in count.items() if k[0] != msg.channel}
        elif msg.type in ("note_on", "note_off"):
            key = (msg.channel, msg.note)
            count[key] = max(0, count.get(key, 0) + (-1 if is_note_off(msg) else 1))
    return {k: v for k, v in count.items() if v}


def merged(spans: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """``spans`` joined where they overlap or touch: when a key sounds, without a gap."""
    out: list[list[float]] = []
    for start, end in sorted(spans):
        if out and start <= out[-1][1]:
            out[-1][1] = max(out[-1][1], end)
        else:
            out.append([start, end])
    return [(a, b) for a, b in out]


def key_spans(messages) -> dict[tuple[int, int], list[tuple[float, float]]]:
    """When each (channel, pitch) sounds on a synth with one voice per key, as fluidsynth and
    most GM synths play: a note-on starts the key (or re-strikes it), any note-off stops it."""
    started: dict[tuple[int, int], float] = {}
    spans: dict[tuple[int, int], list[tuple[float, float]]] = {}
    for t, msg in messages:
        if msg.type not in ("note_on", "note_off"):
            continue
        key = (msg.channel, msg.note)
        if not is_note_off(msg):
            started.setdefault(key, t)
        elif key in started:
            spans.setdefault(key, []).append((started.pop(key), t))
    return {key: merged(s) for key, s in spans.items()}


def test_messages_leave_in_time_order_at_their_due_time(rng, clock):
    notes = phrase(rng)
    sink = MemorySink()
    scheduler = NoteScheduler(sink, clock)
    for note in reversed(notes):  # scheduling order must not matter
        scheduler.play(note)
    run_until(scheduler, clock, 100.0)

    times = [t for t, _ in sink.messages]
    assert times == sorted(times)
    ons = sorted((t, m.channel, m.note, m.velocity) for t, m in sink.messages if not is_note_off(m))
    assert ons == sorted((n.time, n.channel, n.pitch, n.velocity) for n in notes)  # every on at its due time
    assert sum(is_note_off(m) for _, m in sink.messages) == len(notes)  # one off each
    wanted: dict[tuple[int, int], list[tuple[float, float]]] = {}
    for n in notes:
        wanted.setdefault((n.channel, n.pitch), []).append((n.time, n.end))
    assert key_spans(sink.messages) == {key: merged(s) for key, s in wanted.items()}  # each key as long as its notes
    assert scheduler.restruck > 0  # this phrase repeats pitches within a note's length
    assert scheduler.sounding == [] and scheduler.next_due() is None


def test_a_repeated_pitch_that_overlaps_re_strikes_the_key(clock):
    """on, on, off, off of one key is heard on, on, off: the second note lost its tail. The
    earlier note ends at the re-strike, and the key sounds to the later end."""
    sink = MemorySink()
    scheduler = NoteScheduler(sink, clock)
    scheduler.play(NoteEvent(0.0, 60, 100, 0, 2.0))
    scheduler.play(NoteEvent(1.0, 60, 90, 0, 2.0))  # overlaps the first by a second
    scheduler.play(NoteEvent(4.0, 62, 100, 1, 3.0))
    scheduler.play(NoteEvent(5.0, 62, 70, 1, 0.5))  # inside the first: the key still rings to 7
    scheduler.play(NoteEvent(8.0, 64, 100, 2, 1.0))
    scheduler.play(NoteEvent(8.0, 64, 80, 2, 0.0))  # the same instant, no length
    run_until(scheduler, clock, 10.0)
    sent = [(t, m.channel, "off" if is_note_off(m) else m.velocity) for t, m in sink.messages]
    assert sent == [(0.0, 0, 100), (1.0, 0, "off"), (1.0, 0, 90), (3.0, 0, "off"),
                    (4.0, 1, 100), (5.0, 1, "off"), (5.0, 1, 70), (7.0, 1, "off"),
                    (8.0, 2, 100), (8.0, 2, "off"), (8.0, 2, 80), (9.0, 2, "off")]
    assert scheduler.restruck == 3
    assert scheduler.sounding == [] and scheduler.next_due() is None


def test_nothing_goes_out_early(clock):
    sink = MemorySink()
    scheduler = NoteScheduler(sink, clock)
    scheduler.play(NoteEvent(1.0, 60, 100, 0, 0.5))
    clock.advance_to(0.999)
    assert scheduler.pump() == 0
    clock.advance_to(1.0)
    assert scheduler.pump() == 1 and sink.messages[0][1].type == "note_on"
    clock.advance_to(1.4)
    assert scheduler.pump() == 0
    clock.advance_to(1.6)  # a late pump sends the off stamped with its due time
    assert scheduler.pump() == 1 and sink.messages[1][0] == 1.5


def test_repeated_pitch_is_not_cut_short_and_zero_length_note_keeps_order(clock):
    sink = MemorySink()
    scheduler = NoteScheduler(sink, clock)
    scheduler.play(NoteEvent(0.0, 60, 100, 0, 1.0))
    scheduler.play(NoteEvent(1.0, 60, 90, 0, 1.0))
    scheduler.play(NoteEvent(3.0, 62, 80, 0, 0.0))
    run_until(scheduler, clock, 5.0)
    kinds = [(t, "off" if is_note_off(m) else "on") for t, m in sink.messages]
    assert kinds == [(0.0, "on"), (1.0, "off"), (1.0, "on"), (2.0, "off"), (3.0, "on"), (3.0, "off")]


def test_abort_mid_phrase_leaves_no_hanging_note(rng, clock):
    notes = phrase(rng)
    sink = MemorySink()
    with pytest.raises(RuntimeError, match="creature fell over"):
        with NoteScheduler(sink, clock) as scheduler:
            for note in notes:
                scheduler.play(note)
            scheduler.play(NoteEvent(0.5, 30, 100, 5, 0.0), hold=True)  # a stuck note
            run_until(scheduler, clock, notes[len(notes) // 2].time)
            sounding = len(scheduler.sounding)
            raise RuntimeError("creature fell over")
    assert sounding >= 2
    # Every note-on that went out has an explicit note-off, before the CC 123s.
    tail = sink.messages[-(sounding + 5):]
    assert all(is_note_off(m) for _, m in tail[:sounding])
    assert [(m.channel, m.control) for _, m in tail[sounding:]] == [(c, 123) for c in (0, 1, 2, 3, 5)]
    explicit = [(t, m) for t, m in sink.messages if m.type != "control_change"]
    assert open_notes(explicit) == {}
    # ... and nothing scheduled after the abort goes out.
    n_sent = len(sink.messages)
    clock.advance(1000.0)
    assert scheduler.pump() == 0 and len(sink.messages) == n_sent


def test_extend_moves_the_note_off_and_release_ends_a_held_note(clock):
    sink = MemorySink()
    scheduler = NoteScheduler(sink, clock)
    short = scheduler.play(NoteEvent(0.0, 60, 100, 0, 1.0))
    held = scheduler.play(NoteEvent(0.0, 64, 100, 0, 1.0), hold=True)
    scheduler.pump()
    assert scheduler.extend(short, 2.5)
    run_until(scheduler, clock, 10.0)
    assert scheduler.is_sounding(held) and not scheduler.is_sounding(short)
    assert scheduler.release(held)
    assert not scheduler.extend(held, 20.0)  # it has ended
    notes = from_messages(sink.messages)
    assert [(n.pitch, n.duration) for n in notes] == [(60, 2.5), (64, 10.0)]


def test_file_sink_records_a_playable_file(rng, clock, tmp_path):
    from midi.files import read_notes

    notes = phrase(rng, 50)
    with FileSink(tmp_path / "take.mid") as sink:
        scheduler = NoteScheduler(sink, clock)
        for note in notes:
            scheduler.play(note)
        run_until(scheduler, clock, 100.0)
    back = read_notes(tmp_path / "take.mid")
    assert [(n.pitch, n.channel) for n in back] == [(n.pitch, n.channel) for n in sink.notes()]
    assert mido.MidiFile(tmp_path / "take.mid").type == 1


class FlakySink(MemorySink):
    """Fails on its first message after ``armed`` is set, like a port that glitches once."""

    armed = False

    def send(self, time: float, msg: mido.Message) -> None:
        if self.armed:
            self.armed = False
            raise OSError("port glitch")
        super().send(time, msg)


def test_one_failed_send_does_not_stop_the_rest_of_all_notes_off(clock):
    sink = FlakySink()
    scheduler = NoteScheduler(sink, clock)
    for pitch in (60, 64, 67):
        scheduler.play(NoteEvent(0.0, pitch, 100, 0, 10.0))
    scheduler.pump()
    sink.armed = True
    with pytest.raises(OSError, match="port glitch"):
        scheduler.all_notes_off()
    tail = [m for _, m in sink.messages[3:]]
    assert [(m.type, getattr(m, "note", None)) for m in tail] == [("note_off", 64), ("note_off", 67), ("control_change", None)]
    assert scheduler.sounding == []


def test_a_note_played_in_the_past_is_filed_at_its_time(clock, tmp_path):
    """A note due before messages already sent goes out late, stamped with its own time; the
    file puts it in time order (mido refused the negative delta: no ``.mid`` at all)."""
    from midi.files import read_notes

    with FileSink(tmp_path / "take.mid") as sink:
        scheduler = NoteScheduler(sink, clock)
        scheduler.play(NoteEvent(5.9, 60, 100, 0, 0.05))
        run_until(scheduler, clock, 6.0)
        scheduler.play(NoteEvent(5.5, 62, 90, 0, 0.25))
        scheduler.pump()  # its on and its off, both due
        run_until(scheduler, clock, 7.0)
    back = read_notes(tmp_path / "take.mid")
    assert [(n.pitch, n.velocity) for n in back] == [(62, 90), (60, 100)]
    assert [(n.time, n.duration) for n in back] == [pytest.approx((5.5, 0.25), abs=1e-3), pytest.approx((5.9, 0.05), abs=1e-3)]
