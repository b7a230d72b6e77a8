"""Audio-only runs: the input audio's pitched notes reach the creatures as note events."""

from __future__ import annotations

import numpy as np
import pytest
import soundfile as sf

from audio.transcribe import Transcriber
from creatures.events import read_events
from creatures.runtime.inputs import phrase_notes, render_notes
from creatures.runtime.offline import run_offline
from creatures.runtime.schema import load_installation
from installations import path as installation_path

SR = 22050


def _phrase() -> tuple[list, np.ndarray]:
    notes = phrase_notes(start=0.5, gap=4.0, rng=np.random.default_rng(3))
    return notes, render_notes(notes, SR, 13.0)


def test_streamed_audio_gives_the_notes_that_were_played():
    notes, audio = _phrase()
    noisy = audio + np.random.default_rng(0).normal(0.0, 0.003, len(audio)).astype(np.float32)
    ear = Transcriber(SR)
    heard = [n for start in range(0, len(noisy), 882) for n in ear.feed(noisy[start:start + 882])]
    assert [n.pitch for n in heard] == [n.pitch for n in notes]
    assert max(abs(h.time - n.time) for h, n in zip(heard, notes)) < 0.03
    assert ear.notes == len(notes)


def test_an_audio_only_offline_run_feeds_the_note_pipeline(tmp_path):
    notes, audio = _phrase()
    wav = tmp_path / "flute.wav"
    sf.write(wav, audio, SR)
    inst = load_installation(installation_path("exchange"))
    inst.settings.output.wav = inst.settings.output.report = False
    run_offline(inst, tmp_path / "out", audio=wav, duration=13.0)
    events = read_events(tmp_path / "out" / "events.jsonl")
    heard = [e for e in events if e["kind"] == "heard"]
    assert heard and all(e["source"] == "audio" for e in heard)
    assert [e["pitch"] for e in heard] == [n.pitch for n in notes]
    # Heard notes are the creatures' own material now: a creature that hears the input places them.
    placed = {e["heard"] for e in events if e["kind"] == "placed" and e["source"] == "input"}
    assert placed and placed <= {n.pitch for n in notes}


def test_runs_that_are_given_notes_do_not_also_transcribe_them(tmp_path):
    inst = load_installation(installation_path("exchange"))  # generated phrase: notes and their tones
    inst.settings.output.wav = inst.settings.output.report = False
    run_offline(inst, tmp_path / "out", duration=20.0)
    heard = [e for e in read_events(tmp_path / "out" / "events.jsonl") if e["kind"] == "heard"]
    assert heard and {e["source"] for e in heard} == {"input"}


class _Microphone:
    """A live microphone's twin: each read gives what arrived since the last, ``chunk`` samples."""

    def __init__(self, audio: np.ndarray, chunk: int) -> None:
        self.audio, self.chunk, self.at = audio, chunk, 0

    def read(self) -> np.ndarray:
        block = self.audio[self.at:self.at + self.chunk]
        self.at += len(block)
        return block.copy()


@pytest.mark.parametrize("look, bound", [("live", 0.05), ("quick", 0.03)])
def test_notes_in_the_microphone_are_heard_between_ticks_and_the_tick_still_hears_all_the_audio(look, bound):
    """Read at every look of the live loop (here every 128 samples, 5.8 ms, with no tick at all),
    each note joins the note bus within the transcriber's look of its attack, not at the next
    tick; the tick then gets every sample read since the last one, transcribed once. The config's
    ``[audio] look`` chooses the transcriber's look (measured at most 39.5 ms live, 29.5 ms quick)."""
    from creatures.clock import SimulatedClock
    from creatures.events import EventLog
    from creatures.runtime.microphone_notes import MicrophoneNotes
    from creatures.runtime.session import Session
    from midi.sinks import MemorySink

    notes, audio = _phrase()
    inst = load_installation(installation_path("exchange"))
    inst.settings.audio.look = look
    session = Session(inst, SimulatedClock(), EventLog(), MemorySink(), transcribe=True)
    microphone = _Microphone(audio, 128)
    heard = MicrophoneNotes(microphone, session)
    when = []  # (the look that heard it, how many notes joined the bus)
    for read in range(1, len(audio) // 128 + 1):
        if count := heard.poll(read * 128 / SR):
            when.append((read * 128 / SR, count))
    given = sorted(session.world._pending)
    assert [entry[2].pitch for entry in given] == [n.pitch for n in notes]
    assert sum(count for _, count in when) == len(notes)
    lags = [t - n.time for (t, _), n in zip(when, notes)]
    print(f"{look}: max lag {1e3 * max(lags):.1f} ms")
    assert max(lags) <= bound, lags  # the look (3 hops after the attack's, quick 4 of 128 samples) and one read, no tick
    assert session._transcriber.look == look
    block = heard.take(len(audio) / SR)
    assert np.array_equal(block, audio[:len(block)]) and len(block) == microphone.at
    assert len(heard.take(len(audio) / SR)) == 0  # taken once
    session.step(len(audio) / SR, len(block), block, transcribed=True)
    assert session._transcriber.notes == len(notes)  # not transcribed again
