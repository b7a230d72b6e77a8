"""Audio out, one interface for the loudspeaker and for files (the creature's "mouth").

Every output takes blocks of shape ``(frames, channels)`` through :meth:`AudioOutput.write`
and is closed once (or used as a context manager), in the manner of mido's ports: a small
base class whose subclasses fill in ``_write``/``_close``.

* :class:`WavOutput` — soundfile, written to a temporary file beside the target and renamed
  into place on close (atomic: a crash never leaves half a WAV where a good one was).
* :class:`LiveOutput` — sounddevice callback stream. Blocks go, interleaved, into the
  preallocated lock-free :class:`audio.sources.RingBuffer` that live input uses too; the
  PortAudio callback only copies out of it (no allocation of buffers, no locks, no
  logging), counts underruns and keeps the lowest spare it found (for :mod:`audio.lead`).
  Being Python it takes the interpreter's lock, which a live run hands over every
  millisecond (:func:`creatures.runtime.ticking.gil_handover`). Callback streams, never
  blocking ``write()``: under JACK a blocking mono write aborted the process (ENVIRONMENT.md). A loudspeaker that survives
  its device vanishing and returning is :class:`audio.resilient.ResilientOutput`.
* :class:`SilentOutput` — what :func:`open_output` returns when no device exists, so an
  installation keeps running (and can still record) with a clear ``reason``.
"""

from __future__ import annotations

import contextlib
import errno
import logging
import os
import tempfile
import time
from pathlib import Path
from types import TracebackType
from typing import Any, Iterator, Self

import numpy as np
import soundfile

from audio.device import AudioBackend, AudioDeviceUnavailable, device_rate, find_device, portaudio, start_stream
from audio.lead import UNSEEN
from audio.sources import RingBuffer
from creatures.persist import file_mode

log = logging.getLogger(__name__)

BUFFER_FRAMES = 16384
"""Frames a :class:`WavOutput` gathers before writing them to its file."""


class AudioOutput:
    """Base class: checks block shapes, holds rate and channel count, closes once."""

    def __init__(self, sample_rate: int, channels: int) -> None:
        if sample_rate <= 0 or channels <= 0:
            raise ValueError(f"sample_rate and channels must be > 0, got {sample_rate}, {channels}")
        self.sample_rate = int(sample_rate)
        self.channels = int(channels)
        self.frames_written = 0
        self.closed = False

    def write(self, block: np.ndarray) -> None:
        """Queue or store one block ``(frames, channels)`` (a 1-D block is taken as mono)."""
        if self.closed:
            raise ValueError(f"{type(self).__name__} is closed")
        block = np.asarray(block)
        if block.ndim == 1:
            block = block[:, None]
        if block.ndim != 2 or block.shape[1] != self.channels:
            raise ValueError(f"block must be (frames, {self.channels}), got {block.shape}")
        self._write(block)
        self.frames_written += len(block)

    def close(self) -> None:
        if not self.closed:
            self.closed = True
            self._close()

    def _write(self, block: np.ndarray) -> None:
        raise NotImplementedError

    def _close(self) -> None:
        pass

    def __enter__(self) -> Self:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()


class WavOutput(AudioOutput):
    """A WAV file written atomically: temp file in the same directory, fsync, rename."""

    def __init__(self, path: str | os.PathLike, sample_rate: int, channels: int = 2, *,
                 subtype: str = "PCM_16") -> None:
        super().__init__(sample_rate, channels)
        self.path = Path(path)
        fd, tmp = tempfile.mkstemp(prefix=f".{self.path.name}.", suffix=".tmp", dir=self.path.parent)
        try:
            os.fchmod(fd, file_mode(self.path))  # a recording is a normal file once renamed, not 0600
        finally:
            os.close(fd)
        self._tmp = Path(tmp)
        try:
            with self._said_as_os_error():
                self._file = soundfile.SoundFile(self._tmp, mode="w", samplerate=self.sample_rate,
                                                 channels=self.channels, format="WAV", subtype=subtype)
        except BaseException:
            self._tmp.unlink(missing_ok=True)
            raise
        self._buffer = np.zeros((BUFFER_FRAMES, self.channels))
        self._held = 0

    def _write(self, block: np.ndarray) -> None:
        # A run writes one short block a tick; soundfile's per-call cost outweighed the copy,
        # so blocks gather in a preallocated buffer and reach the file a buffer at a time.
        n = len(block)
        if self._held + n > len(self._buffer):
            self._drain()
            if n > len(self._buffer):
                with self._said_as_os_error():
                    self._file.write(block)
                return
        self._buffer[self._held:self._held + n] = block
        self._held += n

    def _drain(self) -> None:
        if self._held:
            with self._said_as_os_error():
                self._file.write(self._buffer[:self._held])
            self._held = 0

    @contextlib.contextmanager
    def _said_as_os_error(self) -> Iterator[None]:
        """libsndfile's failures as the :class:`OSError` they are, naming the file.

        libsndfile writes from C, so a full disk reaches Python as ``LibsndfileError: System
        error.``, a RuntimeError: no caller's ``except OSError`` took it, and an offline run on a
        full disk ended in a traceback. The errno libsndfile's write failed with is cffi's, read
        straight after the failed call (EIO when it cannot be read)."""
        try:
            yield
        except soundfile.SoundFileRuntimeError as exc:
            code = getattr(getattr(soundfile, "_ffi", None), "errno", 0) or errno.EIO
            raise OSError(code, f"{os.strerror(code)} (libsndfile: {exc})", str(self.path)) from None

    def _close(self) -> None:
        try:
            self._drain()
            with self._said_as_os_error():
                self._file.flush()
                self._file.close()  # writes the final header
            with open(self._tmp, "rb+") as handle:
                os.fsync(handle.fileno())
            os.replace(self._tmp, self.path)
        except BaseException:  # a full disk at the end: no half recording is left beside the file
            self.closed = False
            self.abandon()
            raise

    def abandon(self) -> None:
        """Drop the partial recording; whatever was at ``path`` before stays untouched."""
        if not self.closed:
            self.closed = True
            with contextlib.suppress(soundfile.SoundFileError, OSError):  # its header on a full disk
                self._file.close()
            self._tmp.unlink(missing_ok=True)

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        if exc_type is not None:
            self.abandon()
        else:
            self.close()


