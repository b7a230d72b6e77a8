"""Training material for the note model (audio/note_model.py): music generated in code, rendered
by fluidsynth through General MIDI soundfonts, put in rooms, and turned into the model's
features and frame labels.

Held out on purpose: **FluidR3_GM**, the soundfont every test and the bench score on, is never
rendered here; the model learns from TimGM6mb, Csound's GM bank (``sf_GMbank``), MuseScore
General (Debian: ``timgm6mb-soundfont csound-soundfont musescore-general-soundfont``) and plain
additive tones. MuseScore General grew out of FluidR3 and still plays FluidR3's own samples for
about half of the General MIDI programs (its church organ and nylon guitar are FluidR3's, sample
for sample): :func:`shared_programs` finds them by rendering every program from both, and those
programs are never rendered from MuseScore General, so no test timbre is heard in training. The textures are this module's own (lines, block chords with doublings,
chorales, arpeggios, melody over chords, isolated notes), not the tests' generators.

Used by ``tools/train_hearing.py``; run alone it renders a set::

    python -m tools.hearing_data OUT_DIR --segments 600 --seed 1

or, with ``--from DIR``, gives the sets rendered there the features of another hop (their audio
is kept for that): the quick look's model hears on a finer grid than the others::

    python -m tools.hearing_data OUT_DIR --from DIR --hop 128
"""

from __future__ import annotations

import argparse
import tempfile
from dataclasses import dataclass
from pathlib import Path

import mido
import numpy as np
import soundfile as sf
from scipy import signal

from audio.logspectrum import HOP, RATE, LogSpectrum
from audio.note_model import HIGH, LOW
from bench._sampled import SOUNDFONT as FLUIDR3  # the tests' and the bench's sampler, never trained on
from bench._sampled import fluidsynth

SOUNDFONTS = {
    "timgm": Path("/usr/share/sounds/sf2/TimGM6mb.sf2"),
    "csound": Path("/usr/share/sounds/sf2/sf_GMbank.sf2"),
    "musescore": Path("/usr/share/sounds/sf3/MuseScore_General_Full.sf3"),
}
SEGMENT = 10.0
GAP = 1.0

# (programs, lowest, highest, weight): General MIDI families and their usual compasses.
FAMILIES = [
    ((0, 1, 2, 3, 4, 5, 6, 7), 21, 108, 0.22),  # pianos, harpsichord, clavinet
    ((8, 9, 10, 11, 12, 13, 14, 15), 48, 100, 0.05),  # chromatic percussion
    ((16, 17, 18, 19, 20, 21, 22, 23), 28, 96, 0.12),  # organs, accordion, harmonica
    ((24, 25, 26, 27, 28, 29, 30, 31), 40, 88, 0.12),  # guitars
    ((32, 33, 34, 35, 36, 37, 38, 39), 28, 60, 0.05),  # basses
    ((40, 41, 42, 43, 44, 45, 46), 28, 100, 0.08),  # solo strings, tremolo, pizzicato, harp
    ((48, 49, 50, 51, 52, 53, 54), 36, 96, 0.1),  # ensembles, choirs
    ((56, 57, 58, 59, 60, 61, 62, 63), 36, 84, 0.05),  # brass
    ((64, 65, 66, 67, 68, 69, 70, 71), 40, 96, 0.06),  # reeds
    ((72, 73, 74, 75, 76, 77, 78, 79), 55, 100, 0.08),  # pipes
    ((80, 81, 82, 83, 84, 85, 86, 87, 88, 89, 90, 91, 92, 93, 94, 95), 36, 96, 0.04),  # synth leads, pads
    ((104, 105, 106, 107, 108, 109, 110, 111), 40, 96, 0.03),  # ethnic
]
CHORD_SHAPES = [(0, 4, 7), (0, 3, 7), (0, 4, 7, 10), (0, 3, 7, 10), (0, 4, 7, 11), (0, 5, 7), (0, 2, 7),
                (0, 3, 6), (0, 4, 8), (0, 7, 12), (0, 4, 7, 14), (0, 3, 5), (0, 1, 3)]
SCALE = (0, 2, 4, 5, 7, 9, 11)


@dataclass(frozen=True)
class Note:
    onset: float
    offset: float
    pitch: int
    velocity: int
    channel: int = 0


def _length(rng: np.random.Generator) -> float:
    return float(np.clip(rng.lognormal(np.log(0.35), 0.7), 0.06, 2.5))


