"""Not listening while singing (audio/self_hearing.py with audio/segment.py)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from audio.segment import Segmenter, SoundEvent
from audio.self_hearing import SingingState
from audio_fixtures import SR, noise, word, warm_librosa  # noqa: F401
from creatures.clock import SimulatedClock

SING_AT, OTHER_AT = 1.0, 2.6

pytestmark = pytest.mark.usefixtures("warm_librosa")


def room(voice: np.ndarray) -> np.ndarray:
    """The loudspeaker heard by the microphone: 10 ms away, with a wall echo 150 ms later."""
    response = np.zeros(int(0.16 * SR))
    response[int(0.01 * SR)] = 0.6
    response[int(0.15 * SR)] = 0.4
    return signal.fftconvolve(voice, response)


def scene(rng: np.random.Generator) -> tuple[np.ndarray, float]:
    """4 s at the microphone: the creature's own song at 1.0 s, another voice at 2.6 s."""
    x = noise(4.0, rng, rms=0.001)
    song = word("ai", rng, rms=0.1)
    heard_song = room(song)
    i = int(SING_AT * SR)
    x[i : i + len(heard_song)] += heard_song
    other = word("oe", rng, rms=0.05)
    j = int(OTHER_AT * SR)
    x[j : j + len(other)] += other
    return x, SING_AT + len(song) / SR


def listen(
    x: np.ndarray,
    clock: SimulatedClock,
    *,
    sing_until: float | None,
    strength: float = 1.0,
    release: float = 0.25,
) -> tuple[list[SoundEvent], Segmenter]:
    """Run the creature's hearing loop block by block; it sings from SING_AT to ``sing_until``."""
    seg = Segmenter(SR, t0=clock.now())
    singing = SingingState(release=release) if sing_until else None
    if singing is not None:
        seg.hearing.inhibit_by(singing, strength)
    events = []
    for block in np.array_split(x, len(x) // 512):
        if singing is not None and clock.now() >= SING_AT and len(singing) == 0:
            singing.sing(clock.now(), 1.0)
        if singing is not None and clock.now() >= sing_until:
            singing.silence(sing_until)
        events += seg.feed(block)
        clock.advance(len(block) / SR)
    return events + seg.flush(), seg


def test_own_song_is_not_heard_but_another_voice_is(
    rng: np.random.Generator, clock: SimulatedClock
) -> None:
    x, song_end = scene(rng)
    deaf, _ = listen(x, SimulatedClock(), sing_until=None)
    assert [round(e.start, 1) for e in deaf] == [SING_AT, OTHER_AT]  # the song alone would trigger
    events, _ = listen(x, clock, sing_until=song_end)
    assert [round(e.start, 1) for e in events] == [OTHER_AT]


def test_release_covers_the_echo_of_the_last_note(rng: np.random.Generator) -> None:
    x, song_end = scene(rng)
    no_release, _ = listen(x, SimulatedClock(), sing_until=song_end, release=0.0)
    assert any(song_end - 0.05 <= e.start < song_end + 0.2 for e in no_release)  # the echo
    events, _ = listen(x, SimulatedClock(), sing_until=song_end, release=0.25)
    assert not any(e.start < OTHER_AT - 0.1 for e in events)


def test_strength_scales_the_inhibition(rng: np.random.Generator) -> None:
    x, song_end = scene(rng)
    _, open_ear = listen(x, SimulatedClock(), sing_until=None)
    _, half = listen(x, SimulatedClock(), sing_until=song_end, strength=0.5)
    for t in np.linspace(SING_AT + 0.05, song_end - 0.05, 5):
        assert half.hearing.saliency_at(t) == pytest.approx(0.5 * open_ear.hearing.saliency_at(t))
    t = OTHER_AT + 0.1
    assert half.hearing.saliency_at(t) == pytest.approx(open_ear.hearing.saliency_at(t))


def test_singing_saliency_holds_through_the_release() -> None:
    singing = SingingState(release=0.2)
    singing.silence(0.5)  # silence before any song changes nothing
    assert singing.saliency_at(0.5) == 0.0
    singing.sing(1.0, 0.8)
    singing.silence(2.0)
    singing.silence(2.1)  # a repeated silence does not restart the release
    assert [singing.saliency_at(t) for t in (0.9, 1.5, 2.0, 2.19, 2.2, 3.0)] == pytest.approx(
        [0.0, 0.8, 0.8, 0.8, 0.0, 0.0]
    )
    with pytest.raises(ValueError, match="release"):
        SingingState(release=-1.0)
