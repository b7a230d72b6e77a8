"""A run's outputs: written aside, published all or none, never over what is not ours.

``--out DIR`` is a folder the artist owns, and may hold anything: their notes, a live run's
state, an older run's outputs. An offline run therefore

* writes every output into a hidden staging directory inside ``DIR`` (``.creatures-run-*``);
* records what it published in a manifest, ``DIR/.creatures-manifest.json``: every file and
  directory, relative to ``DIR``, each file with its :func:`stamp`;
* replaces only what the previous manifest lists, as it wrote it. Before running, and again
  before publishing, it checks every name it will write and every name the previous run
  wrote: a name that holds anything the previous manifest does not list (a ``state/`` the
  artist made, a note put into ``report/``), or a file whose stamp changed, is *refused*, with the path named and nothing changed. We chose
  refusal over publishing elsewhere: an output directory whose layout depended on what
  happened to be in it would break every script that reads ``DIR/events.jsonl``;
* publishes all or none. The previous run's entries are moved aside into a hidden
  ``.creatures-old-*`` directory, the new ones moved in, and the new manifest written last:
  that write is the commit. A failure before it (a rename refused, a full disk) moves
  everything back. A journal (``DIR/.creatures-publish.json``) written before the first rename
  lets the next run finish or undo a publish that was killed half-way (SIGKILL, power loss);
* removes what the previous run wrote and this one did not (an older ``report/`` or
  ``frames/``), so the files side by side are always from one run;
* cleans staging directories of runs that were killed at the next start (they hold a marker
  file; a directory without it is not ours and is left alone).

Renames within one file system are atomic, and all of these are inside ``DIR``.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from pathlib import Path
from typing import Any, Iterator

from creatures.lock import FolderLock, FolderLockedError
from creatures.paths import directory
from creatures.persist import StateFileError, load_json, save_json

MANIFEST = ".creatures-manifest.json"
MANIFEST_KIND = "creature-music outputs"
JOURNAL = ".creatures-publish.json"
JOURNAL_KIND = "creature-music publish journal"
STAGING = ".creatures-run-"
RETIRED = ".creatures-old-"
MARKER = ".creatures-staging"
"""In every staging and set-aside directory: what makes it ours to remove."""


class OutputDirectoryError(OSError):
    """The output directory cannot be created or written, or holds files this run did not
    write where it would publish; nothing was changed."""


def entries(root: Path) -> list[str]:
    """Every file and directory under ``root``, relative, directories ending in ``/``."""
    found = []
    for here, dirs, files in os.walk(root):
        base = Path(here).relative_to(root)
        found += [f"{(base / d).as_posix()}/" for d in dirs]
        found += [(base / f).as_posix() for f in files]
    return sorted(found)


def _entry(out: Path, name: str) -> str:
    """``name``'s manifest entry as it stands in ``out`` (a directory ends in ``/``)."""
    return f"{name}/" if (out / name).is_dir() and not (out / name).is_symlink() else name


def _manifest(out: Path) -> dict[str, Any]:
    """The previous run's manifest ({} without a readable one)."""
    try:
        return load_json(out / MANIFEST, kind=MANIFEST_KIND)
    except StateFileError:
        return {}


def _listed(manifest: dict[str, Any]) -> set[str]:
    files = manifest.get("files")
    return {f for f in files if isinstance(f, str) and inside(f)} if isinstance(files, list) else set()


def stamp(path: Path) -> list[int]:
    """A file's size and modification time (ns), recorded in the manifest as it was published.
    A name alone owned whatever came to stand under it: a live run's ``--state`` pointed at an
    offline run's ``state/`` saved its learning there, and the next run into ``--out`` removed
    it as its own old output; so did an artist's edit of ``report/index.html``."""
    here = os.lstat(path)
    return [here.st_size, here.st_mtime_ns]


def _unchanged(path: Path, was: object) -> bool:
    """Whether ``path`` is as the manifest's stamp ``was`` records it (no stamp: a manifest
    written before stamps, owned by its name)."""
    if was is None:
        return True
    try:
        return stamp(path) == was
    except OSError:
        return False


def _stamps(manifest: dict[str, Any]) -> dict[str, Any]:
    """A manifest's stamps by entry ({} for one written before stamps, or damaged)."""
    stamps = manifest.get("stamps")
    return stamps if isinstance(stamps, dict) else {}


def owned(out: Path, manifest: dict[str, Any] | None = None) -> set[str]:
    """What the manifest (``out``'s, read unless given) says the previous run wrote and is
    still as it wrote it (nothing, without a readable manifest): a file changed since is no
    longer the run's to replace."""
    manifest = _manifest(out) if manifest is None else manifest
    stamps = _stamps(manifest)
    return {f for f in _listed(manifest) if f.endswith("/") or _unchanged(out / f, stamps.get(f))}


