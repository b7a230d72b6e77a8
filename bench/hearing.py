"""Hearing: offline analysis speed of a creature's ear (segmentation + cepstra + DTW against
50 templates) as a multiple of real time on a synthetic recording, with librosa's bare MFCC
over the same audio as the anchor; the numba DTW kernel against librosa.sequence.dtw; and
streaming polyphonic transcription (audio/transcribe.py, both looks) of sampled piano at
44.1 kHz, with basic-pitch's published ONNX model (Spotify, Apache-2.0; ``pip install
basic-pitch==0.4.0 --no-deps`` beside ``onnxruntime``) side by side on the same audio where it
is installed, and (without ``--quick``) note F1 per instrument and texture, ours beside the
model's: the table of docs/hearing.md.

Everything is timed under :func:`bench.voice.one_core`: the target is "≥ 100× real time on
one core", and the anchor ratio compares like with like only if librosa's MFCC (whose mel
projection would otherwise use threaded BLAS) gets the same single core as the ear."""

from __future__ import annotations

import time

import librosa
import numpy as np

from audio.cepstrum import cepstra, distances_to, dtw_cost
from audio.formants import SAMPLE_RATE as SR
from audio.formants import WORDS, word
from audio.segment import segment
from bench import Row, best_of
from bench._peers import skipped
from bench._sampled import (RANGES, answer_delays, chorale, given_times, have_sampler, note_f1, random_texture,
                            render)
from bench.voice import one_core