def lines(rng, low, high, voices, channel=0):
    notes, span = [], (high - low) / voices
    for v in range(voices):
        lo, hi = int(low + v * span), int(low + (v + 1) * span)
        t = rng.uniform(0.0, 0.3)
        while t < SEGMENT - 0.3:
            d = _length(rng)
            if rng.random() > 0.15:
                legato = rng.choice([0.5, 0.9, 1.0, 1.2])
                notes.append(Note(t, t + d * legato, int(rng.integers(lo, max(lo + 1, hi))), int(rng.integers(25, 128)), channel))
            t += d
    return notes


def chords(rng, low, high, voices, channel=0):
    notes, t = [], rng.uniform(0.0, 0.3)
    while t < SEGMENT - 0.3:
        d = float(rng.choice([0.2, 0.3, 0.5, 0.75, 1.0, 1.5, 2.0]))
        shape = CHORD_SHAPES[rng.integers(len(CHORD_SHAPES))]
        root = int(rng.integers(low, max(low + 1, high - 14)))
        tones = {root + s for s in shape}
        if rng.random() < 0.6:
            tones.add(root + 12 * int(rng.integers(1, 3)))  # an octave doubling
        if rng.random() < 0.3:
            tones.add(root - 12)
        tones = sorted(p for p in tones if low <= p <= high)[: max(2, voices + 2)]
        v = int(rng.integers(30, 128))
        for p in tones:
            notes.append(Note(t, t + d * rng.uniform(0.6, 1.0), p, int(np.clip(v + rng.integers(-12, 13), 1, 127)), channel))
        t += d + (rng.uniform(0.0, 0.5) if rng.random() < 0.2 else 0.0)
    return notes


