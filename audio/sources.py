"""Where a creature's ear gets its sound: live input, files and arrays behind one interface.

A creature hears through a microphone (thesis: "soundcreatures", a microphone-as-ear) or, for
offline runs and tests, from a recording. Every source yields mono float32 blocks at one
known analysis rate, so segmentation and cepstral analysis never care where sound came from.

Live input follows DESIGN.md ("The audio callback only copies blocks"): the PortAudio callback
copies each block into a preallocated single-producer/single-consumer :class:`RingBuffer` and
returns; overruns are counted, never logged. Cleaning (NaN/inf) and resampling happen on the
creature's side, in :meth:`LiveInput.read`. A microphone that survives its device vanishing
and returning is :class:`audio.resilient.ResilientInput`.
"""

from __future__ import annotations

import logging
import math
import os
import re
from abc import ABC, abstractmethod
from pathlib import Path
from typing import Any, Callable, Iterator

import numpy as np
import soundfile
import soxr

from audio.device import AudioBackend, AudioDeviceUnavailable, find_device, portaudio, start_stream
from audio.resample import Resampler

_log = logging.getLogger(__name__)

ANALYSIS_RATE = 22050
"""The rate every source delivers (librosa's default; enough for speech and song)."""

MIN_FILE_RATE = 1000
"""Lowest sample rate a sound file may declare. Resampling multiplies a file's size by
``samplerate / rate``: a 44 kB file claiming 1 Hz would unpack to 2 GB at 22.05 kHz."""

MAX_FILE_RATE = 768_000
"""Highest sample rate a sound file may declare: the fastest audio interfaces record at 768 kHz.
A damaged header's rate of 2 GHz made six seconds of a phrase 0.1 ms long, heard as nothing."""

RESAMPLE_MARGIN = 1.0
"""Seconds read past the part of a file that is wanted (:func:`load_audio`'s ``seconds``): soxr's
filter looks ahead a few milliseconds, and with this margin the wanted samples come out exactly
as the whole file's would (measured: 1000 samples at 44.1 kHz suffice)."""

FULL_SCALE = 0.999
"""A live sample this loud (or louder) is counted as clipped."""

LARGEST_SAMPLE = 1e3
"""The largest magnitude a sample may have: 1000 × full scale, +60 dB. Float recordings may
legally go a little past ±1.0 (a mix summed without limiting), never this far; beyond it a
sample is garbage (a wrong byte order, a corrupt float file, a driver writing junk), and at
±1e18 the spectra's squares overflow float32 to inf, which crashed the offline ear in scipy's
clustering. A file holding such samples is refused like one holding NaN/inf; live, they are
counted and zeroed like non-finite ones."""

CANCELLED_DB = 20.0
"""A file's channels mixed this far below their own level cancel: one is the other inverted (a
balanced lead wired the other way round), and the ear, which hears the mix, hears almost
nothing. Unrelated channels mix 3 dB below theirs, a wide stereo mix a few dB more."""

READ_BLOCK = 4096
"""Frames read at a time from a file whose decoder failed part-way, so the frames before the
fault are kept (a whole-file read returns nothing but the error). libsndfile cannot seek in a
FLAC once its decoder has lost sync, so the fault is found in one pass of blocks this size:
up to 0.1 s at 44.1 kHz before it is lost with it."""

_PROMISED = re.compile(r"^\s*(?:data|SSND)\s*:\s*(\d+)\s*\(should be (\d+)\)", re.MULTILINE)
"""libsndfile's log line for a WAV's data chunk (an AIFF's SSND) that claims more bytes than the
file holds."""

_BYTES_PER_SECOND = re.compile(r"^\s*Bytes/sec\s*:\s*(\d+)", re.MULTILINE)
"""libsndfile's log line of a WAV's fmt chunk: what the promised bytes are in seconds."""

_FRAMES = re.compile(r"^\s*Frames\s*:\s*(\d+)", re.MULTILINE)
"""libsndfile's log line of an AIFF's COMM chunk: the frames it promises."""

_UNENDED = "Ogg: Last page lacks an end-of-stream bit."
"""libsndfile's log line for an Ogg stream cut short: it is read up to its last whole page."""

STREAMED = 0x7FFF0000
"""A data chunk this large (2 GiB less 64 kB) or larger is a placeholder, not a promise: a WAV
written to a pipe cannot have its sizes patched in at its end (``espeak-ng --stdout`` writes
0x7ffff000, ffmpeg 0xffffffff), and holds all there is. A real WAV this long that was cut short
is heard up to where it ends without that being said."""

