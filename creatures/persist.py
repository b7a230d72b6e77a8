"""Atomic, code-free persistence of creature state (DESIGN.md, "State that lasts").

State is JSON (human readable, diffable, mergeable) plus NPZ for large arrays. Every save
goes to a temporary file in the same directory, is fsync'd, then renamed over the target:
a crash or a full disk mid-save leaves the previous file intact. Loading never executes
code (no pickle; ``np.load(allow_pickle=False)``).

Files are bounded: a JSON state file, and the arrays of an NPZ once unpacked, may hold at
most :data:`MAX_STATE_BYTES`; anything larger is refused before it is read, so a damaged or
hostile file cannot exhaust a gallery machine's memory.
"""

from __future__ import annotations

import glob
import json
import math
import os
import tempfile
import zipfile
from pathlib import Path
from typing import Any, Callable

import numpy as np

from creatures.paths import UnsafePathError, open_regular, read_regular

FORMAT_VERSION = 1
MAX_STATE_BYTES = 256 * 1024 * 1024
"""Largest JSON state file, and largest total of unpacked NPZ arrays, that will be read."""


class StateFileError(Exception):
    """A state file is missing, unreadable or malformed; the message names the file."""


def atomic_write(path: str | os.PathLike, write: Callable[[Any], None], mode: str) -> None:
    """Call ``write(handle)`` on a temporary file beside ``path``, fsync it, rename it over
    ``path``: other formats (e.g. ``.mid`` files in ``midi.files``) save atomically too."""
    path = Path(path)
    directory = path.parent if str(path.parent) else Path(".")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=directory)
    try:
        os.fchmod(fd, file_mode(path))  # mkstemp makes 0600: a saved file gets a normal file's mode
        with os.fdopen(fd, mode) as handle:
            write(handle)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, path)
        # A process killed mid-save (SIGKILL, power loss) leaves its temporary file behind;
        # the next good save of the same file clears such leftovers so they cannot pile up.
        for stale in directory.glob(f".{glob.escape(path.name)}.*.tmp"):
            stale.unlink(missing_ok=True)
    except BaseException as exc:
        # Nothing partial survives: the temporary file goes, the old target stays.
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        if isinstance(exc, OSError) and exc.errno is not None and exc.filename is None:
            # "No space left on device" alone does not say which save failed.
            raise type(exc)(exc.errno, exc.strerror, str(path)) from None
        raise
    fsync_directory(directory)


def fsync_directory(directory: Path) -> None:
    """Make the renames into ``directory`` durable (a power cut after a rename could otherwise
    lose it); a filesystem that cannot fsync a folder is let be."""
    try:
        dir_fd = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(dir_fd)
    except OSError:
        pass
    finally:
        os.close(dir_fd)


def umask() -> int:
    """The process's umask, read without changing it (``os.umask`` can only be read by setting
    it, a race with any other thread creating files meanwhile)."""
    try:
        with open("/proc/self/status", encoding="ascii") as status:
            for line in status:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def file_mode(path: Path) -> int:
    """The mode a file written through a temporary file (``mkstemp`` makes 0600) gets at
    ``path``: the one it has (an artist's chmod is kept), else what ``open`` would give a new
    file (0666 less the umask)."""
    try:
        return path.stat().st_mode & 0o7777
    except OSError:
        return 0o666 & ~umask()


def save_json(path: str | os.PathLike, data: dict[str, Any], *, kind: str) -> None:
    """Write ``data`` as JSON atomically, stamped with ``kind`` and the format version."""
    write_json_text(path, json_text(data, kind=kind))


def json_text(data: dict[str, Any], *, kind: str) -> str:
    """What :func:`save_json` writes: encoding is quick, the atomic write (an fsync) is not, so a
    live run encodes on the creature's thread and writes on another (creatures/runtime/live.py)."""
    document = {"format": kind, "version": FORMAT_VERSION, **data}
    return json.dumps(document, indent=1, sort_keys=True, allow_nan=False)


def write_json_text(path: str | os.PathLike, text: str) -> None:
    atomic_write(Path(path), lambda h: h.write(text), "w")