def recording(
    seconds: float, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Words at random gaps over a 20 dB SNR noise bed: the signal, onsets (s), word indices."""
    x = 0.005 * rng.standard_normal(int(seconds * SR))  # the noise bed
    t, onsets, labels = 0.5, [], []
    while True:
        k = int(rng.integers(len(WORDS)))
        w = word(WORDS[k], rng, stretch=rng.uniform(0.8, 1.25), f0=rng.uniform(100, 160), rms=0.05)
        i = int(t * SR)
        if i + len(w) >= len(x):
            return x.astype(np.float32), np.array(onsets), np.array(labels)
        x[i : i + len(w)] += w
        onsets.append(t)
        labels.append(k)
        t += len(w) / SR + rng.uniform(0.25, 0.7)


def _hearing_rows(quick: bool) -> list[Row]:
    seconds = 60.0 if quick else 600.0
    rng = np.random.default_rng(7)
    x, onsets, labels = recording(seconds, rng)
    templates = [cepstra(word(WORDS[k % 5], rng), SR) for k in range(50)]
    heard: list[tuple[float, int]] = []  # (event start, word of the nearest template)

    def hear() -> None:
        heard.clear()
        for event in segment(x, SR):
            nearest = int(np.argmin(distances_to(cepstra(event.samples, SR), templates)))
            heard.append((event.start, nearest % 5))

    def bare_mfcc() -> None:
        librosa.feature.mfcc(y=x, sr=SR, n_mfcc=13)

    hear()  # warm numba and librosa
    bare_mfcc()
    t_hear = best_of(hear, repeat=1 if not quick else 2)
    t_mfcc = best_of(bare_mfcc)
    speed, anchor = seconds / t_hear, seconds / t_mfcc
    said = [labels[np.argmin(np.abs(onsets - start))] for start, _ in heard]
    recognised = np.mean([k == w for k, (_, w) in zip(said, heard)])
    return [
        Row(f"ear on {seconds / 60:g} min ({len(heard)} events/{len(onsets)} words, 50 templates)",
            speed, "× real time", target=100.0, baseline="bare librosa MFCC",
            ratio=speed / anchor),
        Row("bare librosa MFCC, same audio (anchor)", anchor, "× real time"),
        Row("words recognised by the ear (sanity check)", 100 * recognised, "%", target=95.0),
    ]


def _dtw_rows(quick: bool) -> list[Row]:
    rng = np.random.default_rng(8)
    a, b = rng.standard_normal((200, 13)), rng.standard_normal((200, 13))
    pairs = 20 if quick else 100
    dtw_cost(a, b)
    librosa.sequence.dtw(X=a.T, Y=b.T)

    def ours() -> None:
        for _ in range(pairs):
            dtw_cost(a, b)

    def theirs() -> None:
        for _ in range(pairs):
            librosa.sequence.dtw(X=a.T, Y=b.T)

    fast, slow = best_of(ours) / pairs, best_of(theirs) / pairs
    return [
        Row("DTW 200×13 vs 200×13 (numba kernel)", fast * 1e3, "ms", higher_is_better=False,
            baseline="librosa.sequence.dtw", ratio=slow / fast),
        Row("DTW 200×13 vs 200×13 (librosa.sequence.dtw)", slow * 1e3, "ms"),
    ]


BASIC_PITCH = "pip install basic-pitch==0.4.0 --no-deps onnxruntime pretty_midi 'resampy<0.4.3' importlib_resources"
"""How the peer is installed (its own dependencies would pull in TensorFlow)."""


def basic_pitch_model() -> str | None:
    """Where basic-pitch's ONNX model is, if the package (``--no-deps``, with ``onnxruntime``,
    ``pretty_midi``, ``resampy<0.4.3`` and, for pretty_midi 0.2.11, ``importlib_resources``, for its
    note creation) is installed."""
    import importlib.util
    from pathlib import Path

    needed = ("basic_pitch", "onnxruntime", "pretty_midi", "resampy")
    try:
        if any(importlib.util.find_spec(name) is None for name in needed):
            return None
    except ImportError:  # installed but broken (resampy 0.4.2 imports pkg_resources, gone from setuptools 81)
        return None
    spec = importlib.util.find_spec("basic_pitch")
    model = Path(spec.submodule_search_locations[0]) / "saved_models" / "icassp_2022" / "nmp.onnx"
    return str(model) if model.is_file() else None


def basic_pitch_notes(session: object, mono: np.ndarray, rate: int) -> list[tuple[float, float, int]]:
    """basic-pitch's ``predict`` with its own note creation and default thresholds, run on an
    onnxruntime session: 2 s windows at 22.05 kHz overlapping by 30 frames, half the overlap
    cut from each side (``basic_pitch.inference.run_inference``, without its file loading)."""
    import logging

    import soxr

    logging.getLogger().setLevel(logging.ERROR)  # it warns about each backend it lacks (TensorFlow, CoreML)
    from basic_pitch import note_creation

    n, overlap = 43844, 30 * 256
    y = soxr.resample(mono, rate, 22050).astype(np.float32)
    frames_total = int(len(y) * 86 / 22050)
    y = np.concatenate([np.zeros(overlap // 2, np.float32), y])
    note, onset = [], []
    for i in range(0, len(y), n - overlap):
        w = np.pad(y[i:i + n], (0, max(0, n - len(y[i:i + n]))))[None, :, None]
        f, o = session.run(["StatefulPartitionedCall:1", "StatefulPartitionedCall:2"], {"serving_default_input_2:0": w})
        note.append(f[0, 15:-15])
        onset.append(o[0, 15:-15])
    frames, onsets = np.concatenate(note)[:frames_total], np.concatenate(onset)[:frames_total]
    events = note_creation.output_to_notes_polyphonic(frames, onsets, onset_thresh=0.5, frame_thresh=0.3,
                                                      min_note_len=11, infer_onsets=True, max_freq=None,
                                                      min_freq=None, melodia_trick=True)
    times = note_creation.model_frames_to_time(len(frames))
    return [(float(times[a]), float(times[min(b, len(times) - 1)]), int(p)) for a, b, p, *_ in events]


def _stream(ear: object, mono: np.ndarray, block: int = 512) -> list[tuple[float, float, int]]:
    """Feed ``mono`` to a transcriber in ``block``-frame blocks (as a live input gives it); the notes it heard."""
    ear.ended = type(ear.ended)()
    for i in range(0, len(mono), block):
        ear.feed(mono[i:i + block])
    ear.flush()
    return [(n.time, n.end, n.pitch) for n in ear.ended]


def _basic_pitch_session() -> tuple[object | None, str]:
    """An onnxruntime session of basic-pitch's model on one thread, or None and why it (or its
    note creation, which imports pretty_midi) cannot be loaded."""
    model = basic_pitch_model()
    if model is None:
        return None, f"not installed: {BASIC_PITCH}"
    try:
        import onnxruntime
        from basic_pitch import note_creation  # noqa: F401
    except ImportError as exc:
        return None, f"installed but cannot be imported ({exc}): {BASIC_PITCH}"

    options = onnxruntime.SessionOptions()
    options.intra_op_num_threads = options.inter_op_num_threads = 1
    return onnxruntime.InferenceSession(model, options, providers=["CPUExecutionProvider"]), ""


TABLE = [("piano", 1, "random"), ("piano", 4, "random"), ("piano", 4, "chorale"), ("guitar", 1, "random"),
         ("guitar", 3, "chorale"), ("flute", 1, "random"), ("strings", 1, "random"), ("strings", 3, "chorale"),
         ("organ", 1, "random"), ("organ", 3, "chorale")]
"""The side-by-side table of docs/hearing.md: instrument, voices, texture (FluidR3, 22.05 kHz)."""


def _transcription_rows(quick: bool) -> list[Row]:
    """Sampled piano (fluidsynth) at 44.1 kHz, streamed in 512-frame blocks as a live input gives
    it, each look, with basic-pitch's published model on the same audio, and how long after its
    onset each note heard live was given (fed in 64-frame blocks, a short JACK period); then
    (not ``quick``) note F1 per instrument and texture, ours beside the model's."""
    from audio.transcribe import EARS, LIVE, OFFLINE, QUICK, Transcriber

    if not have_sampler():
        return [skipped("transcription", "needs fluidsynth and fluid-soundfont-gm")]
    rate, seconds = 44100, 30.0 if quick else 120.0
    rng = np.random.default_rng(11)
    notes = random_texture(rng, 4, seconds / 2, 36, 96)
    notes += [type(n)(n.onset + seconds / 2, n.offset + seconds / 2, n.pitch, n.velocity)
              for n in chorale(rng, 4, seconds / 2, 36, 96)]
    mono = render(notes, "piano", rate).mean(axis=1)
    rows, speeds = [], {}
    repeat = 1 if quick else 2  # each side's best of as many runs: its first run's warm-up left out alike
    for look in (LIVE, QUICK, OFFLINE):
        heard: list[tuple[float, float, int]] = []

        def stream() -> None:
            heard[:] = _stream(Transcriber(rate, look=look), mono)

        ear = Transcriber(rate, look=look)
        speed = len(mono) / rate / best_of(stream, repeat=repeat, clock=time.process_time)
        speeds[look] = Row(f"transcription, 4-voice piano 44.1 kHz, {look} look ({1e3 * ear.latency:.0f} ms), "
                           "one core", speed, "× real time", target=50.0)
        rows.append(speeds[look])
        rows.append(Row(f"  note F1 (mir_eval, onset 50 ms), {look} look", note_f1(notes, heard), "", target=0.75))
    for look in (LIVE, QUICK):  # every note of a chord, not only a line's: the issue's ≤ 60 ms
        delays = 1e3 * answer_delays(notes, given_times(Transcriber(rate, look=look), mono, rate))
        if not delays.size:
            rows.append(Row(f"  onset → note event, {look} look (no note heard)", 0.0, "ms"))
            continue
        rows.append(Row(f"  onset → note event, {look} look, p90 (p50 {np.median(delays):.0f}, max {delays.max():.0f} ms; "
                        f"{np.mean(delays <= 60):.0%} ≤ 60 ms)", float(np.percentile(delays, 90)), "ms",
                        target=60.0, higher_is_better=False))
    session, why = _basic_pitch_session()
    if session is None:
        return rows + [skipped("basic-pitch ONNX, same audio", why)]
    theirs: list[tuple[float, float, int]] = []

    def infer() -> None:
        theirs[:] = basic_pitch_notes(session, mono, rate)

    their_speed = len(mono) / rate / best_of(infer, repeat=repeat, clock=time.process_time)
    offline = speeds[OFFLINE]  # the like-for-like look
    offline.baseline, offline.ratio = "basic-pitch ONNX", offline.value / their_speed
    rows += [
        Row("basic-pitch ONNX, same audio (offline, 2 s windows)", their_speed, "× real time"),
        Row("  note F1 (basic-pitch ONNX)", note_f1(notes, theirs), ""),
    ]
    if quick:
        return rows
    for instrument, voices, texture in TABLE:
        f1: dict[str, list[float]] = {}
        for seed in (1, 2):
            tune = (random_texture if texture == "random" else chorale)(np.random.default_rng([seed, voices]), voices,
                                                                       20.0, *RANGES[instrument])
            sound = render(tune, instrument, 22050).mean(axis=1)
            each = (("onsets",), ("model",), EARS)
            for look, ear_sets in ((OFFLINE, each), (LIVE, each), (QUICK, (EARS,))):  # the quick look: two ears
                for ears in ear_sets:
                    heard = _stream(Transcriber(22050, look=look, ears=ears), sound)
                    f1.setdefault(f"{look} {'+'.join(ears)}", []).append(note_f1(tune, heard))
            f1.setdefault("basic-pitch", []).append(note_f1(tune, basic_pitch_notes(session, sound, 22050)))
        means = {k: float(np.mean(v)) for k, v in f1.items()}
        ours, model = means[f"{OFFLINE} {'+'.join(EARS)}"], means["basic-pitch"]
        detail = ", ".join(f"{k} {v:.2f}" for k, v in means.items() if k != "basic-pitch")
        rows.append(Row(f"  F1 {instrument} {voices}v {texture}, two ears offline ({detail})", ours, "",
                        baseline="basic-pitch", ratio=ours / max(model, 1e-9)))
        rows.append(Row(f"  F1 {instrument} {voices}v {texture}, basic-pitch", model, ""))
    return rows


def run(quick: bool) -> list[Row]:
    t0 = time.perf_counter()
    with one_core():
        rows = _dtw_rows(quick) + _hearing_rows(quick) + _transcription_rows(quick)
    rows.append(Row("benchmark wall time", time.perf_counter() - t0, "s"))
    return rows
