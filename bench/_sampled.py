"""Audio made by a real sampler for the transcription tests and bench: textures generated in code (random
and composed, 1–4 voices, General MIDI programs), written as MIDI files, rendered by fluidsynth
through Debian's GM soundfont (``fluid-soundfont-gm``), optionally with room noise and
reverb, and scored with mir_eval (the field's metric: note F1, onset within 50 ms, no offset
criterion). Renders are cached per process (a test worker, the bench) in a temporary directory
keyed by everything that makes them, removed when the process ends.
"""

from __future__ import annotations

import atexit
import functools
import hashlib
import shutil
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

import mido
import numpy as np
import soundfile as sf
from scipy import signal

SOUNDFONT = Path("/usr/share/sounds/sf2/FluidR3_GM.sf2")
PROGRAMS = {"piano": 0, "organ": 19, "guitar": 24, "strings": 48, "flute": 73}
"""General MIDI programs (0-based) of the instruments the tests play."""
RANGES = {"piano": (36, 96), "organ": (36, 91), "guitar": (40, 84), "strings": (36, 88), "flute": (60, 96)}
"""MIDI pitches each instrument is given (its usual compass within the transcriber's range)."""


def have_sampler() -> bool:
    return shutil.which("fluidsynth") is not None and SOUNDFONT.is_file()


@dataclass(frozen=True)
class Note:
    onset: float
    offset: float
    pitch: int
    velocity: int = 90


def random_texture(rng: np.random.Generator, voices: int, seconds: float, low: int, high: int) -> list[Note]:
    """``voices`` independent random lines: notes of 0.2–0.8 s, rests now and then; the
    voices keep apart (each its own band of the compass) so they cross rarely, as in music."""
    notes: list[Note] = []
    span = (high - low) / voices
    for v in range(voices):
        lo, hi = int(low + v * span), int(low + (v + 1) * span)
        t = 0.3 + rng.uniform(0, 0.2)
        while t < seconds - 0.5:
            length = float(rng.choice([0.2, 0.3, 0.4, 0.6, 0.8]))
            if rng.random() > 0.1:
                notes.append(Note(round(t, 4), round(t + length * 0.95, 4), int(rng.integers(lo, max(lo + 1, hi))),
                                  int(rng.integers(60, 111))))
            t += length
    return sorted(notes, key=lambda n: (n.onset, n.pitch))


CHORDS = [(0, 4, 7), (5, 9, 12), (7, 11, 14), (9, 12, 16), (2, 5, 9), (7, 11, 14), (0, 4, 7), (4, 7, 11)]
"""A diatonic progression (scale degrees from the key's tonic) for the composed chorale."""


def chorale(rng: np.random.Generator, voices: int, seconds: float, low: int, high: int) -> list[Note]:
    """A composed texture: a chord progression voiced in ``voices`` parts (bass, then upper
    voices a chord tone apart), one chord per beat, now and then a passing melody note."""
    key = int(rng.integers(0, 12))
    beat = float(rng.choice([0.5, 0.6, 0.75]))
    notes: list[Note] = []
    t, i = 0.3, 0
    bass_low = max(low, 36 + key % 12)
    while t < seconds - 0.6:
        chord = CHORDS[i % len(CHORDS)]
        base = bass_low + chord[0]
        tones = [base] + [base + 12 + c - chord[0] for c in chord][: voices - 1]
        for k, p in enumerate(tones[:voices]):
            while p > high:
                p -= 12
            velocity = int(rng.integers(70, 105))
            if k == voices - 1 and voices > 1 and rng.random() < 0.3:  # melody: two halves
                notes.append(Note(round(t, 4), round(t + beat / 2 * 0.95, 4), p + 12 if p + 12 <= high else p, velocity))
                notes.append(Note(round(t + beat / 2, 4), round(t + beat * 0.95, 4), p, velocity))
            else:
                notes.append(Note(round(t, 4), round(t + beat * 0.95, 4), p, velocity))
        t += beat
        i += 1
    return sorted(set(notes), key=lambda n: (n.onset, n.pitch))


def write_midi(notes: list[Note], program: int, path: Path) -> None:
    track = mido.MidiTrack()
    track.append(mido.MetaMessage("set_tempo", tempo=500000, time=0))  # 120 bpm, 480 tpb → ticks = s * 960
    track.append(mido.Message("program_change", program=program, channel=0, time=0))
    timed = sorted([(n.onset, 1, n.pitch, n.velocity) for n in notes] + [(n.offset, 0, n.pitch, 0) for n in notes])
    now = 0
    for t, on, pitch, velocity in timed:
        tick = int(round(t * 960))
        track.append(mido.Message("note_on" if on else "note_off", note=pitch, velocity=velocity, channel=0,
                                  time=tick - now))
        now = tick
    track.append(mido.MetaMessage("end_of_track", time=960))
    mid = mido.MidiFile(ticks_per_beat=480)
    mid.tracks.append(track)
    mid.save(path)


@functools.lru_cache(maxsize=1)
def cache_dir() -> Path:
    """This process's renders; removed at exit (each test run used to leave ~26 MB in /tmp)."""
    path = Path(tempfile.mkdtemp(prefix="creatures-sampled-"))
    atexit.register(shutil.rmtree, path, ignore_errors=True)
    return path