__all__ = [
    "ANALYSIS_RATE",
    "ArraySource",
    "AudioDeviceUnavailable",
    "AudioFileError",
    "AudioSource",
    "FileSource",
    "LiveInput",
    "RingBuffer",
    "load_audio",
    "unusable",
]


class AudioFileError(ValueError):
    """A sound file cannot be heard (unreadable, empty, non-finite); the message names it."""


def unusable(samples: np.ndarray) -> np.ndarray:
    """Mask of the samples no ear can take: NaN, ±inf, or beyond :data:`LARGEST_SAMPLE`.

    One test (``not |x| <= bound``, false for NaN) so file and live input agree on what is garbage.
    """
    return ~(np.abs(samples) <= LARGEST_SAMPLE)


def _refuse_unusable(path: Path, data: np.ndarray, rate: int) -> None:
    """Raise :class:`AudioFileError` naming ``path``, the count and the first place of bad samples.

    NaN/inf and samples past :data:`LARGEST_SAMPLE` are told apart: the fix differs (a broken
    writer versus a wrong scale or format).
    """
    for bad, what in (
        (~np.isfinite(data), "NaN/inf samples"),
        (unusable(data), f"samples beyond ±{LARGEST_SAMPLE:g}, +60 dB over full scale"),
    ):
        if bad.any():
            frame = int(np.argmax(bad.any(axis=1)))
            raise AudioFileError(f"{path}: {int(bad.sum())} {what} (first at {frame / rate:.3f} s)")


class AudioSource(ABC):
    """Blocks of mono float32 samples at :attr:`samplerate`.

    :meth:`read` returns the next block, an empty block when a live source has nothing new
    yet, or ``None`` when the source is exhausted. Iterating yields blocks until exhaustion.
    """

    samplerate: int

    @abstractmethod
    def read(self) -> np.ndarray | None: ...

    def __iter__(self) -> Iterator[np.ndarray]:
        while (block := self.read()) is not None:
            yield block


class ArraySource(AudioSource):
    """A numpy signal cut into blocks: the in-memory source for tests and offline analysis."""

    def __init__(self, samples: np.ndarray, samplerate: int, *, block_size: int = 1024) -> None:
        if block_size < 1:
            raise ValueError(f"block_size must be positive (got {block_size})")
        self.samples = np.ascontiguousarray(samples, dtype=np.float32)
        if self.samples.ndim != 1:
            raise ValueError(
                f"ArraySource wants a mono 1-D signal (got shape {self.samples.shape})"
            )
        self.samplerate = int(samplerate)
        self.block_size = int(block_size)
        self._pos = 0

    def read(self) -> np.ndarray | None:
        if self._pos >= len(self.samples):
            return None
        block = self.samples[self._pos : self._pos + self.block_size]
        self._pos += len(block)
        return block


def _cut_short(sound: soundfile.SoundFile) -> str | None:
    """What a file cut short lacks ("of the 6.0 s its header promises"), or None when it holds
    all it promised.

    libsndfile reads a WAV or AIFF cut short (a recorder that crashed, a copy that stopped) up to
    where it ends, and an Ogg stream up to its last whole page, and only notes the difference in
    its log; the file is heard, and said. A header that promises nothing it can be held to (a
    streamed WAV's placeholder size, :data:`STREAMED`) is not a cut."""
    info = sound.extra_info
    if _UNENDED in info:
        return "and ends without its end-of-stream page"
    found = _PROMISED.search(info)
    if found is None or int(found[1]) <= int(found[2]) or int(found[1]) >= STREAMED:
        return None
    per_second, frames = _BYTES_PER_SECOND.search(info), _FRAMES.search(info)
    if per_second is not None:
        promised = int(found[1]) / int(per_second[1])
    elif frames is not None:
        promised = int(frames[1]) / sound.samplerate
    elif int(found[2]):
        promised = sound.frames * int(found[1]) / int(found[2]) / sound.samplerate
    else:
        return None
    return f"of the {promised:,.1f} s its header promises"


def _is_midi(path: Path) -> bool:
    """Whether ``path`` begins as a Standard MIDI File (or one in a RIFF ``RMID`` wrapper): given
    where sound belongs (the phrase beside its render), libsndfile only says "Format not
    recognised", as of a damaged file."""
    with open(path, "rb") as handle:
        head = handle.read(12)
    return head.startswith(b"MThd") or (head.startswith(b"RIFF") and head[8:12] == b"RMID")


