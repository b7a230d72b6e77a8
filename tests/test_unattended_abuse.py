"""An installation engineer's abuse of a show left running: stops at awkward moments, outputs
and state folders shared with what the artist keeps (docs/unattended.md)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent

KEEPER = """
import sys
from creatures.runtime import keeper
keeper.RESTART_AFTER = 30.0  # a crash loop's wait: long, so a stop can only come during it
child = (sys.executable, "-c", "import pathlib, sys, time; runs = pathlib.Path(sys.argv[1]); "
         "runs.write_text(runs.read_text() + 'x') if runs.exists() else runs.write_text('x'); "
         "sys.exit(1) if len(runs.read_text()) == 1 else time.sleep(120)", sys.argv[1])
sys.exit(keeper.supervise(list(child), lambda line: print(line, flush=True)))
"""


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT, signal.SIGHUP], ids=lambda s: s.name)
def test_a_stop_while_the_keeper_waits_to_restart_ends_it_and_starts_nothing(tmp_path: Path, sig) -> None:
    """The keeper slept out its wait before a restart (up to 30 s) and then started a new child
    whatever it was sent meanwhile: that child ran on, to be stopped only by a second signal,
    and ``kill KEEPER`` on a crash-looping show looked obeyed and was not."""
    runs = tmp_path / "runs"
    keeper = subprocess.Popen([sys.executable, "-c", KEEPER, str(runs)], env={**os.environ, "PYTHONPATH": str(ROOT)},
                              stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True)
    try:
        line = keeper.stdout.readline()  # said once the first child has died: the keeper now waits
        assert "restart 1 in 30 s" in line, line
        keeper.send_signal(sig)
        code = keeper.wait(timeout=20)
    finally:
        if keeper.poll() is None:
            os.killpg(keeper.pid, signal.SIGKILL)
            keeper.wait()
    assert code == 128 + sig
    assert "not restarting" in keeper.stdout.read()
    assert runs.read_text() == "x"  # one child only: none was started after the stop


COLONY = f"""
extends = "{ROOT / 'installations' / 'exchange.toml'}"
[output]
report = false
"""


def _tree(root: Path) -> dict[str, bytes]:
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def test_learning_a_live_run_saved_into_an_offline_runs_state_is_never_removed(tmp_path: Path, capsys) -> None:
    """An offline run's ``state/`` is "as a live run's --state saves it" (README), so an engineer
    goes on learning live there: ``creatures run show.toml --state DIR/state``. The next
    ``creatures offline show.toml --out DIR`` took those files for its own old outputs (the
    manifest listed their names) and removed them with the live run's learning: exit 0."""
    from creatures.cli import main

    config, out = tmp_path / "show.toml", tmp_path / "DIR"
    config.write_text(COLONY)
    assert main(["offline", str(config), "--out", str(out), "--duration", "1", "--no-progress"]) == 0
    offline = _tree(out / "state")
    live = subprocess.run([sys.executable, "-m", "creatures", "run", str(config), "--state", str(out / "state"),
                           "--duration", "1"], env={**os.environ, "PYTHONPATH": str(ROOT)}, capture_output=True,
                          text=True, timeout=300)
    assert live.returncode == 0, live.stderr
    learned = _tree(out / "state")
    assert learned != offline and set(learned) == set(offline)  # the same names, the live run's learning
    capsys.readouterr()
    before = _tree(out)
    assert main(["offline", str(config), "--out", str(out), "--duration", "1", "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "changed since a creatures run wrote it" in err and str(out / "state") in err
    assert _tree(out) == before  # nothing replaced, nothing removed


def test_outputs_of_a_manifest_without_stamps_are_still_the_runs_to_replace(tmp_path: Path) -> None:
    """An output folder written before stamps has a manifest of names only: its files are still
    replaced by the next run, not refused as changed."""
    from creatures.cli import main
    from creatures.persist import load_json, save_json
    from creatures.runtime.outputs import MANIFEST, MANIFEST_KIND

    config, out = tmp_path / "show.toml", tmp_path / "DIR"
    config.write_text(COLONY)
    assert main(["offline", str(config), "--out", str(out), "--duration", "1", "--no-progress"]) == 0
    manifest = load_json(out / MANIFEST, kind=MANIFEST_KIND)
    assert set(manifest.pop("stamps")) == {e for e in manifest["files"] if not e.endswith("/")}
    save_json(out / MANIFEST, {k: v for k, v in manifest.items() if k not in ("format", "version")}, kind=MANIFEST_KIND)
    (out / "state" / "ada.json").write_text((out / "state" / "ada.json").read_text() + " ")  # changed: unknowable
    assert main(["offline", str(config), "--out", str(out), "--duration", "2", "--no-progress"]) == 0


def test_a_live_run_given_a_snapshot_as_its_state_is_refused_and_the_snapshot_kept(tmp_path: Path) -> None:
    """``creatures run show.toml --state STATE/snapshots/<stamp>`` (an engineer going back to
    last Tuesday) ran, and every save rewrote the snapshot: the history `state diff` and
    `rollback` read was gone, with nothing said. ``rollback`` and ``merge`` refused to write
    into a snapshot; the run now does too, before anything starts."""
    config, state = tmp_path / "show.toml", tmp_path / "state"
    config.write_text(COLONY)
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    first = subprocess.run([sys.executable, "-m", "creatures", "run", str(config), "--state", str(state),
                            "--duration", "1"], env=env, capture_output=True, text=True, timeout=300)
    assert first.returncode == 0, first.stderr
    snapshot = state / "snapshots" / "2026-12-01T000000Z"
    snapshot.mkdir(parents=True)
    for saved in state.glob("*.json"):
        (snapshot / saved.name).write_bytes(saved.read_bytes())
    kept = _tree(snapshot)
    run = subprocess.run([sys.executable, "-m", "creatures", "run", str(config), "--state", str(snapshot),
                          "--duration", "1"], env=env, capture_output=True, text=True, timeout=300)
    assert run.returncode == 2
    assert run.stderr.splitlines() == [f"creatures: {snapshot}: is a snapshot, kept as the colony was then; run on "
                                       f"the state folder ({state}), and its next snapshot keeps that (nothing "
                                       "changed; to work from the snapshot itself, copy it into a folder of its own)"]
    assert _tree(snapshot) == kept


def test_service_never_writes_its_unit_over_a_file_it_did_not_write(tmp_path: Path) -> None:
    """``creatures service show.toml --out show.toml`` (the unit's name typed as the config's)
    wrote the unit over the installation's config: exit 0, the piece gone. A unit the command
    wrote is still replaced by the next one (a new --watchdog)."""
    config, unit = tmp_path / "show.toml", tmp_path / "show.service"
    config.write_text(COLONY)
    env = {**os.environ, "PYTHONPATH": str(ROOT)}

    def service(out: Path, *more: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run([sys.executable, "-m", "creatures", "service", str(config), "--out", str(out), *more],
                              env=env, capture_output=True, text=True, timeout=120)

    refused = service(config)
    assert refused.returncode == 2
    assert refused.stderr == (f"creatures: --out {config}: holds a file that is not a unit `creatures service` wrote; "
                              "not replaced (nothing written): choose another --out, or move that file away\n")
    assert config.read_text() == COLONY and sorted(p.name for p in tmp_path.iterdir()) == ["show.toml"]
    assert service(unit).returncode == 0 and "WatchdogSec=30" in unit.read_text()
    assert service(unit, "--watchdog", "20").returncode == 0 and "WatchdogSec=20" in unit.read_text()


def test_inspect_never_writes_its_page_over_the_artists(tmp_path: Path) -> None:
    """``creatures inspect STATE --out ~/site`` wrote its index.html (and PNGs) over the
    artist's own page there: exit 0, the page gone. Now it is refused, naming the file, and
    nothing is written; a folder inspect wrote is still written again."""
    config, state, site = tmp_path / "show.toml", tmp_path / "state", tmp_path / "site"
    config.write_text(COLONY)
    env = {**os.environ, "PYTHONPATH": str(ROOT)}

    def creatures(*argv: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run([sys.executable, "-m", "creatures", *argv], env=env, capture_output=True, text=True,
                              timeout=300)

    assert creatures("run", str(config), "--state", str(state), "--duration", "1").returncode == 0
    site.mkdir()
    (site / "index.html").write_text("<h1>the gallery's own page</h1>")
    before = _tree(site)
    refused = creatures("inspect", str(state), "--out", str(site))
    assert refused.returncode == 2
    assert refused.stderr == (f"creatures: {site}: not replacing {site / 'index.html'}: no creatures run wrote it "
                              "(it is not in .creatures-manifest.json); nothing was changed. Move it away or choose "
                              "another --out\n")
    assert _tree(site) == before
    for _ in range(2):  # its own folder: written, then written again
        assert creatures("inspect", str(state), "--out", str(tmp_path / "seen")).returncode == 0
    assert "ada" in (tmp_path / "seen" / "index.html").read_text()


def test_a_live_runs_out_mid_leaves_an_offline_runs_outputs_beside_it(tmp_path: Path) -> None:
    """``creatures run show.toml --out DIR`` into the folder of the rehearsal's offline run
    published its ``out.mid`` as if it were a whole run's outputs, and so removed the offline
    run's ``events.jsonl``, ``out.wav`` and learned ``state/`` when the show ended, saying only
    "wrote DIR/out.mid". It replaces ``out.mid`` alone now; the next offline run still
    replaces all of it."""
    from creatures.cli import main
    from creatures.persist import load_json
    from creatures.runtime.outputs import MANIFEST, MANIFEST_KIND

    config, out = tmp_path / "show.toml", tmp_path / "DIR"
    config.write_text(COLONY)
    assert main(["offline", str(config), "--out", str(out), "--duration", "1", "--no-progress"]) == 0
    rehearsed = {name: data for name, data in _tree(out).items() if name not in (MANIFEST, "out.mid")}
    live = subprocess.run([sys.executable, "-m", "creatures", "run", str(config), "--out", str(out), "--duration", "1"],
                          env={**os.environ, "PYTHONPATH": str(ROOT)}, capture_output=True, text=True, timeout=300)
    assert live.returncode == 0, live.stderr
    assert f"wrote {out / 'out.mid'}" in live.stdout
    after = _tree(out)
    assert {name: after.get(name) for name in rehearsed} == rehearsed and "state/ada.json" in rehearsed
    listed = set(load_json(out / MANIFEST, kind=MANIFEST_KIND)["files"])
    assert listed == {e for e in [*after, "state/"] if e != MANIFEST}
    assert main(["offline", str(config), "--out", str(out), "--duration", "1", "--no-progress"]) == 0