def fluidsynth(soundfont: Path, mid: Path, wav: Path, rate: int) -> None:
    """``mid`` rendered by fluidsynth through ``soundfont`` into ``wav``. A missing soundfont is
    an error here: fluidsynth itself says so on stderr and renders through its default soundfont
    instead, so a tuning or training set would be made, silently, of another sampler's sound."""
    if not soundfont.is_file():
        raise FileNotFoundError(f"{soundfont}: no such soundfont (Debian packages: fluid-soundfont-gm, "
                                "timgm6mb-soundfont, csound-soundfont, musescore-general-soundfont)")
    subprocess.run(["fluidsynth", "-ni", "-g", "0.8", "-F", str(wav), "-r", str(rate), str(soundfont), str(mid)],
                   check=True, capture_output=True, timeout=600)


def render(notes: list[Note], instrument: str, rate: int) -> np.ndarray:
    """Stereo float32 (frames, 2) at ``rate``: ``notes`` played by fluidsynth on ``instrument``."""
    key = hashlib.sha1(repr((notes, instrument, rate, SOUNDFONT)).encode()).hexdigest()[:16]  # tune_hearing renders another soundfont
    wav = cache_dir() / f"{key}.wav"
    if not wav.exists():
        mid = cache_dir() / f"{key}.mid"
        write_midi(notes, PROGRAMS[instrument], mid)
        fluidsynth(SOUNDFONT, mid, wav, rate)
    audio, sr = sf.read(wav, dtype="float32", always_2d=True)
    assert sr == rate
    return audio


def room(audio: np.ndarray, rate: int, rng: np.random.Generator, *, snr_db: float = 30.0,
         reverb_s: float = 0.4) -> np.ndarray:
    """``audio`` in a room: convolved with an exponentially decaying noise impulse response
    (RT60 ``reverb_s``, 20 % wet) and over pink-ish room noise ``snr_db`` below it."""
    n = int(reverb_s * rate)
    t = np.arange(n) / rate
    ir = rng.standard_normal(n) * np.exp(-6.9 * t / reverb_s)
    ir = 0.2 * ir / np.sqrt(np.sum(ir**2))
    ir[0] += 1.0
    wet = signal.fftconvolve(audio, ir[:, None], axes=0)[: len(audio)]
    hum = signal.lfilter([1.0], [1.0, -0.95], rng.standard_normal(audio.shape), axis=0)
    level = np.sqrt(np.mean(wet**2)) / np.sqrt(np.mean(hum**2)) * 10 ** (-snr_db / 20)
    return (wet + level * hum).astype(np.float32)


def _hz(p: np.ndarray | list[int]) -> np.ndarray:
    return 440.0 * 2.0 ** ((np.asarray(p, dtype=float) - 69.0) / 12.0)


def _reference(reference: list[Note]) -> tuple[np.ndarray, np.ndarray]:
    """mir_eval's intervals and pitches (Hz) of ``reference``."""
    return (np.array([[n.onset, max(n.offset, n.onset + 0.01)] for n in reference]).reshape(-1, 2),
            _hz([n.pitch for n in reference]))


def note_f1(reference: list[Note], estimated: list[tuple[float, float, int]]) -> float:
    """mir_eval note F1: onset within 50 ms, pitch within 50 cents, offsets ignored."""
    import mir_eval

    if not estimated:
        return 0.0
    est_i = np.array([[a, max(b, a + 0.01)] for a, b, _ in estimated])
    _, _, f1, _ = mir_eval.transcription.precision_recall_f1_overlap(*_reference(reference), est_i,
                                                                    _hz([p for _, _, p in estimated]),
                                                                    onset_tolerance=0.05, offset_ratio=None)
    return float(f1)


def answer_delays(reference: list[Note], given: list[tuple[float, int, float]]) -> np.ndarray:
    """Seconds from each heard note's MIDI onset to when its note event was given: ``given`` is
    (the note's time, pitch, the stream time it was given at), matched as :func:`note_f1` matches
    (mir_eval, onset within 50 ms, pitch within 50 cents); notes not heard are not counted."""
    import mir_eval

    if not given:
        return np.zeros(0)
    est_i = np.array([[t, t + 0.01] for t, _, _ in given])
    pairs = mir_eval.transcription.match_notes(*_reference(reference), est_i, _hz([p for _, p, _ in given]),
                                               onset_tolerance=0.05, offset_ratio=None)
    return np.array([given[e][2] - reference[r].onset for r, e in pairs])


def given_times(ear: object, mono: np.ndarray, rate: int, block: int = 64) -> list[tuple[float, int, float]]:
    """Each note event's (time, pitch, and the stream's time when it was given), ``mono`` fed in
    ``block``-frame blocks (64: 1.5 ms at 44.1 kHz, a short JACK period's wait)."""
    given = []
    for i in range(0, len(mono), block):
        end = min(i + block, len(mono)) / rate
        given += [(n.time, n.pitch, end) for n in ear.feed(mono[i:i + block])]
    return given