def _read_what_decodes(sound: soundfile.SoundFile, frames: int, dtype: str) -> tuple[np.ndarray, str | None]:
    """``frames`` frames of the open ``sound`` (-1: all), and why the read stopped early if the
    decoder failed.

    A FLAC cut inside its data fails in the decoder, and one read of the whole file returns
    nothing but the error: a three-hour field recording missing its last minute was refused
    whole. Read again block by block from a fresh handle (libsndfile cannot seek in a FLAC
    whose decoder lost sync), everything before the fault is kept."""
    try:
        return sound.read(frames, dtype=dtype, always_2d=True), None
    except (soundfile.LibsndfileError, RuntimeError) as exc:
        fault = exc
    blocks: list[np.ndarray] = []
    left = frames if frames >= 0 else sound.frames
    with soundfile.SoundFile(sound.name) as again:
        while left > 0:
            try:
                block = again.read(min(READ_BLOCK, left), dtype=dtype, always_2d=True)
            except (soundfile.LibsndfileError, RuntimeError):
                break
            if block.shape[0] == 0:
                break
            blocks.append(block)
            left -= block.shape[0]
    if not blocks:
        raise fault
    return np.concatenate(blocks), str(fault).strip()


def _cancelled(data: np.ndarray, mono: np.ndarray) -> float | None:
    """How far (dB) the mix ``mono`` of ``data``'s channels lies below their mean level, when
    past :data:`CANCELLED_DB`; else None."""
    channels = float(np.mean(np.square(data, dtype=np.float64)))
    mixed = float(np.mean(np.square(mono, dtype=np.float64)))
    if channels == 0.0:
        return None
    below = 10.0 * math.log10(channels / max(mixed, channels * 1e-12))
    return below if below >= CANCELLED_DB else None


def load_audio(path: str | os.PathLike, *, samplerate: int = ANALYSIS_RATE,
               seconds: float | None = None, say: Callable[[str], None] | None = None) -> np.ndarray:
    """Read a sound file as mono float32 at ``samplerate``.

    Any format libsndfile reads (WAV 8/16/24/32-bit and float, FLAC, OGG, ...) at any rate;
    channels are averaged (channels that cancel so are said: :data:`CANCELLED_DB`; so are samples at
    :data:`FULL_SCALE`, clipped, which the transcriber counted and nothing told), the rate is
    converted with soxr. Raises :class:`AudioFileError`
    naming the file when it is unreadable, truncated beyond use, empty, or holds NaN/inf
    samples or samples beyond :data:`LARGEST_SAMPLE` (silently zeroing those would hide a
    broken recording).

    A file cut short (a WAV or AIFF holding less than its header promises, an Ogg stream without
    its last page, a FLAC whose decoder fails part-way) is heard up to where it ends, and that is
    said to ``say`` (the module's logger when none): losing the recording whole would lose what it holds, and hearing it
    silently would hide why the creatures fall quiet early.

    ``seconds`` reads no further than that much of the file (plus :data:`RESAMPLE_MARGIN`, so
    the samples up to it are exactly those of the whole file resampled); only what is read is
    checked. An offline run hears only its duration, and reading the whole file first made a
    5-second run of a one-hour stereo recording take 27 s and 3.3 GB, and a 4 GB WAV more
    memory than a gallery machine has.
    """
    say = say or _log.warning
    path = Path(path)
    if not path.is_file():
        raise AudioFileError(f"{path}: no such sound file")
    try:
        with soundfile.SoundFile(path) as sound:
            rate = sound.samplerate
            if not MIN_FILE_RATE <= rate <= MAX_FILE_RATE:
                bound = f"below {MIN_FILE_RATE} Hz" if rate < MIN_FILE_RATE else f"above {MAX_FILE_RATE:,} Hz"
                raise AudioFileError(f"{path}: sample rate {rate:,} Hz is {bound} (a damaged header?)")
            frames = -1 if seconds is None else math.ceil((seconds + RESAMPLE_MARGIN) * rate)
            # A double file is checked before it is narrowed: 1e300 (a wrong scale) cast to
            # float32 is inf, and was refused as "NaN/inf", whose cause and fix differ.
            wide = sound.subtype == "DOUBLE"
            cut, promised = _cut_short(sound), sound.frames
            data, fault = _read_what_decodes(sound, frames, "float64" if wide else "float32")
    except (soundfile.LibsndfileError, RuntimeError, OSError) as exc:
        if path.stat().st_size == 0:
            raise AudioFileError(f"{path}: empty file (0 bytes)") from None
        if _is_midi(path):
            raise AudioFileError(f"{path}: a MIDI file, not a sound file (an offline run takes MIDI with "
                                 "--midi)") from None
        raise AudioFileError(f"{path}: unreadable or corrupt ({exc})") from None
    if data.shape[0] == 0:
        raise AudioFileError(f"{path}: cut short: it holds no samples {cut}" if cut is not None else
                             f"{path}: contains no samples (a zero-length recording, or an Ogg file cut "
                             "short: libsndfile reads an Ogg stream's length from its end)")
    if fault is not None:
        say(f"{path}: cut short: it decodes to {data.shape[0] / rate:,.1f} s of the {promised / rate:,.1f} s "
            f"its header promises ({fault}); heard up to there")
    elif cut is not None and (seconds is None or seconds > data.shape[0] / rate):
        say(f"{path}: cut short: it holds {data.shape[0] / rate:,.1f} s {cut}; heard up to there")
    _refuse_unusable(path, data, rate)
    data = data.astype(np.float32, copy=False)
    mono = data.mean(axis=1) if data.shape[1] > 1 else data[:, 0]
    if (clipped := int(np.count_nonzero(np.abs(data) >= FULL_SCALE))):
        first = int(np.flatnonzero((np.abs(data) >= FULL_SCALE).any(axis=1))[0])
        say(f"{path}: {clipped:,} samples at full scale, the first at {first / rate:,.2f} s: clipped (a clipped tone "
            "sounds partials of its own, which the ear does not take as notes where it clips); record it quieter")
    if data.shape[1] > 1 and (below := _cancelled(data, mono)) is not None:
        say(f"{path}: its {data.shape[1]} channels cancel when mixed to the one the ear hears ({below:.0f} dB below "
            "them): one is the other inverted (a lead wired the other way round?); heard as mixed")
    if rate != samplerate:
        mono = soxr.resample(mono, rate, samplerate)
    return np.ascontiguousarray(mono, dtype=np.float32)