def chorale(rng, low, high, voices, channel=0):
    key, beat = int(rng.integers(0, 12)), float(rng.uniform(0.35, 1.0))
    notes, t = [], rng.uniform(0.0, 0.3)
    bass = max(low, min(high - 24, 36 + key))
    while t < SEGMENT - 0.3:
        degree = int(rng.integers(0, 7))
        chord = [SCALE[(degree + k) % 7] + 12 * ((degree + k) // 7) for k in (0, 2, 4)]
        tones = [bass + chord[0]] + [bass + 12 + c for c in chord] + [bass + 24 + chord[0]]
        keep = [tones[0]] + sorted(rng.choice(tones[1:], size=min(voices, 4) - 1, replace=False).tolist())
        v = int(rng.integers(40, 120))
        for p in keep:
            while p > high:
                p -= 12
            if p >= low:
                notes.append(Note(t, t + beat * 0.95, int(p), int(np.clip(v + rng.integers(-10, 11), 1, 127)), channel))
        t += beat
    return notes


def arpeggio(rng, low, high, voices, channel=0):
    notes, t = [], rng.uniform(0.0, 0.3)
    step = float(rng.uniform(0.08, 0.3))
    while t < SEGMENT - 0.5:
        shape = CHORD_SHAPES[rng.integers(len(CHORD_SHAPES))]
        root = int(rng.integers(low, max(low + 1, high - 24)))
        pattern = [root + s + 12 * o for o in range(2) for s in shape]
        hold = float(rng.uniform(0.3, 1.5))
        v = int(rng.integers(30, 120))
        for p in pattern:
            if low <= p <= high:
                notes.append(Note(t, t + hold, p, int(np.clip(v + rng.integers(-15, 16), 1, 127)), channel))
            t += step
    return notes


def isolated(rng, low, high, voices, channel=0):
    notes, t = [], rng.uniform(0.0, 0.3)
    while t < SEGMENT - 0.3:
        d = _length(rng)
        notes.append(Note(t, t + d, int(rng.integers(low, high + 1)), int(rng.integers(20, 128)), channel))
        t += d + rng.uniform(0.05, 0.6)
    return notes


TEXTURES = [(lines, 0.35), (chords, 0.2), (chorale, 0.15), (arpeggio, 0.12), (isolated, 0.18)]


def segment(rng: np.random.Generator, banned: set[int] = frozenset()) -> tuple[list[Note], dict[int, int]]:
    """One segment's notes and its channels' programs (one instrument, or two: a second, lower
    or higher, on channel 1 now and then), none of them ``banned``."""
    weights = np.array([f[3] for f in FAMILIES])
    programs: dict[int, int] = {}
    notes: list[Note] = []
    parts = 2 if rng.random() < 0.25 else 1
    if rng.random() < 0.06:
        parts = 0  # a segment of the room alone: noise, hum, nothing to hear as notes
    for channel in range(parts):
        programs_: list[int] = []
        while not programs_:  # a family the soundfont still has programs of
            family, low, high, _ = FAMILIES[rng.choice(len(FAMILIES), p=weights / weights.sum())]
            programs_ = [p for p in family if p not in banned]
        programs[channel] = int(rng.choice(programs_))
        low, high = max(low, LOW), min(high, HIGH)
        texture = TEXTURES[rng.choice(len(TEXTURES), p=[w for _, w in TEXTURES])][0]
        voices = int(rng.integers(1, 5)) if parts == 1 else int(rng.integers(1, 3))
        notes += texture(rng, low, high, voices, channel)
    return notes, programs or {0: 0}


def write_midi(segments: list[tuple[list[Note], dict[int, int]]], path: Path) -> list[Note]:
    """One MIDI file of the segments one after another (``GAP`` s of silence between), and
    their notes on that timeline (an overlapping repeat of a pitch is cut where it restrikes)."""
    events: list[tuple[float, int, mido.Message]] = []
    timeline: list[Note] = []
    for i, (notes, programs) in enumerate(segments):
        t0 = i * (SEGMENT + GAP)
        for channel, program in programs.items():
            events.append((t0, 0, mido.Message("program_change", channel=channel, program=program)))
        by_key: dict[tuple[int, int], list[Note]] = {}
        for n in notes:
            by_key.setdefault((n.channel, n.pitch), []).append(n)
        for group in by_key.values():
            group.sort(key=lambda n: n.onset)
            for a, b in zip(group, group[1:] + [None]):
                end = min(a.offset, SEGMENT, b.onset - 0.01 if b is not None else SEGMENT)
                if end - a.onset < 0.03:
                    continue
                note = Note(t0 + a.onset, t0 + end, a.pitch, a.velocity, a.channel)
                timeline.append(note)
                events.append((note.onset, 2, mido.Message("note_on", channel=a.channel, note=a.pitch, velocity=a.velocity)))
                events.append((note.offset, 1, mido.Message("note_off", channel=a.channel, note=a.pitch)))
    events.sort(key=lambda e: (e[0], e[1]))
    track = mido.MidiTrack([mido.MetaMessage("set_tempo", tempo=500000, time=0)])
    now = 0
    for t, _, message in events:
        tick = int(round(t * 960))
        track.append(message.copy(time=tick - now))
        now = tick
    track.append(mido.MetaMessage("end_of_track", time=960))
    mid = mido.MidiFile(ticks_per_beat=480)
    mid.tracks.append(track)
    mid.save(path)
    return sorted(timeline, key=lambda n: (n.onset, n.pitch))


def additive(notes: list[Note], seconds: float, rng: np.random.Generator) -> np.ndarray:
    """Plain harmonic tones for ``notes``: random partial strengths, attacks and decays; or, for
    two notes in five, a pipe organ's registration — the note's 8' foundation (sometimes weak)
    with stops an octave, a twelfth, two octaves … above, now and then a 16' below — which
    sounds an octave up or down as much as at its pitch, and is still called by its key; or,
    for one in five, the few ``1/k`` partials of the project's own generated input
    (``creatures.runtime.inputs.render_notes``), whose even partials a chord's octave would share."""
    out = np.zeros(int(seconds * RATE), dtype=np.float32)
    for n in notes:
        start = int(n.onset * RATE)
        length = min(int((n.offset - n.onset + 0.15) * RATE), len(out) - start)
        if length <= 0:
            continue
        t = np.arange(length) / RATE
        f0 = 440.0 * 2 ** ((n.pitch - 69) / 12)
        mode = rng.random()
        if mode < 0.2:
            k = np.arange(1, int(rng.integers(2, 7)) + 1).astype(float)
            k = k[k * f0 < 0.45 * RATE]
            amps = 1.0 / k
        elif mode < 0.6:
            ratios = [1.0] + [r for r in (0.5, 2.0, 3.0, 4.0, 6.0, 8.0) if rng.random() < (0.15 if r < 1 else 0.4)]
            levels = [rng.uniform(0.15, 1.0)] + list(rng.uniform(0.2, 1.0, len(ratios) - 1))
            partials: dict[float, float] = {}
            for ratio, level in zip(ratios, levels):
                for k in range(1, int(rng.integers(1, 5)) + 1):  # a flue pipe: few partials
                    partials[ratio * k] = partials.get(ratio * k, 0.0) + level / k**1.5
            k = np.array([m for m in partials if m * f0 < 0.45 * RATE])
            amps = np.array([partials[m] for m in k])
        else:
            k = np.arange(1, int(rng.integers(1, 12)) + 1).astype(float)
            k = k[k * f0 < 0.45 * RATE]
            amps = rng.uniform(0.2, 1.0, len(k)) / k ** rng.uniform(0.5, 2.0)
        if not len(k):
            continue
        tone = (amps[:, None] * np.sin(2 * np.pi * np.outer(k, f0 * t) + rng.uniform(0, 6.3, len(k))[:, None])).sum(0)
        attack = rng.uniform(0.002, 0.08)
        env = np.minimum(1.0, t / attack) * np.exp(-rng.uniform(0.0, 4.0) * t)
        env *= np.clip((n.offset - n.onset + 0.15 - t) / 0.15, 0.0, 1.0)  # released over 0.15 s
        out[start:start + length] += 0.25 * n.velocity / 127 * env * tone / max(amps.sum(), 1e-9)
    return out


def thumps(x: np.ndarray, onsets: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Unpitched knocks at some of ``onsets`` (s, within ``x``): low-passed noise bursts, as a
    hammer, a key or a pick makes, which are not notes (FluidR3's high piano notes thump low)."""
    x = x.copy()
    level = np.sqrt(np.mean(x**2)) + 1e-6
    for t in onsets[rng.random(len(onsets)) < 0.3]:
        n = int(rng.uniform(0.02, 0.12) * RATE)
        i = int(t * RATE)
        burst = signal.lfilter(*signal.butter(2, rng.uniform(80, 1500), fs=RATE), rng.standard_normal(n))
        burst *= np.exp(-np.arange(n) / (rng.uniform(0.005, 0.04) * RATE))
        burst *= level * 10 ** (rng.uniform(-15, 5) / 20) / (np.sqrt(np.mean(burst**2)) + 1e-9)
        x[i:i + n] += burst[: len(x) - i]
    return x


def room(x: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """A room for one segment: maybe reverb; a gain, now and then far too much (a microphone
    clipping); maybe noise of some colour, or mains hum, from the start or switched on partway
    (a fan, an amplifier); now and then a DC step."""
    if rng.random() < 0.4:
        rt = rng.uniform(0.2, 1.2)
        n = int(rt * RATE)
        ir = rng.standard_normal(n) * np.exp(-6.9 * np.arange(n) / RATE / rt)
        ir = rng.uniform(0.1, 0.5) * ir / np.sqrt(np.sum(ir**2))
        ir[0] += 1.0
        x = signal.fftconvolve(x, ir)[: len(x)]
    x = x * 10 ** (rng.uniform(-30, 3) / 20)
    if rng.random() < 0.1:
        x = np.clip(x / (np.abs(x).max() + 1e-9) * 10 ** (rng.uniform(6, 30) / 20), -1.0, 1.0)
    if rng.random() < 0.6:
        if rng.random() < 0.15:
            t = np.arange(len(x)) / RATE
            mains = rng.choice([50.0, 60.0])
            noise = sum(np.sin(2 * np.pi * k * mains * t + rng.uniform(0, 6.3)) / k for k in range(1, 8))
        else:
            noise = signal.lfilter([1.0], [1.0, -rng.choice([0.0, 0.5, 0.9, 0.99])], rng.standard_normal(len(x)))
        noise = noise / np.sqrt(np.mean(noise**2)) * 10 ** (rng.uniform(-80, -12) / 20)
        if rng.random() < 0.2:
            noise[: int(rng.uniform(0, len(x)))] = 0.0  # switched on partway
        x = x + noise
    if rng.random() < 0.05:
        x[int(rng.uniform(0, len(x))):] += rng.uniform(-0.3, 0.3)
    return np.clip(x, -1.0, 1.0).astype(np.float32)


SAME_SAMPLES = 0.97
"""Spectral correlation (a note's magnitude spectrum, its first 0.5 s, at any of three pitches)
above which a program counts as played with FluidR3's samples. Measured: MuseScore General's
church organ and nylon guitar 1.00 at every pitch; 88 of its programs above 0.97; TimGM6mb, an
independent soundfont, 4 (simple timbres: an electric piano, a synth bass, voice oohs, a
piccolo) and sf_GMbank 3 — excluded too, to be safe."""


def shared_programs(soundfont: Path, pitches: tuple[int, ...] = (48, 67, 84)) -> set[int]:
    """The General MIDI programs ``soundfont`` plays with FluidR3's samples (at any of ``pitches``)."""
    track = mido.MidiTrack()
    for program in range(128):
        for p in pitches:
            track += [mido.Message("program_change", program=program), mido.Message("note_on", note=p, velocity=100),
                      mido.Message("note_off", note=p, time=480), mido.Message("note_on", note=p, velocity=0, time=480)]
    mid = mido.MidiFile(ticks_per_beat=480)  # 120 bpm: a note a second
    mid.tracks.append(track)
    renders = []
    with tempfile.TemporaryDirectory() as tmp:
        mid.save(Path(tmp) / "all.mid")
        for font in (FLUIDR3, soundfont):
            wav = Path(tmp) / "all.wav"
            fluidsynth(font, Path(tmp) / "all.mid", wav, RATE)
            renders.append(sf.read(wav, dtype="float32", always_2d=True)[0].mean(axis=1))
    shared = set()
    for program in range(128):
        for j in range(len(pitches)):
            i = (program * len(pitches) + j) * RATE
            a, b = (np.abs(np.fft.rfft(r[i:i + RATE // 2])) for r in renders)
            if a.std() > 0 and b.std() > 0 and np.corrcoef(a, b)[0, 1] > SAME_SAMPLES:
                shared.add(program)
    return shared


def features(audio: np.ndarray, hop: int = HOP) -> np.ndarray:
    """The model's feature rows of ``audio`` (float32 at :data:`RATE`), as float16 (half the memory
    in training; the rows are log-compressed, so float16's 3 digits lose nothing the model uses)."""
    spectrum = LogSpectrum(hop)
    return np.concatenate([spectrum.feed(audio[i:i + (1 << 18)]) for i in range(0, len(audio), 1 << 18)]).astype(np.float16)


def save(path: Path, audio: np.ndarray, notes: np.ndarray, hop: int = HOP) -> None:
    """A set as training reads it: features, the notes (onset, offset, pitch), the hop (seconds)
    and the audio (16-bit, for other front-ends)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez(path, features=features(audio, hop), notes=notes, hop=np.array(hop / RATE),
             audio=np.round(audio * 32767).astype(np.int16))


def refeature(source: Path, out: Path, hop: int) -> None:
    """``source``'s set with the features of ``hop``: written as ``out/<its name>``."""
    with np.load(source) as z:
        audio, notes = z["audio"].astype(np.float32) / 32767, z["notes"]
    save(out / source.name, audio, notes, hop)


def render_set(out: Path, source: str, segments: int, seed: int) -> None:
    """Render ``segments`` segments through ``source`` (a soundfont's name or "additive") and
    write ``out/<source>-<seed>.npz``: features (float16), the notes (onset, offset, pitch) and
    the audio (16-bit, for other front-ends)."""
    rng = np.random.default_rng([seed, len(source)])
    banned = shared_programs(SOUNDFONTS[source]) if source in SOUNDFONTS else set()  # no test timbre
    made = [segment(rng, banned) for _ in range(segments)]
    seconds = segments * (SEGMENT + GAP)
    with tempfile.TemporaryDirectory() as tmp:
        mid = Path(tmp) / "set.mid"
        notes = write_midi(made, mid)
        if source == "additive":
            audio = additive(notes, seconds, rng)
        else:
            wav = Path(tmp) / "set.wav"
            fluidsynth(SOUNDFONTS[source], mid, wav, RATE)
            audio = sf.read(wav, dtype="float32", always_2d=True)[0].mean(axis=1)
    audio = np.r_[audio, np.zeros(max(0, int(seconds * RATE) - len(audio)), np.float32)][: int(seconds * RATE)]
    step = int((SEGMENT + GAP) * RATE)
    onsets = np.array([n.onset for n in notes])
    for i in range(segments):
        part = audio[i * step:(i + 1) * step]
        if rng.random() < 0.5:
            part = thumps(part, onsets[(onsets >= i * step / RATE) & (onsets < (i + 1) * step / RATE)] - i * step / RATE, rng)
        audio[i * step:(i + 1) * step] = room(part, rng)
    table = np.array([(n.onset, n.offset, n.pitch) for n in notes], dtype=np.float64)
    save(out / f"{source}-{seed}.npz", audio, table)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--segments", type=int, default=300)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--sources", default="timgm,csound,musescore,additive")
    parser.add_argument("--from", dest="source", type=Path, help="a directory of rendered sets: give them --hop's features")
    parser.add_argument("--hop", type=int, default=HOP)
    args = parser.parse_args()
    if args.hop <= 0 or HOP % args.hop:
        parser.error(f"--hop must divide {HOP} (the onset ear's hop, which a transcriber's model grid refines), not {args.hop}")
    if args.source is not None:
        for path in sorted(args.source.glob("*.npz")):
            refeature(path, args.out, args.hop)
            print(f"{path.name}: features every {args.hop} samples", flush=True)
        return
    for source in args.sources.split(","):
        render_set(args.out, source, args.segments, args.seed)
        print(f"rendered {source} seed {args.seed}", flush=True)


if __name__ == "__main__":
    main()