def inside(entry: str) -> bool:
    """Whether a manifest entry names something inside ``--out``: relative, no ``..`` and no
    empty part. A manifest or journal is a file anyone can plant; one naming ``../elsewhere``
    must not make a run move or remove what lies outside its folder."""
    parts = entry.removesuffix("/").split("/")
    return not entry.startswith("/") and all(part not in ("", ".", "..") for part in parts) and "\0" not in entry


def _part(name: str) -> bool:
    """Whether ``name`` is one path part inside ``--out`` (a journal's entries are top-level)."""
    return inside(name) and "/" not in name


def foreign(out: Path, names: set[str], ours: set[str]) -> list[str]:
    """Paths under ``out/name`` (for each of ``names``) that ``ours`` does not list."""
    strangers = []
    for name in sorted(names):
        target = out / name
        if not os.path.lexists(target):
            continue
        top = _entry(out, name)
        inside = [f"{name}/{e}" for e in entries(target)] if top.endswith("/") else []
        strangers += [e for e in [top, *inside] if e not in ours]
    return strangers


def refuse_foreign(out: Path, names: set[str], replaces: set[str] | None = None) -> None:
    """Raise :class:`OutputDirectoryError` if publishing ``names`` (top-level entries) into
    ``out`` would replace or remove anything the previous run did not write (of what it wrote,
    only the entries ``replaces`` names go, when it is given)."""
    manifest = _manifest(out)
    ours = owned(out, manifest)
    previous = {e.split("/", 1)[0] for e in ours}
    strangers = foreign(out, names | (previous if replaces is None else previous & replaces), ours)
    if strangers:
        more = f" (and {len(strangers) - 1} more)" if len(strangers) > 1 else ""
        why = ("it changed since a creatures run wrote it (saved into by a live run's --state, or edited)"
               if strangers[0] in _listed(manifest) else f"no creatures run wrote it (it is not in {MANIFEST})")
        raise OutputDirectoryError(
            f"{out}: not replacing {out / strangers[0]}{more}: {why}; nothing was changed. Move it away or "
            "choose another --out")


def hold(out: Path) -> FolderLock:
    """Create and lock ``out`` (the run's until released); a directory that cannot be written
    is an :class:`OutputDirectoryError` before anything runs."""
    try:
        directory(out, "--out").mkdir(parents=True, exist_ok=True)
        return FolderLock(out, "output directory").acquire()
    except FolderLockedError:
        raise
    except OSError as exc:
        raise OutputDirectoryError(f"cannot write outputs to {out}: {exc.strerror or exc}") from None


def _hidden_dir(out: Path, prefix: str) -> Path:
    path = Path(tempfile.mkdtemp(prefix=prefix, dir=out))
    (path / MARKER).write_text(f"{os.getpid()}\n")
    return path


def stage(out: Path) -> Path:
    """A fresh staging directory inside ``out``: where the run writes."""
    return _hidden_dir(out, STAGING)


def publish(staged: Path, out: Path, *, replaces: set[str] | None = None, **facts: object) -> None:
    """Move a finished run's outputs from ``staged`` into ``out`` all or none (module
    docstring); ``facts`` are recorded in the manifest beside the file list.

    ``replaces``: the top-level entries this publish owns, for a command that writes a part of
    a folder (``creatures render`` beside a run's outputs, or its line drawings beside its
    frames): the previous manifest's other entries, and its facts, are kept as they were.
    None: everything the previous run wrote is replaced or removed."""
    new = sorted(p.name for p in staged.iterdir() if p.name != MARKER)
    refuse_foreign(out, set(new), replaces)
    previous = _manifest(out)
    ours, previous_stamps = owned(out, previous), _stamps(previous)
    old = sorted({e.split("/", 1)[0] for e in ours if os.path.lexists(out / e.split("/", 1)[0])})
    kept: list[str] = []
    if replaces is not None:
        going = replaces | set(new)
        kept = [e for e in sorted(ours) if e.split("/", 1)[0] not in going and os.path.lexists(out / e.split("/", 1)[0])]
        old = [name for name in old if name in going]
        facts = {**_facts(previous), **facts}
    retired = _hidden_dir(out, RETIRED)
    save_json(out / JOURNAL, {"staged": staged.name, "retired": retired.name, "new": new, "old": old},
              kind=JOURNAL_KIND)
    try:
        if (out / MANIFEST).exists():  # first: a manifest in ``out`` now means the commit happened
            os.replace(out / MANIFEST, retired / MANIFEST)
        for name in old:
            os.replace(out / name, retired / name)
        for name in new:
            os.replace(staged / name, out / name)
        files = [e for name in new for e in _listing(out, name)] + kept
        keep = set(kept)
        stamps = {**{e: was for e, was in previous_stamps.items() if e in keep},
                  **{e: stamp(out / e) for e in files if not e.endswith("/") and e not in keep}}
        save_json(out / MANIFEST, {**facts, "files": files, "stamps": stamps}, kind=MANIFEST_KIND)  # the commit
    except BaseException:
        _undo(out, staged, retired, new, old)  # if this fails too, the journal is left for the next run
        (out / JOURNAL).unlink()
        shutil.rmtree(retired, ignore_errors=True)
        raise
    _finish(out, staged, retired)