class FileSource(ArraySource):
    """A recording played into the ear block by block (see :func:`load_audio`)."""

    def __init__(
        self,
        path: str | os.PathLike,
        *,
        samplerate: int = ANALYSIS_RATE,
        block_size: int = 1024,
    ) -> None:
        self.path = Path(path)
        super().__init__(load_audio(path, samplerate=samplerate), samplerate, block_size=block_size)


class RingBuffer:
    """A preallocated single-producer/single-consumer ring of float32 samples between an audio
    callback and the creature's thread.

    For live input the callback is the producer and the creature the consumer; for live
    output (:class:`audio.output.LiveOutput`) the creature produces and the callback consumes.
    The producer only copies into the preallocated array and moves its own write counter; the
    consumer only moves its read counter. Each counter has one writer, so no lock is needed.
    A block that does not fit is dropped whole and counted in :attr:`overruns`, so neither
    side ever waits for the other inside the ring.
    """

    def __init__(self, capacity: int) -> None:
        if capacity < 1:
            raise ValueError(f"ring capacity must be positive (got {capacity})")
        self.capacity = int(capacity)
        self._data = np.zeros(self.capacity, dtype=np.float32)
        self._written = 0  # total frames written (producer only)
        self._read = 0  # total frames read (consumer only)
        self.overruns = 0

    def available(self) -> int:
        return self._written - self._read

    def write(self, frames: np.ndarray) -> bool:
        """Copy ``frames`` in (no allocation); False and an overrun counted if it won't fit."""
        n = frames.shape[0]
        if n > self.capacity - (self._written - self._read):
            self.overruns += 1
            return False
        start = self._written % self.capacity
        first = min(n, self.capacity - start)
        self._data[start : start + first] = frames[:first]
        self._data[: n - first] = frames[first:]
        self._written += n
        return True

    def read(self, out: np.ndarray) -> int:
        """Copy up to ``len(out)`` frames into ``out``; returns how many were copied."""
        n = min(out.shape[0], self.available())
        start = self._read % self.capacity
        first = min(n, self.capacity - start)
        out[:first] = self._data[start : start + first]
        out[first:n] = self._data[: n - first]
        self._read += n
        return n