class LiveOutput(AudioOutput):
    """The loudspeaker: a sounddevice callback stream fed from a :class:`RingBuffer`.

    With ``pace`` (the default) ``write`` blocks (sleeping, on the caller's thread) while the
    ring is full, which paces an offline-speed producer to real time; without it a block that
    finds no room is dropped and counted in :attr:`overruns`, for a caller already paced by
    its clock that must never be held up by a stalled device. ``callbacks``, ``underruns``
    (callbacks that had to pad with silence, once anything was written) and ``lowest_spare``
    (samples, all channels: the least any callback left in the ring since the writer last
    reset it to :data:`audio.lead.UNSEEN`) can be read at any time.
    """

    def __init__(self, sample_rate: int = 48000, channels: int = 2, *, blocksize: int = 512,
                 device: str | int | None = None, buffer_seconds: float = 0.25, pace: bool = True,
                 backend: AudioBackend | None = None) -> None:
        super().__init__(sample_rate, channels)
        backend = backend or portaudio()
        index = find_device(device, kind="output", backend=backend)
        # interleaved samples: (frames, channels) blocks are C-contiguous, so a flat view is free
        self.ring = RingBuffer(max(int(buffer_seconds * sample_rate), 2 * blocksize) * channels)
        self.callbacks = 0
        self.underruns = 0
        self.lowest_spare = UNSEEN  # samples: the least a callback left in the ring (audio/lead.py)
        self.pace = pace
        self._pause = blocksize / sample_rate / 2
        try:
            self.stream = start_stream(backend, "output", samplerate=sample_rate, channels=channels,
                                       dtype="float32", blocksize=blocksize, device=index, callback=self._callback)
        except backend.PortAudioError as exc:
            native = device_rate(device, kind="output", backend=backend)
            runs_at = f" (device runs at {native} Hz)" if native else ""
            raise AudioDeviceUnavailable(
                f"cannot open audio output {device!r} at {sample_rate} Hz{runs_at}: {exc}"
            ) from None

    @property
    def overruns(self) -> int:
        """Blocks dropped because the ring was full (only without ``pace``)."""
        return self.ring.overruns

    @property
    def active(self) -> bool:
        """Whether the device still calls back (PortAudio stops a stream that failed)."""
        return bool(self.stream.active)

    def _callback(self, outdata: np.ndarray, frames: int, time_info: Any, status: Any) -> None:
        # Real-time thread: copy and count only.
        self.callbacks += 1
        flat = outdata.reshape(-1)
        spare = self.ring.available() - len(flat)
        if spare < self.lowest_spare:  # read and reset by the writer (ResilientOutput), one int
            self.lowest_spare = spare
        copied = self.ring.read(flat)
        if copied < len(flat):
            flat[copied:] = 0.0
            if self.frames_written:  # before the first block the silence is the show not yet begun
                self.underruns += 1

    def _write(self, block: np.ndarray) -> None:
        samples = np.ascontiguousarray(block, dtype=np.float32).reshape(-1)
        step = self.ring.capacity // 2 // self.channels * self.channels
        for start in range(0, len(samples), step):
            part = samples[start : start + step]
            while self.pace and self.ring.capacity - self.ring.available() < len(part):
                if not self.stream.active:
                    raise AudioDeviceUnavailable("audio output stream stopped while writing")
                time.sleep(self._pause)
            self.ring.write(part)

    def _close(self) -> None:
        try:
            self.stream.stop()
        finally:  # closed even when stopping fails (a device already gone)
            self.stream.close()


class SilentOutput(AudioOutput):
    """Discards audio; stands in for a missing device and says why in :attr:`reason`."""

    def __init__(self, sample_rate: int, channels: int, reason: str) -> None:
        super().__init__(sample_rate, channels)
        self.reason = reason

    def _write(self, block: np.ndarray) -> None:
        pass


def open_output(sample_rate: int = 48000, channels: int = 2, *, device: str | int | None = None,
                blocksize: int = 512) -> LiveOutput | SilentOutput:
    """The live output, or a :class:`SilentOutput` (with a logged warning) when none exists."""
    try:
        return LiveOutput(sample_rate, channels, blocksize=blocksize, device=device)
    except AudioDeviceUnavailable as exc:
        log.warning("continuing without sound: %s", exc)
        return SilentOutput(sample_rate, channels, reason=str(exc))
