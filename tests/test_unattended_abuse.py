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