def _facts(previous: dict[str, Any]) -> dict[str, Any]:
    """What a manifest records beside its files."""
    return {k: v for k, v in previous.items() if k not in ("files", "stamps", "format", "version")}


def _listing(out: Path, name: str) -> list[str]:
    top = _entry(out, name)
    return [top] + ([f"{name}/{e}" for e in entries(out / name)] if top.endswith("/") else [])


def _undo(out: Path, staged: Path, retired: Path, new: list[str], old: list[str]) -> None:
    """Put back what a publish moved: the new entries into staging, the old ones into place."""
    for name in new:
        if os.path.lexists(out / name) and not os.path.lexists(staged / name):
            os.replace(out / name, staged / name)
    for name in [*old, MANIFEST]:
        if os.path.lexists(retired / name):
            os.replace(retired / name, out / name)


def _finish(out: Path, staged: Path, retired: Path) -> None:
    (out / JOURNAL).unlink(missing_ok=True)
    shutil.rmtree(retired, ignore_errors=True)
    shutil.rmtree(staged, ignore_errors=True)


def recover(out: Path) -> None:
    """At a run's start (holding ``out``'s lock): finish or undo a publish that was killed
    half-way, and remove staging directories of runs that were killed."""
    journal = out / JOURNAL
    if journal.exists():
        try:
            done = load_json(journal, kind=JOURNAL_KIND)
            staged, retired = out / str(done["staged"]), out / str(done["retired"])
            new, old = [str(n) for n in done["new"]], [str(n) for n in done["old"]]
            names = [str(done["staged"]), str(done["retired"]), *new, *old]
            if not (all(_part(n) for n in names) and names[0].startswith(STAGING) and names[1].startswith(RETIRED)):
                raise ValueError(f"it names {next((n for n in names if not _part(n)), names[0])!r}, not a "
                                 f"{STAGING}* and a {RETIRED}* folder and top-level entries inside {out}")
        except (StateFileError, KeyError, TypeError, ValueError) as exc:
            raise OutputDirectoryError(f"{journal}: cannot finish an interrupted publish ({exc}); "
                                       f"nothing was changed: look inside {out} and remove the journal") from None
        if not (out / MANIFEST).exists():  # killed before the commit: the previous run comes back
            _undo(out, staged, retired, new, old)
        _finish(out, staged, retired)
    for prefix in (STAGING, RETIRED):
        for leftover in out.glob(f"{prefix}*"):
            if (leftover / MARKER).is_file() or not any(leftover.iterdir()):
                shutil.rmtree(leftover, ignore_errors=True)


def discard(staged: Path) -> None:
    """A run that failed or was stopped: its staging directory goes."""
    shutil.rmtree(staged, ignore_errors=True)


@contextlib.contextmanager
def publishing(out: Path, replaces: set[str] | None, *, planned: set[str] | None = None,
               facts: dict[str, object] | None = None) -> Iterator[Path]:
    """``with publishing(out, {"frames", "out.mp4"}) as staged:`` — write into ``staged``; when
    the block ends its entries are published into ``out`` with ``facts`` (filled in by the
    block, if it likes), replacing of what was published there before only the entries
    ``replaces`` names, or everything with None (:func:`publish`). A block that fails (Ctrl-C,
    a full disk) changes nothing in ``out``; one that would replace what no run wrote (of
    ``planned``, the names it will write, ``replaces`` if not given) is refused before it
    starts. ``out`` is held meanwhile, as a run holds it."""
    made = not out.exists()
    try:
        with hold(out):
            recover(out)
            refuse_foreign(out, replaces if planned is None else planned, replaces)
            try:
                staged = stage(out)
            except OSError as exc:
                raise OutputDirectoryError(f"cannot write outputs to {out}: {exc.strerror or exc}") from None
            try:
                try:
                    yield staged
                except OSError as exc:
                    raise _unwritten(exc, staged, out) from None
                publish(staged, out, replaces=replaces, **(facts or {}))
            finally:
                discard(staged)
    except BaseException:
        if made:  # stopped or failed, it leaves no empty folder it made
            with contextlib.suppress(OSError):
                out.rmdir()
        raise


def _unwritten(exc: OSError, staged: Path, out: Path) -> OSError:
    """A write into ``staged`` that failed (a full disk, a file too large), said of the output
    it was to become, and that ``out`` is as it was: the hidden staging path it named
    (``out/.creatures-run-x1y2/out.wav``) told the engineer neither."""
    written = Path(str(exc.filename)) if exc.filename is not None else None
    if isinstance(exc, OutputDirectoryError) or written is None or not written.is_relative_to(staged):
        return exc
    output = out / written.relative_to(staged)
    return OutputDirectoryError(exc.errno, f"{exc.strerror or exc} while writing {output}; nothing in {out} was "
                                "changed (the previous run's outputs are as they were)", str(output))


__all__ = ["MANIFEST", "OutputDirectoryError", "discard", "publish", "publishing", "recover", "refuse_foreign",
           "stage"]
