"""Where footage's frames are kept: in memory while small, past :data:`IN_MEMORY` bytes in an
unlinked file beside the run's outputs that the walk pages in as it reads.

Footage is read at random (a walk jumps between keys and blurs groups of frames), so it cannot
be streamed; held in memory, the embedded cube of an hour-long run was 5.2 GB at its default
160×120 and 4096×4096 frames allowed 50 MB each. The file's space is reserved before a frame is
written: a full disk is then an error naming the folder (the footage loader's
:class:`~creatures.image.footage.FootageError`), not a SIGBUS when a page of a sparse file finds
no block.
"""

from __future__ import annotations

import math
import os
import tempfile
from pathlib import Path

import numpy as np

IN_MEMORY = 512 * 2**20
"""Bytes of frames held in memory; more go to a file in the scratch folder."""


class NoRoom(OSError):
    """No room for the frames in the scratch folder (the message names it)."""


class FrameStore:
    """Frames of one shape (height, width, 3), the first one's, appended in order; :meth:`frames`
    is them all.

    ``scratch``: the folder for frames past :data:`IN_MEMORY` (None: the system's temporary
    folder, which may be memory itself on some systems). ``capacity`` frames are made room for
    at the first; past them it grows by doubling, so appending a video of unknown length copies
    each frame at most about twice."""

    def __init__(self, scratch: Path | None = None, capacity: int = 64) -> None:
        self.scratch = scratch
        self.capacity = max(int(capacity), 1)
        self.shape: tuple[int, ...] | None = None  # the first frame's
        self.count = 0
        self._array: np.ndarray | None = None

    def append(self, frame: np.ndarray) -> None:
        if self._array is None:
            self.shape = frame.shape
            self._array = self._allocate(self.capacity)
        elif self.count == len(self._array):
            grown = self._allocate(2 * len(self._array))
            grown[: self.count] = self._array[: self.count]
            self._array = grown
        self._array[self.count] = frame
        self.count += 1

    def frames(self) -> np.ndarray:
        """The frames appended, ``(count, *shape)`` uint8 (a view: no copy), once there is one."""
        assert self._array is not None, "no frame appended"
        return self._array[: self.count]

    def _allocate(self, capacity: int) -> np.ndarray:
        assert self.shape is not None
        size = capacity * math.prod(self.shape)
        if size <= IN_MEMORY:
            return np.empty((capacity, *self.shape), np.uint8)
        folder = self.scratch if self.scratch is not None else Path(tempfile.gettempdir())
        with tempfile.TemporaryFile(prefix=".footage-", dir=folder) as handle:  # unlinked: gone with its map
            try:
                os.posix_fallocate(handle.fileno(), 0, size)
            except OSError as exc:
                raise NoRoom(exc.errno, f"no room for {size / 2**30:.1f} GB of footage frames in "
                                        f"{folder} ({exc.strerror})") from None
            return np.memmap(handle, np.uint8, "w+", shape=(capacity, *self.shape))