class LiveInput(AudioSource):
    """A microphone through sounddevice/PortAudio, resampled to the analysis rate.

    The stream runs at the device's own rate (JACK, for one, will not change it); blocks are
    converted on the reading side by :class:`audio.resample.Resampler`, which gives every
    block's samples on at once (soxr's streaming "HQ" resampler held up to 38 ms back, in
    bursts: most of a live ear's budget). Non-finite samples from a misbehaving driver, and
    finite ones beyond :data:`LARGEST_SAMPLE` (junk that overflows the ear's spectra), are
    replaced by zero and counted in :attr:`bad_samples` so the creature's loop never dies on them; samples at full scale are counted in :attr:`clipped`
    (a microphone gain set too high in a gallery shows there, not only in what is heard).
    ``block_size`` 0 (the default) takes each host buffer as it comes (JACK's period): a fixed
    512 on a 128-frame JACK period made PortAudio hold four periods before calling back
    (measured through JACK, bench/live_hearing.py, 2026-12-05: onset → answer p50 43.2 → 35.2
    ms, p99 54.4 → 46.7 ms; unchanged at a 512-frame period). The callback only copies into
    the ring, so any size costs nothing there.
    It can be started again after :meth:`stop` (on a device that came back); the counters
    carry on.
    """

    def __init__(
        self,
        device: str | int | None = None,
        *,
        samplerate: int = ANALYSIS_RATE,
        block_size: int = 0,
        buffer_seconds: float = 2.0,
        backend: AudioBackend | None = None,
    ) -> None:
        self.device = device
        self.backend = backend
        self.samplerate = int(samplerate)
        self.block_size = int(block_size)
        self.buffer_seconds = float(buffer_seconds)
        self.device_rate: int | None = None
        self.bad_samples = 0
        self.clipped = 0
        self.driver_overflows = 0
        self.callbacks = 0
        self.ring: RingBuffer | None = None
        self._stream: Any = None
        self._scratch: np.ndarray | None = None
        self._resampler: Resampler | None = None

    @property
    def overruns(self) -> int:
        """Blocks dropped because the creature did not read fast enough."""
        return self.ring.overruns if self.ring is not None else 0

    def prepare(self, device_rate: int) -> None:
        """Allocate the ring and scratch buffers for ``device_rate`` (done before streaming)."""
        self.device_rate = int(device_rate)
        dropped_before = self.overruns
        self.ring = RingBuffer(int(self.buffer_seconds * self.device_rate))
        self.ring.overruns = dropped_before
        self._scratch = np.zeros(self.ring.capacity, dtype=np.float32)
        self._resampler = (
            None
            if self.device_rate == self.samplerate
            else Resampler(self.device_rate, self.samplerate)
        )

    def start(self) -> None:
        """Open and start the input stream; :class:`AudioDeviceUnavailable` if there is none."""
        backend = self.backend or portaudio()
        index = find_device(self.device, kind="input", backend=backend)
        try:
            info = backend.query_devices(index, kind="input")
            self.prepare(int(info["default_samplerate"]))
            self._stream = start_stream(
                backend,
                "input",
                device=index,
                channels=1,
                samplerate=self.device_rate,
                blocksize=self.block_size,
                dtype="float32",
                callback=self.callback,
            )
        except backend.PortAudioError as exc:
            self._stream = None
            named = repr(self.device) if self.device is not None else "(default)"
            raise AudioDeviceUnavailable(f"cannot open audio input {named}: {exc}") from None

    @property
    def active(self) -> bool:
        """Whether the device still calls back (PortAudio stops a stream that failed)."""
        return self._stream is not None and bool(self._stream.active)

    def stop(self) -> None:
        """Stop and close the stream; closed even when stopping fails (a device already gone)."""
        stream, self._stream = self._stream, None
        if stream is not None:
            try:
                stream.stop()
            finally:
                stream.close()

    def callback(self, indata: np.ndarray, frames: int, time: Any, status: Any) -> None:
        """PortAudio's thread: copy channel 0 into the ring; nothing else (no alloc/lock/log)."""
        self.callbacks += 1
        if status:
            self.driver_overflows += 1
        self.ring.write(indata[:frames, 0])

    def read(self) -> np.ndarray | None:
        """Everything that arrived since the last read (possibly empty), cleaned and resampled."""
        if self.ring is None:
            raise AudioDeviceUnavailable("live input not started: call start() first")
        n = self.ring.read(self._scratch)
        block = self._scratch[:n]
        bad = unusable(block)
        if bad.any():
            self.bad_samples += int(bad.sum())
            block[bad] = 0.0
        self.clipped += int(np.count_nonzero(np.abs(block) >= FULL_SCALE))
        if self._resampler is not None:
            return self._resampler(block)
        return block.copy()

    def __enter__(self) -> "LiveInput":
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()
