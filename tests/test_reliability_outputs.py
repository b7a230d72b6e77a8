"""Issue 13, outputs, files and friendly stops: one test (or more) per defect a hostile user
found, each reproduced as the issue tells it, on temporary directories. Each of these failed
on the code before the fix.

* defect 1: an offline run deleted ``state/`` and ``report/`` it did not write;
* defect 2: a failed publish replaced part of the previous outputs; an older run's
  ``report/`` stayed beside a new run's files (tests/test_runtime_offline.py);
* defect 3: ``--log`` (and the other paths) could name a device, FIFO or directory, and log
  rotation renamed it;
* defect 5: a full disk under the events log crashed a live run;
* defect 10 (outputs half): no lock on a state folder; ``inspect`` tracebacks and "no state
  files" when all were skipped; Ctrl-C/SIGTERM tracebacks; a killed run's staging folder;
  a failed final save exiting 0; outputs written 0600.
"""

from __future__ import annotations

import errno
import os
import shutil
import signal
import socket
import stat
import subprocess
import sys
import time
from pathlib import Path

import pytest

from creatures import lock
from creatures.cli import main
from creatures.events import EventLog, read_events
from creatures.lock import LOCK_FILE, FolderLock, FolderLockedError
from creatures.paths import UnsafePathError
from creatures.persist import StateFileError, load_json, load_npz, save_json
from creatures.runtime import live, outputs
from creatures.runtime.offline import run_offline
from creatures.runtime.outputs import JOURNAL, MANIFEST, MANIFEST_KIND, OutputDirectoryError
from creatures.runtime.schema import load_installation
from test_faults import _fill_disk, _read_only, _tree

ROOT = Path(__file__).resolve().parents[1]
LISTEN = ROOT / "installations" / "listen.toml"
COLONY = f"""
extends = "{ROOT / 'installations' / 'exchange.toml'}"
title = "reliable"
[output]
report = false
"""
"""The shipped exchange colony (three creatures, 0.04 s ticks), without the report."""


@pytest.fixture
def config(tmp_path) -> Path:
    path = tmp_path / "colony.toml"
    path.write_text(COLONY)
    return path


def _offline(config: Path, out: Path, duration: float = 1.0, *extra: str) -> int:
    return main(["offline", str(config), "--out", str(out), "--duration", str(duration), "--no-progress", *extra])


def _env() -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}


def _hidden(out: Path) -> list[str]:
    """Staging, set-aside, journal and lock files a run leaves in ``out`` (none, after it ends;
    a stopped run that made ``out`` removes it, empty)."""
    if not out.exists():
        return []
    return sorted(p.name for p in out.iterdir() if p.name.startswith(".") and p.name != MANIFEST)