def load_json(path: str | os.PathLike, *, kind: str) -> dict[str, Any]:
    """Read a JSON state file written by :func:`save_json`, checking its kind and version."""
    path = Path(path)
    try:
        if path.stat().st_size > MAX_STATE_BYTES:
            raise StateFileError(f"{path}: state file larger than {MAX_STATE_BYTES} bytes; refused")
        text = read_regular(path, "state file", MAX_STATE_BYTES).decode("utf-8")
    except FileNotFoundError:
        raise StateFileError(f"{path}: state file {_absent(path)}") from None
    except UnsafePathError as exc:  # a FIFO or a device: it would block or never end
        raise StateFileError(str(exc)) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise StateFileError(f"{path}: cannot read state file ({exc})") from None
    try:
        document = json.loads(text, parse_constant=_refuse_constant, parse_float=_finite_float)
    except json.JSONDecodeError as exc:
        raise StateFileError(f"{path}:{exc.lineno}: malformed JSON ({exc.msg})") from None
    except ValueError as exc:
        raise StateFileError(f"{path}: {exc}") from None
    except RecursionError:  # the parser recurses once per nested array or object
        raise StateFileError(f"{path}: nested too deeply to be a state file") from None
    if not isinstance(document, dict):
        raise StateFileError(f"{path}: expected a JSON object at the top level")
    if document.get("format") != kind:
        said = document.get("format")
        raise StateFileError(f"{path}: not a {kind!r} file (" + (f"it says it is a {said!r} file)" if said else
                                                                   "a JSON file with no 'format' of this program's)"))
    if document.get("version") != FORMAT_VERSION:
        raise StateFileError(
            f"{path}: unsupported {kind} version {document.get('version')!r}"
            f" (this build reads version {FORMAT_VERSION})"
        )
    return document


def _absent(path: Path) -> str:
    """Why a file that is not there is not: "not found", or, for a symbolic link whose target is
    gone (a state file linked to a drive not mounted), where it points: "not found" sent the
    engineer looking for a file that is there, as a link."""
    if path.is_symlink():
        return f"is a link to {os.readlink(path)}, which does not exist"
    return "not found"


def _refuse_constant(name: str) -> float:
    """Python's json reads NaN/Infinity, which :func:`save_json` never writes: a file holding
    them was not saved by us, and a NaN restored into a value would poison it silently."""
    raise ValueError(f"non-finite number {name} (state files hold finite numbers only)")


def _finite_float(text: str) -> float:
    """A JSON number; ``1e400`` reads as infinity, which no saved state holds (see above)."""
    value = float(text)
    if not math.isfinite(value):
        raise ValueError(f"number {text[:40]} is out of range (state files hold finite numbers only)")
    return value


def save_npz(path: str | os.PathLike, arrays: dict[str, np.ndarray]) -> None:
    """Write named arrays to an ``.npz`` atomically."""
    atomic_write(Path(path), lambda h: np.savez(h, **arrays), "wb")


def load_npz(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """Read an ``.npz`` written by :func:`save_npz`; object arrays are refused."""
    path = Path(path)
    try:
        with open_regular(path, "array file") as handle, np.load(handle, allow_pickle=False) as data:
            unpacked = sum(info.file_size for info in data.zip.infolist())
            if unpacked > MAX_STATE_BYTES:  # checked before unpacking: a zip bomb stays packed
                raise StateFileError(f"{path}: arrays unpack to {unpacked} bytes, more than {MAX_STATE_BYTES}; refused")
            each_holds_what_it_claims(path, data.zip)
            return {name: data[name] for name in data.files}
    except FileNotFoundError:
        raise StateFileError(f"{path}: array file {_absent(path)}") from None
    except UnsafePathError as exc:
        raise StateFileError(str(exc)) from None
    # truncated: BadZipFile; a damaged header can claim a zip version zipfile lacks: NotImplementedError
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, NotImplementedError) as exc:
        raise StateFileError(f"{path}: malformed array file ({exc})") from None


def each_holds_what_it_claims(path: Path, archive: zipfile.ZipFile) -> None:
    """Refuse an ``.npz`` (:class:`StateFileError`) with an array whose header claims more bytes
    than its member holds.

    numpy allocates the whole array its header's shape claims before reading a byte of it: a
    90-byte ``.npy`` claiming 10**13 floats raised MemoryError (no :class:`StateFileError`, a
    traceback) however small the archive, and the unpacked-size bound above, which reads the
    zip's sizes, never saw it. The motor-graph cache is read through this too."""
    for info in archive.infolist():
        if info.filename.endswith(".npy"):
            _holds_what_it_claims(path, archive, info)


def _holds_what_it_claims(path: Path, archive: zipfile.ZipFile, info: zipfile.ZipInfo) -> None:
    with archive.open(info) as member:
        version = np.lib.format.read_magic(member)
        read_header = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
        shape, _, dtype = read_header(member)
        claimed, held = math.prod(shape) * dtype.itemsize, info.file_size - member.tell()
        if claimed > held:
            raise StateFileError(f"{path}: array {info.filename[:-4]!r} claims {claimed} bytes ({shape} of "
                                 f"{dtype}) and holds {held}; refused")