# -- defect 1: never delete what the run did not write ---------------------------------------
def test_an_offline_run_never_deletes_state_or_report_it_did_not_write(tmp_path, capsys):
    """The issue's reproduction: DIR/state/README.txt and DIR/report/opening.html survive
    `creatures offline installations/listen.toml --out DIR --duration 5`, which refuses."""
    out = tmp_path / "DIR"
    (out / "state").mkdir(parents=True)
    (out / "state" / "README.txt").write_text("what the live installation learned lives here")
    (out / "report").mkdir()
    (out / "report" / "opening.html").write_text("<p>the opening</p>")
    before = _tree(out)

    assert main(["offline", str(LISTEN), "--out", str(out), "--duration", "5", "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "not replacing" in err and "no creatures run wrote it" in err
    assert str(out / "report") in err or str(out / "state") in err
    assert _tree(out) == before  # nothing written, nothing removed, no staging left


def test_an_artists_file_put_into_an_earlier_runs_output_is_never_removed(config, tmp_path, capsys):
    out = tmp_path / "out"
    assert _offline(config, out, 1.0) == 0
    capsys.readouterr()
    manifest = load_json(out / MANIFEST, kind=MANIFEST_KIND)
    assert set(manifest["files"]) == {e for e in outputs.entries(out) if e != MANIFEST}  # all it wrote, only that
    (out / "state" / "my-notes.txt").write_text("mine")
    before = _tree(out)
    assert _offline(config, out, 2.0) == 2
    assert f"not replacing {out / 'state' / 'my-notes.txt'}" in capsys.readouterr().err
    assert _tree(out) == before


def test_a_runs_own_output_fed_back_as_its_input_into_the_same_out_is_refused_not_replaced(config, tmp_path, capsys):
    """What the creatures played, fed back to them (`--midi DIR/out.mid` or `--audio DIR/out.wav`
    with the same `--out DIR`): the run read it, then published its own out.mid or out.wav over
    it, and the take the artist fed was gone. The run refuses before it starts, saying why."""
    out = tmp_path / "DIR"
    assert _offline(config, out, 4.0) == 0
    capsys.readouterr()
    before = _tree(out)
    for flag, name in (("--midi", "out.mid"), ("--audio", "out.wav")):
        assert _offline(config, out, 2.0, flag, str(out / name)) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert err == [f"creatures: {flag} {out / name} is this run's own {name} in {out}, which the run would "
                       "replace: copy it out of there first, or give another --out"]
        assert _tree(out) == before
    assert _offline(config, tmp_path / "other", 2.0, "--midi", str(out / "out.mid")) == 0  # elsewhere, it is heard


# -- defect 2: all or none ----------------------------------------------------------------
def test_a_publish_of_part_of_a_folder_replaces_only_its_part_and_keeps_the_rest(tmp_path):
    """``creatures render`` publishes its frames into a run's folder, and its line drawings
    beside them: each replaces only its own entries, keeps the others and the run's facts; a
    block that fails changes nothing, and one that would replace a file no run wrote is refused
    before it starts."""
    out = tmp_path / "run"

    def made(files: dict[str, str], replaces: set[str] | None, **facts) -> None:
        staged = outputs.stage(out)
        for name, text in files.items():
            (staged / name).parent.mkdir(parents=True, exist_ok=True)
            (staged / name).write_text(text)
        outputs.publish(staged, out, replaces=replaces, **facts)
        outputs.discard(staged)

    out.mkdir()
    made({"events.jsonl": "run", "frames/frame_000000.png": "run"}, None, events_lost=3)
    with outputs.publishing(out, {"frames", "out.mp4"}) as staged:
        (staged / "frames").mkdir()
        (staged / "frames" / "frame_000001.png").write_text("render")
    with outputs.publishing(out, {"lines"}) as staged:
        (staged / "lines").mkdir()
        (staged / "lines" / "frame_000000.svg").write_text("lines")
    manifest = load_json(out / MANIFEST, kind=MANIFEST_KIND)
    assert manifest["events_lost"] == 3
    assert sorted(manifest["files"]) == ["events.jsonl", "frames/", "frames/frame_000001.png", "lines/",
                                         "lines/frame_000000.svg"]
    before = _tree(out)
    with pytest.raises(KeyboardInterrupt), outputs.publishing(out, {"lines"}) as staged:
        (staged / "lines").mkdir()
        raise KeyboardInterrupt
    assert _tree(out) == before
    (out / "lines" / "mine.txt").write_text("an artist's")
    with pytest.raises(OutputDirectoryError, match="mine.txt"), outputs.publishing(out, {"lines"}):
        pytest.fail("a publish that would remove an artist's file began")
    assert _tree(out) == {**before, "lines/mine.txt": b"an artist's"}


def test_a_plain_file_where_the_state_folder_was_replaces_nothing(config, tmp_path, capsys):
    """The issue's case: DIR/state is a plain file. Before, events.jsonl, out.mid and out.wav
    were already replaced when the rename of state/ failed."""
    out = tmp_path / "out"
    assert _offline(config, out, 1.0) == 0
    for saved in (out / "state").iterdir():
        saved.unlink()
    (out / "state").rmdir()
    (out / "state").write_text("a plain file")
    before = _tree(out)
    capsys.readouterr()
    assert _offline(config, out, 2.0) == 2
    assert f"not replacing {out / 'state'}" in capsys.readouterr().err
    assert _tree(out) == before


@pytest.mark.parametrize("failing", ["state", "out.wav", MANIFEST])
def test_a_rename_failing_while_publishing_puts_everything_back(failing, config, tmp_path, monkeypatch):
    """One rename of the publish fails (an I/O error): every output of the previous run is
    back in place, byte for byte, and nothing of the failed run is left."""
    out = tmp_path / "out"
    assert _offline(config, out, 1.0) == 0
    before = _tree(out)
    real, failed = os.replace, []

    def replace(src, dst):  # publishing it (or, for the manifest, the commit) fails once
        if Path(dst) == out / failing and not failed:
            failed.append(dst)
            raise OSError(errno.EIO, os.strerror(errno.EIO), str(dst))
        real(src, dst)

    monkeypatch.setattr(os, "replace", replace)
    with pytest.raises(OSError, match="Input/output error"):
        run_offline(load_installation(config), out, duration=2.0)
    monkeypatch.undo()
    assert failed and _tree(out) == before
    assert run_offline(load_installation(config), out, duration=2.0).files["events"] == out / "events.jsonl"
    assert read_events(out / "events.jsonl")[0]["duration"] == 2.0 and _hidden(out) == []


PUBLISH_KILLED = r"""
import os, signal, sys
from pathlib import Path
from creatures.runtime import outputs
from creatures.runtime.offline import run_offline
from creatures.runtime.schema import load_installation

out, moved, real = Path(sys.argv[2]), [], os.replace

def replace(src, dst):  # a rename of the publish: between DIR and its staging or set-aside folder
    sides = {Path(src).parent, Path(dst).parent}
    if out in sides and any(p.parent == out and p.name.startswith((outputs.STAGING, outputs.RETIRED)) for p in sides):
        moved.append(dst)
        if len(moved) == int(sys.argv[3]):
            os.kill(os.getpid(), signal.SIGKILL)  # power lost half-way through publishing
    real(src, dst)

os.replace = replace
run_offline(load_installation(sys.argv[1]), out, duration=2.0)
"""


@pytest.mark.parametrize("at", [1, 3, 6, 9])
def test_a_publish_killed_half_way_is_undone_at_the_next_start(at, config, tmp_path):
    """Killed before the ``at``-th of the publish's 9 renames (the old manifest and 4 entries
    set aside, 4 new entries moved in): the next start puts the previous run back whole."""
    out = tmp_path / "out"
    assert _offline(config, out, 1.0) == 0
    before = _tree(out)
    script = tmp_path / "killed.py"
    script.write_text(PUBLISH_KILLED)
    done = subprocess.run([sys.executable, str(script), str(config), str(out), str(at)], env=_env(), timeout=300)
    assert done.returncode == -signal.SIGKILL
    assert (out / JOURNAL).exists() and _tree(out) != before  # the previous run was half replaced

    with FolderLock(out, "output directory"):
        outputs.recover(out)  # what every run does first
    assert _tree(out) == before


PLANTED = [  # a journal anyone could write into --out: each names something outside it
    {"staged": "../sibling", "retired": ".creatures-old-x", "new": [], "old": []},
    {"staged": ".creatures-run-x", "retired": "../sibling", "new": [], "old": []},
    {"staged": ".creatures-run-x", "retired": ".creatures-old-x", "new": ["../sibling"], "old": []},
    {"staged": ".creatures-run-x", "retired": ".creatures-old-x", "new": [], "old": ["/tmp"]},
    {"staged": "sibling", "retired": ".creatures-old-x", "new": [], "old": []},  # not a staging folder
]


@pytest.mark.parametrize("journal", PLANTED, ids=range(len(PLANTED)))
def test_a_planted_journal_or_manifest_never_touches_a_folder_outside_out(journal, config, tmp_path, capsys):
    """A planted ``.creatures-publish.json`` made an offline run remove a folder beside
    ``--out``: now the journal is refused (exit 2, one line) and everything is left; a
    manifest naming ``../sibling`` owns nothing outside ``--out`` either."""
    sibling = tmp_path / "sibling"
    sibling.mkdir()
    (sibling / "work.txt").write_text("an artist's work")
    out = tmp_path / "out"
    out.mkdir()
    save_json(out / JOURNAL, journal, kind=outputs.JOURNAL_KIND)
    before = _tree(tmp_path)
    assert _offline(config, out) == 2
    err = capsys.readouterr().err
    assert "cannot finish an interrupted publish" in err and err.count("\n") == 1
    assert _tree(tmp_path) == before and (sibling / "work.txt").read_text() == "an artist's work"

    (out / JOURNAL).unlink()
    save_json(out / MANIFEST, {"files": ["../sibling/", "../sibling/work.txt", "/tmp/", "events.jsonl"]},
              kind=MANIFEST_KIND)
    assert outputs.owned(out) == {"events.jsonl"}
    assert _offline(config, out) == 0
    assert (sibling / "work.txt").read_text() == "an artist's work"


# -- defect 3: regular files only ---------------------------------------------------------
@pytest.fixture
def device(tmp_path) -> Path:
    """A character device node like /dev/null (1, 3), made in the test's own directory."""
    node = tmp_path / "null"
    try:
        os.mknod(node, stat.S_IFCHR | 0o666, os.makedev(1, 3))
    except PermissionError:
        pytest.skip("mknod needs CAP_MKNOD")
    return node


def test_a_log_past_its_bound_never_renames_a_device_node(device, tmp_path):
    """The issue's case: past max_bytes the log renamed whatever --log named."""
    with pytest.raises(UnsafePathError, match="is a character device, not a regular file"):
        EventLog(device, max_bytes=500)
    assert stat.S_ISCHR(device.lstat().st_mode) and not (tmp_path / "null.1").exists()

    # A regular log whose path is swapped for a device node while it runs: rotation refuses.
    path = tmp_path / "events.jsonl"
    said = []
    log = EventLog(path, max_bytes=2000, report=said.append)
    os.replace(device, path)
    for i in range(200):
        log.emit(i * 0.1, "tick", i=i)
    log.close()
    assert stat.S_ISCHR(path.lstat().st_mode) and not (tmp_path / "events.jsonl.1").exists()
    assert log.lost > 0 and "not rotated" in said[0]


def _special(kind: str, path: Path) -> Path:
    if kind == "FIFO":
        os.mkfifo(path)
    elif kind == "directory":
        path.mkdir()
    elif kind == "file":
        path.write_text("a plain file")
    elif kind == "link to nothing":
        path.symlink_to(path.parent / "unmounted" / "state")
    else:
        try:
            os.mknod(path, stat.S_IFCHR | 0o666, os.makedev(1, 3))
        except PermissionError:
            pytest.skip("mknod needs CAP_MKNOD")
    return path


REFUSED = [  # (argument, what it names, what the message says it is)
    ("--log", "device", "is a character device, not a regular file"),
    ("--log", "FIFO", "is a FIFO (named pipe), not a regular file"),
    ("--log", "directory", "is a directory, not a regular file"),
    ("--state", "file", "is a regular file, not a directory"),
    ("--state", "FIFO", "is a FIFO (named pipe), not a directory"),
    ("--frames", "device", "is a character device, not a directory"),
    ("--out", "FIFO", "is a FIFO (named pipe), not a directory"),
    ("--out", "device", "is a character device, not a directory"),
    ("--state", "link to nothing", "is a symbolic link to "),  # state on a disk not mounted: every save failed
    ("--out", "link to nothing", "which does not exist (a disk not mounted?)"),
    ("--frames", "link to nothing", "which does not exist (a disk not mounted?)"),
    ("config", "FIFO", "is a FIFO (named pipe), not a regular file"),
    ("config", "directory", "is a directory, not a regular file"),
]


@pytest.mark.parametrize("argument, kind, says", REFUSED, ids=[f"{a} {k}" for a, k, _ in REFUSED])
def test_paths_that_are_not_regular_files_or_directories_are_refused_before_running(argument, kind, says, config,
                                                                                      tmp_path):
    """Run as a user would (a FIFO made the old code block forever, hence the timeout): one
    line, exit 2, and the thing named is left as it was."""
    special = _special(kind, tmp_path / "special")
    if argument == "config":
        command = ["offline", str(special), "--out", str(tmp_path / "out")]
    elif argument == "--out":
        command = ["offline", str(config), "--out", str(special)]
    else:
        command = ["run", str(config), argument, str(special), "--duration", "0.2"]
    mode = special.lstat().st_mode
    done = subprocess.run([sys.executable, "-m", "creatures.cli", *command], env=_env(), capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 2, done.stderr
    assert says in done.stderr and done.stderr.count("\n") == 1 and "Traceback" not in done.stderr
    assert str(special) in done.stderr
    assert special.lstat().st_mode == mode and not (tmp_path / "special.1").exists()
    assert "running" not in done.stdout  # refused before anything ran


def test_a_fifo_as_a_state_file_is_refused_with_one_line_not_a_hang(config, tmp_path):
    """A FIFO as ``state/ada.json`` blocked ``creatures run`` forever at ``open`` (hence the
    timeout): it is refused before it is opened, exit 2, one line naming the file."""
    state = tmp_path / "state"
    state.mkdir()
    os.mkfifo(state / "ada.json")
    done = subprocess.run([sys.executable, "-m", "creatures.cli", "run", str(config), "--state", str(state),
                           "--duration", "0.2"], env=_env(), capture_output=True, text=True, timeout=120)
    assert done.returncode == 2, done.stderr
    assert done.stderr.count("\n") == 1 and "Traceback" not in done.stderr
    assert str(state / "ada.json") in done.stderr and "is a FIFO (named pipe), not a regular file" in done.stderr
    assert stat.S_ISFIFO((state / "ada.json").lstat().st_mode)


def test_a_fifo_as_the_events_log_makes_inspect_exit_2(tmp_path, capsys):
    """``inspect`` skipped an ``events.jsonl`` that was not a regular file in silence, and
    ``read_events`` would have blocked on it: now one line, exit 2."""
    os.mkfifo(tmp_path / "events.jsonl")
    assert main(["inspect", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert str(tmp_path / "events.jsonl") in err and "is a FIFO (named pipe)" in err and err.count("\n") == 1
    with pytest.raises(UnsafePathError, match="FIFO"):
        read_events(tmp_path / "events.jsonl")


@pytest.mark.parametrize("kind", ["FIFO", "device"])
def test_state_arrays_manifest_and_journal_that_are_not_regular_files_are_refused_unread(kind, config, tmp_path,
                                                                                        capsys):
    """Every reader of a saved file refuses a FIFO or a device node before opening it (a
    device node here is /dev/null's numbers, made in the test's folder, never read)."""
    special = _special(kind, tmp_path / "special")
    for read in (lambda: load_json(special, kind="creature state"), lambda: load_npz(special)):
        with pytest.raises(StateFileError, match=f"{special}: is a"):
            read()
    out = tmp_path / "out"
    out.mkdir()
    os.replace(special, out / JOURNAL)
    assert _offline(config, out) == 2  # the interrupted publish cannot be read: nothing is touched
    assert "cannot finish an interrupted publish" in capsys.readouterr().err
    os.replace(out / JOURNAL, out / MANIFEST)
    assert outputs.owned(out) == set()  # an unreadable manifest owns nothing


@pytest.mark.parametrize("bad", ["--log", "--frames", "osc port"])
def test_a_run_refused_for_its_log_frames_or_port_creates_no_state_folder(bad, config, tmp_path, capsys):
    """``creatures run`` made an empty ``--state`` folder (locking it) before it refused a
    bad ``--log``, ``--frames`` or a busy OSC port: now all three are checked first."""
    state, extra = tmp_path / "state", []
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as busy:
        busy.bind(("127.0.0.1", 0))
        if bad == "osc port":
            config.write_text(config.read_text() + f"[osc]\nport = {busy.getsockname()[1]}\n")
        else:
            extra = [bad, str(_special("FIFO" if bad == "--log" else "file", tmp_path / "special"))]
        assert main(["run", str(config), "--state", str(state), "--duration", "0.2", *extra]) == 2
    err = capsys.readouterr().err
    assert ("already in use" if bad == "osc port" else bad) in err and err.count("\n") == 1
    assert not state.exists()


# -- defect 5: a full disk under the events log ------------------------------------------
class FailingDisk:
    """The disk under a directory: ``room`` bytes left for all its files together (a write
    that passes it writes what fits, then fails with ENOSPC, as a full disk does), or, with
    ``code=EIO``, every write after the first fails with an I/O error."""

    def __init__(self, code: int, room: int = 0) -> None:
        self.code, self.room, self.writes, self.failures = code, room, 0, 0

    def take(self, handle, data) -> int:
        self.writes += 1
        if self.code == errno.EIO and self.writes > 1 or self.code == errno.ENOSPC and len(data) > self.room:
            if self.code == errno.ENOSPC:
                handle.write(data[: self.room])
                self.room = 0
            self.failures += 1
            raise OSError(self.code, os.strerror(self.code))
        self.room -= len(data)
        return handle.write(data)


def _failing_disk(monkeypatch, directory: Path, disk: FailingDisk) -> None:
    """Every file opened for writing under ``directory`` (at the file-call level, ``io.open``,
    as tests/test_faults.py fakes it) is on ``disk``."""
    import io

    from test_faults import _where

    real_open = io.open

    class OnDisk:
        def __init__(self, handle) -> None:
            self.handle = handle

        def write(self, data):
            return disk.take(self.handle, data)

        def __getattr__(self, name):
            return getattr(self.handle, name)

    def open_(file, mode="r", *args, **kwargs):
        handle = real_open(file, mode, *args, **kwargs)
        return OnDisk(handle) if set(mode) & set("wax+") and _where(file).is_relative_to(directory) else handle

    monkeypatch.setattr(io, "open", open_)


@pytest.mark.parametrize("code", [errno.ENOSPC, errno.EIO], ids=["disk full", "I/O error"])
def test_a_full_disk_under_a_live_log_is_counted_loss_and_the_colony_goes_on(code, config, tmp_path, monkeypatch,
                                                                           capsys):
    """The issue's case: a full disk under --log crashed a live run within a second."""
    log = tmp_path / "logs" / "events.jsonl"
    log.parent.mkdir()
    disk = FailingDisk(code, room=3000)
    _failing_disk(monkeypatch, log.parent, disk)
    assert main(["run", str(config), "--log", str(log), "--duration", "3"]) == 0
    monkeypatch.undo()
    printed = capsys.readouterr().out
    assert disk.failures >= 2  # it failed, and failed again when tried again a second later
    stopped = next(line for line in printed.splitlines() if line.startswith("stopped after"))
    assert int(stopped.split(": ")[1].split()[0]) >= 50  # 3 s at 0.04 s a tick: the colony went on to the end
    lost = [line for line in printed.splitlines() if "events not written" in line]
    assert len(lost) == 1 and str(log) in lost[0] and os.strerror(code) in lost[0]
    assert sum("events log: cannot write" in line for line in printed.splitlines()) == 1  # said once
    kinds = [e["kind"] for e in read_events(log)]  # only whole lines were kept
    # The run's record heads the log, after any device said missing as the run opened it (a
    # machine with no sound card: the audio output); the disk's room held no more than that.
    assert "run" in kinds and set(kinds[:kinds.index("run")]) <= {"device"}
    assert log.stat().st_size <= 3000 + (code == errno.EIO) * 10**6


def test_a_log_that_can_be_written_again_resumes_and_records_the_gap(tmp_path, monkeypatch):
    """Full for three seconds of clock time (each retry fails again), then room again: every
    event is either in the file, whole and in order, or counted lost, exactly."""
    path = tmp_path / "events.jsonl"
    disk = FailingDisk(errno.ENOSPC, room=400)
    _failing_disk(monkeypatch, tmp_path, disk)
    said = []
    log = EventLog(path, report=said.append)
    for i in range(600):
        if i == 300:
            disk.room = 10**9  # space freed at t = 3 s
        log.emit(i * 0.01, "tick", i=i)
        if i % 10 == 9:
            log.flush()  # as the live loop's housekeeping does
    log.close()
    monkeypatch.undo()
    assert disk.failures >= 3 and len(said) == 2  # the outage, said once, and its end
    assert "No space left on device" in said[0] and "writing" in said[1] and "again" in said[1]
    events = read_events(path)
    gaps = [e for e in events if e["kind"] == "events lost"]
    assert len(gaps) == 1 and gaps[0]["lost"] == log.lost and "No space left" in gaps[0]["error"]
    kept = [e["i"] for e in events if e["kind"] == "tick"]
    assert kept == sorted(kept) and kept[-1] == 599 and len(kept) + log.lost == 600


def test_a_full_disk_under_an_offline_log_is_counted_printed_and_recorded(config, tmp_path, monkeypatch, capsys):
    out = tmp_path / "out"
    _fill_disk(monkeypatch, out, "events.jsonl", room=5000)
    assert _offline(config, out, 3.0) == 0
    monkeypatch.undo()
    printed = capsys.readouterr().out
    manifest = load_json(out / MANIFEST, kind=MANIFEST_KIND)
    assert manifest["events_lost"] > 0
    assert f"{manifest['events_lost']} events not written" in printed and "No space left on device" in printed
    assert read_events(out / "events.jsonl")[0]["kind"] == "run"
    assert {"out.wav", "out.mid", "state/"} <= set(manifest["files"])  # the rest of the run was kept


def test_a_report_picture_the_disk_cannot_hold_is_said_with_its_file(tmp_path):
    """A full disk under the report's pictures: the error names the picture (from inside
    matplotlib it named no file, and the run's last line said only 'No space left on device').
    /dev/full answers every write with ENOSPC, as a full disk does."""
    from creatures.runtime.report import write_report

    events = tmp_path / "events.jsonl"
    events.write_text('{"t": 0.0, "kind": "run", "title": "x", "creatures": ["a"]}\n'
                      '{"t": 0.1, "kind": "note", "creature": "a", "time": 0.1, "pitch": 60, "duration": 0.2}\n')
    report = tmp_path / "report"
    report.mkdir()
    (report / "notes.png").symlink_to("/dev/full")
    with pytest.raises(OSError) as raised:
        write_report(events, report, title="x")
    assert raised.value.errno == errno.ENOSPC and raised.value.filename == str(report / "notes.png")
    assert str(report / "notes.png") in str(raised.value)


# -- defect 10: one run per folder ---------------------------------------------------------
HOLDER = r"""
import sys
from pathlib import Path
from creatures.lock import FolderLock
lock = FolderLock(Path(sys.argv[1]), "state folder").acquire()
print("held", flush=True)
sys.stdin.read()
"""


@pytest.fixture
def holder(tmp_path):
    """A live process holding a folder's lock until it is killed."""
    script = tmp_path / "holder.py"
    script.write_text(HOLDER)
    started = []

    def hold(folder: Path) -> subprocess.Popen:
        process = subprocess.Popen([sys.executable, str(script), str(folder)], env=_env(), stdin=subprocess.PIPE,
                                   stdout=subprocess.PIPE, text=True)
        started.append(process)
        assert process.stdout.readline() == "held\n"
        return process

    yield hold
    for process in started:
        process.kill()
        process.wait()


def test_two_runs_cannot_share_one_state_folder(config, tmp_path, holder, capsys):
    state = tmp_path / "state"
    other = holder(state)
    assert main(["run", str(config), "--state", str(state), "--duration", "0.2"]) == 2
    err = capsys.readouterr().err
    assert f"in use by another run (pid {other.pid})" in err and err.count("\n") == 1
    assert sorted(p.name for p in state.iterdir()) == [LOCK_FILE]  # nothing saved over the other run's state

    out = tmp_path / "out"  # an offline output directory too
    holder(out)
    assert _offline(config, out) == 2
    assert "two runs cannot share one output directory" in capsys.readouterr().err


def test_one_folder_as_a_runs_state_and_its_out_is_said_as_such_not_as_another_run(config, tmp_path, capsys):
    """flock cannot tell its holders apart: a live run given one folder as --state and --out
    was refused as 'in use by another run (pid N)', N its own pid, sending the artist to look
    for a run that did not exist."""
    both = tmp_path / "show"
    assert main(["run", str(config), "--state", str(both), "--out", str(both), "--duration", "0.2"]) == 2
    err = capsys.readouterr().err
    assert "another run" not in err and str(os.getpid()) not in err and err.count("\n") == 1
    assert f"{both}: already this run's state folder; one folder cannot be both its state folder and its " \
           "output directory" in err
    assert list(both.iterdir()) == []  # nothing saved, the lock let go
    with FolderLock(both, "state folder"):  # a lock let go is not held again in this process's name
        pass


def test_a_state_folder_removed_mid_run_is_locked_again_by_the_save_that_makes_it_again(tmp_path, holder):
    """Someone removes a live run's state folder (a clean-up script, a wrong ``rm -rf``): the
    next save makes it again, and must lock it again, or a second run could take the folder and
    share it unnoticed (both once ran, each saving over the other). A run that took the folder
    meanwhile keeps it: the save is refused and said, and nothing is written over its state."""
    from creatures.lock import hold
    from creatures.runtime.live import LiveSummary, _write_state

    state, said = tmp_path / "state", []
    ours = hold(state, "state folder", said.append)
    try:
        shutil.rmtree(state)
        summary = LiveSummary()
        _write_state(state, [("ada.json", "{}")], summary, said.append, 1.0)
        assert (state / "ada.json").read_text() == "{}" and summary.saved_at == 1.0
        assert (state / LOCK_FILE).read_text() == f"{os.getpid()}\n"
        assert said == [f"state folder {state} was removed while the run used it: made again and locked again"]
        other = subprocess.run([sys.executable, "-c", HOLDER, str(state)], env=_env(), input="", text=True,
                               capture_output=True)
        assert other.returncode != 0 and "in use by another run" in other.stderr  # the second run is refused

        shutil.rmtree(state)
        taker = holder(state)  # removed again, and this time another run takes it first
        _write_state(state, [("ada.json", "{}")], summary, said.append, 2.0)
        assert summary.failed_saves == 1 and summary.saved_at == 1.0
        assert f"in use by another run (pid {taker.pid})" in said[-1] and "previous state is kept" in said[-1]
        assert sorted(p.name for p in state.iterdir()) == [LOCK_FILE]
    finally:
        if ours is not None:
            ours.release()
    assert os.path.abspath(state) not in lock._LOCKS  # the lock another run refused is not kept as this process's


def test_a_stale_lock_of_a_dead_run_is_taken_over(config, tmp_path, holder, capsys):
    state = tmp_path / "state"
    dead = holder(state)
    dead.kill()
    dead.wait()
    assert (state / LOCK_FILE).read_text() == f"{dead.pid}\n"  # left behind, as SIGKILL leaves it
    assert main(["run", str(config), "--state", str(state), "--duration", "0.2"]) == 0
    assert f"left by pid {dead.pid}, which no longer holds it" in capsys.readouterr().out
    assert not (state / LOCK_FILE).exists() and (state / "ada.json").exists()
    with FolderLock(state, "state folder"):  # and it was let go at the end
        with pytest.raises(FolderLockedError):
            FolderLock(state, "state folder").acquire()


# -- defect 10: inspect --------------------------------------------------------------------
BAD_LOGS = {
    "not an object": ('{"t": 0, "kind": "run"}\n[1, 2]\n', 2),
    "no kind": ('{"t": 0, "kind": "run"}\n{"t": 1}\n', 2),
    "kind not a string": ('{"t": 0, "kind": 5}\n', 1),
    "note without pitch": ('{"t": 0, "kind": "run"}\n{"t": 0, "kind": "note", "creature": "a", "time": 0}\n', 2),
    "creature not a string": ('{"t": 0, "kind": "values", "creature": 5, "values": {"x": 1}}\n', 1),
    "tuple a list": ('{"t": 0, "kind": "selection", "creature": "a", "tuple": [1]}\n', 1),
    "nested too deep": ('{"t": 0, "kind": "run"}\n' + "[" * 100_000 + "\n", 2),
    "not UTF-8": (b'{"t": 0, "kind": "run"}\n\xff\xfe\n', 2),
}


@pytest.mark.parametrize("case", sorted(BAD_LOGS))
def test_inspect_reports_a_bad_log_with_file_and_line(case, tmp_path, capsys):
    text, line = BAD_LOGS[case]
    log = tmp_path / "events.jsonl"
    log.write_bytes(text if isinstance(text, bytes) else text.encode())
    assert main(["inspect", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert f"{log}:{line}: malformed event" in err and err.count("\n") == 1


def test_inspect_says_state_files_were_skipped_and_why(tmp_path, capsys):
    state = tmp_path / "state"
    state.mkdir()
    (state / "ada.json").write_text('{"format": "creature-music creature state", "version": 1, "state": {')
    (state / "bo.json").write_text('{"format": "something else"}')
    assert main(["inspect", str(state)]) == 2
    err = capsys.readouterr().err
    assert "no state files" not in err and "every state file there was skipped" in err
    assert f"{state / 'ada.json'}:1: malformed JSON" in err and "(and 1 more)" in err


def test_inspect_names_the_state_files_it_skipped_beside_those_it_read(config, tmp_path, capsys):
    out = tmp_path / "out"
    assert _offline(config, out) == 0
    (out / "state" / "cy.json").write_text("{")
    capsys.readouterr()
    assert main(["inspect", str(out)]) == 0
    printed = capsys.readouterr().out
    assert f"note: skipped {out / 'state' / 'cy.json'}:1: malformed JSON" in printed
    assert "cy.json" in (out / "inspect" / "index.html").read_text()


# -- defect 10: friendly stops -------------------------------------------------------------
def _signal_inside(monkeypatch, target, name: str, sig: int) -> None:
    """The command's work receives a real ``sig`` (delivered to this process) part-way."""
    real = getattr(target, name)

    def interrupted(*args, **kwargs):
        os.kill(os.getpid(), sig)
        return real(*args, **kwargs)

    monkeypatch.setattr(target, name, interrupted)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM, signal.SIGHUP], ids=["Ctrl-C", "SIGTERM", "SIGHUP"])
@pytest.mark.parametrize("command", ["offline", "demo", "inspect", "run"])
def test_ctrl_c_and_sigterm_end_every_command_with_one_line(command, sig, config, tmp_path, monkeypatch, capsys):
    from creatures.runtime import inspect as inspector
    from creatures.runtime import offline

    out = tmp_path / "out"
    if command == "inspect":
        assert _offline(config, out) == 0
        _signal_inside(monkeypatch, inspector, "read_state", sig)
        argv = ["inspect", str(out)]
    elif command == "run":  # while it loads the state: before its own loop handles signals
        _signal_inside(monkeypatch, live.Session, "load_state", sig)
        argv = ["run", str(config), "--state", str(tmp_path / "state"), "--duration", "5"]
    else:
        _signal_inside(monkeypatch, offline.Session, "step", sig)
        argv = (["offline", str(config), "--out", str(out), "--duration", "5", "--no-progress"] if command == "offline"
                else ["demo", "exchange", "--out", str(out), "--duration", "5"])
    capsys.readouterr()
    assert main(argv) == 128 + sig
    err = capsys.readouterr().err
    how = "Ctrl-C" if sig == signal.SIGINT else signal.Signals(sig).name
    assert err.startswith(f"creatures {command}: stopped by {how}") and err.count("\n") == 1
    if command in ("offline", "demo"):
        assert _hidden(out) == [] and not (out / "events.jsonl").exists()  # staging gone, nothing published
    if command == "run":
        assert not (tmp_path / "state" / LOCK_FILE).exists()


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["Ctrl-C", "SIGTERM"])
def test_a_stop_a_finaliser_swallows_is_raised_again_at_the_next_tick(sig, config, tmp_path, monkeypatch, capsys):
    """Python ignores an exception raised in ``__del__`` (numba's compiler swallowed about one
    SIGTERM in two this way): the stop must still end the run, in one line."""
    from creatures.runtime import offline

    class Finaliser:
        def __del__(self):
            os.kill(os.getpid(), sig)  # the handler runs in here, and what it raises is ignored

    real, swallowed = offline.Session.step, []

    def step(self, *args, **kwargs):
        if not swallowed:
            swallowed.append(True)
            Finaliser()  # dropped at once: its __del__ runs here
        return real(self, *args, **kwargs)

    monkeypatch.setattr(offline.Session, "step", step)
    out = tmp_path / "out"
    assert _offline(config, out, 5.0) == 128 + sig
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Exception ignored" not in err and "stopped by" in err
    assert _hidden(out) == [] and not (out / "events.jsonl").exists()


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["Ctrl-C", "SIGTERM"])
def test_a_stop_during_a_numba_compile_waits_for_the_compile_to_end(sig, config, tmp_path, monkeypatch, capsys):
    """Unwinding llvmlite mid-compile crashed the process (SIGSEGV): a stop that lands in
    numba's or llvmlite's code is not raised there, and ends the run at the next tick."""
    from creatures.runtime import offline

    compiling = {"os": os, "sig": sig, "done": []}
    code = compile("os.kill(os.getpid(), sig)\ndone.append(True)", f"{os.sep}site{os.sep}numba{os.sep}core.py", "exec")
    real = offline.Session.step

    def step(self, *args, **kwargs):
        if not compiling["done"]:
            exec(code, compiling)  # as if numba compiled a kernel on this tick and the signal came then
        return real(self, *args, **kwargs)

    monkeypatch.setattr(offline.Session, "step", step)
    out = tmp_path / "out"
    assert _offline(config, out, 5.0) == 128 + sig
    assert compiling["done"] == [True]  # the "compile" ran to its end
    assert capsys.readouterr().err.count("\n") == 1 and _hidden(out) == []


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["Ctrl-C", "SIGTERM"])
def test_a_stopped_offline_process_cleans_its_staging_folder(sig, config, tmp_path):
    """A real ``creatures offline`` process, stopped while it runs: one line, no traceback,
    no staging folder, the previous outputs as they were."""
    out = tmp_path / "out"
    assert _offline(config, out, 0.5) == 0
    before = _tree(out)
    process = subprocess.Popen([sys.executable, "-m", "creatures.cli", "offline", str(config), "--out", str(out),
                                "--duration", "3600", "--no-progress"], env=_env(), stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 120  # start-up under load; the staging folder says it runs
        while not list(out.glob(f"{outputs.STAGING}*/events.jsonl")):
            assert process.poll() is None and time.monotonic() < deadline
            time.sleep(0.05)
        process.send_signal(sig)
        err = process.communicate(timeout=120)[1]
    finally:
        process.kill()
        process.wait()
    assert process.returncode == 128 + sig
    assert "Traceback" not in err and err.count("\n") == 1 and "nothing was published" in err
    assert _tree(out) == before


def test_a_killed_runs_staging_folder_is_cleaned_at_the_next_start(config, tmp_path, capsys):
    out = tmp_path / "out"
    killed = subprocess.Popen([sys.executable, "-m", "creatures.cli", "offline", str(config), "--out", str(out),
                               "--duration", "3600", "--no-progress"], env=_env())
    try:
        deadline = time.monotonic() + 120
        while not list(out.glob(f"{outputs.STAGING}*/events.jsonl")):
            assert killed.poll() is None and time.monotonic() < deadline
            time.sleep(0.05)
    finally:
        killed.kill()
        killed.wait()
    assert list(out.glob(f"{outputs.STAGING}*"))  # SIGKILL: nothing could clean up
    (out / "state").mkdir()
    (out / "state" / "README.txt").write_text("not a run's")  # this next run is refused, after its start
    assert _offline(config, out) == 2
    assert _hidden(out) == []  # yet the killed run's staging folder is gone


# -- defect 10: a failed final save; file modes ---------------------------------------------
def test_a_failed_final_save_exits_non_zero_and_says_what_was_not_kept(config, tmp_path, monkeypatch, capsys):
    state = tmp_path / "state"
    assert main(["run", str(config), "--state", str(state), "--duration", "0.2"]) == 0
    before = _tree(state)
    _read_only(monkeypatch, state, errno.EROFS)
    assert main(["run", str(config), "--state", str(state), "--duration", "0.3"]) == 1
    monkeypatch.undo()
    err = capsys.readouterr().err
    assert "the final save failed" in err and "Read-only file system" in err
    assert "learned in this run was not kept" in err and str(state) in err
    assert _tree(state) == before


@pytest.mark.parametrize("mask", [0o022, 0o027])
def test_outputs_are_written_with_normal_modes_under_the_umask(mask, config, tmp_path):
    out = tmp_path / "out"
    previous = os.umask(mask)
    try:
        assert _offline(config, out) == 0
    finally:
        os.umask(previous)
    modes = {e: (out / e).stat().st_mode & 0o777 for e in [*outputs.entries(out)]}
    files, dirs = 0o666 & ~mask, 0o777 & ~mask
    assert {e: m for e, m in modes.items() if m != (dirs if e.endswith("/") else files)} == {}
    assert {"out.wav", "out.mid", "events.jsonl", "state/ada.json", "state/"} <= set(modes)


def test_only_names_a_run_wrote_may_be_replaced(config, tmp_path):
    out = tmp_path / "out"
    assert _offline(config, out) == 0
    (out / "mine.txt").write_text("the artist's")
    outputs.refuse_foreign(out, {"events.jsonl", "state", "out.wav"})  # the previous run's: fine
    with pytest.raises(OutputDirectoryError, match="mine.txt"):
        outputs.refuse_foreign(out, {"mine.txt"})


@pytest.mark.parametrize("input_flag", ["--midi", "--audio"])
def test_a_run_refused_for_its_input_leaves_no_folder_it_made(input_flag, config, tmp_path, capsys):
    """A text file given as MIDI or audio is refused in one line; the --out folder the run made
    for it is not left behind empty (a folder the user had is kept, with what it held)."""
    bad = tmp_path / "notes.txt"
    bad.write_text("not a recording\n")
    out = tmp_path / "out"
    assert _offline(config, out, 1.0, input_flag, str(bad)) == 2
    assert not out.exists()
    kept = tmp_path / "kept"
    kept.mkdir()
    (kept / "mine.txt").write_text("the artist's")
    assert _offline(config, kept, 1.0, input_flag, str(bad)) == 2
    assert sorted(p.name for p in kept.iterdir()) == ["mine.txt"]
    assert "Traceback" not in capsys.readouterr().err


def test_frames_asked_of_bodiless_creatures_leave_no_empty_frames_folder(tmp_path, capsys):
    """`--video` (or a demo) on a creature with no body (the tutorial's heron) says "no frames"
    and publishes no empty frames/ beside it."""
    out = tmp_path / "out"
    assert main(["offline", str(ROOT / "installations" / "tutorial" / "heron-1.toml"), "--out", str(out),
                 "--duration", "1", "--no-progress", "--video"]) == 0
    assert "no frames" in capsys.readouterr().out
    assert not (out / "frames").exists() and not (out / "out.mp4").exists()


def test_demo_points_to_its_report_only_when_it_wrote_one(tmp_path, capsys):
    """The tutorial's heron writes no report (`[output] report = false`): the demo must not
    send the user to a page that is not there; exchange's report is pointed to."""
    assert main(["demo", "tutorial/heron-1", "--out", str(tmp_path / "heron"), "--duration", "1"]) == 0
    assert "index.html" not in capsys.readouterr().out
    assert main(["demo", "exchange", "--out", str(tmp_path / "exchange"), "--duration", "1"]) == 0
    assert f"open {tmp_path / 'exchange' / 'report' / 'index.html'}" in capsys.readouterr().out


def test_a_midi_file_the_run_hears_nothing_of_is_said(config, tmp_path, capsys):
    """A file of no tracks, and one whose notes all lie past the run's end, ran with exit 0
    and no word: the user took the creatures' silence for theirs."""
    import mido

    empty = tmp_path / "empty.mid"
    mido.MidiFile(type=1).save(empty)
    late = tmp_path / "late.mid"
    track = mido.MidiTrack([mido.Message("note_on", note=60, velocity=90, time=480 * 10),
                            mido.Message("note_off", note=60, velocity=0, time=480)])
    mido.MidiFile(type=0, tracks=[track], ticks_per_beat=480).save(late)  # 120 bpm: the note at 5 s
    assert _offline(config, tmp_path / "a", 1.0, "--midi", str(empty)) == 0
    assert f"{empty}: holds no notes" in capsys.readouterr().out
    assert _offline(config, tmp_path / "b", 1.0, "--midi", str(late)) == 0
    assert f"{late}: none of its 1 notes falls within the run's 1 s (the first at 5.0 s)" in capsys.readouterr().out
    assert _offline(config, tmp_path / "c", 6.0, "--midi", str(late)) == 0
    assert "late.mid" not in capsys.readouterr().out.split("wrote")[0]


def test_the_demo_runs_a_piece_as_long_as_its_config_says(tmp_path, monkeypatch, capsys):
    """One 30 s default for every piece showed Duncan four cues and no learning: a piece runs
    its own ``duration`` unless ``--duration`` says otherwise."""
    import shutil

    import installations

    shipped = tmp_path / "shipped"
    shutil.copytree(installations.HERE / "tutorial", shipped / "tutorial")
    heron = shipped / "tutorial" / "heron-1.toml"
    heron.write_text(heron.read_text(encoding="utf-8").replace("duration = 120.0", "duration = 2.5"), encoding="utf-8")
    monkeypatch.setattr(installations, "HERE", shipped)
    assert main(["demo", "tutorial/heron-1", "--out", str(tmp_path / "own")]) == 0
    assert "2.5 simulated s" in capsys.readouterr().out
    assert main(["demo", "tutorial/heron-1", "--out", str(tmp_path / "asked"), "--duration", "1.5"]) == 0
    assert "1.5 simulated s" in capsys.readouterr().out
