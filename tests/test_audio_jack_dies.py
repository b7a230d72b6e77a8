"""A live run whose JACK server dies under it (a real ``jackd`` dummy server, killed mid-run).

PortAudio stopping a stream whose JACK server died never returns, and nothing can open in that
process after it. Found by an audit: the run kept ticking, saving and heartbeats stopped (the
supervisor's thread waited in ``Pa_StopStream``), ``/health`` said running, and at the end the
process hung in ``Pa_Terminate`` until killed. Now the run says so, saves, and ends with
:data:`creatures.runtime.keeper.AFRESH` for its keeper to start it afresh (audio/resilient.py).

The test starts its own named server (the one ``.ci/run`` starts serves the other JACK tests).
JACK keeps 8 server names in shared memory, and a server killed with SIGKILL keeps its entry
until a server of that name starts again: so the name is fixed, and the test starts it once more
and stops it cleanly at the end, leaving the table as it found it.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from creatures.runtime.keeper import AFRESH

pytestmark = [pytest.mark.jack, pytest.mark.skipif(shutil.which("jackd") is None, reason="needs jackd (jackd2)")]

ROOT = Path(__file__).resolve().parent.parent


def test_a_run_whose_jack_server_dies_saves_and_ends_to_be_started_afresh(tmp_path: Path) -> None:
    server = "creatures-dies"
    env = {**os.environ, "JACK_DEFAULT_SERVER": server, "PYTHONPATH": str(ROOT)}
    jack = subprocess.Popen(["jackd", "-n", server, "--no-realtime", "-d", "dummy", "-r", "44100", "-p", "512"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, env=env)
    run = None
    try:
        if subprocess.run(["jack_wait", "-w", "-t", "15"], env=env, capture_output=True).returncode != 0:
            jack.kill()
            pytest.skip(f"jackd -n {server} did not come up: {jack.communicate()[1][-300:]}")
        env["NOTIFY_SOCKET"] = str(tmp_path / "n")  # the run says READY=1 there
        config = tmp_path / "show.toml"
        config.write_text('title = "dies"\nsave_every = 3600\n[audio]\nsample_rate = 22050\n'
                          '[[creature]]\nname = "ada"\nkind = "exchange"\n')
        notify = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        notify.bind(str(tmp_path / "n"))
        notify.settimeout(180)  # starting python and numba under load: slow, not timed
        run = subprocess.Popen([sys.executable, "-m", "creatures.cli", "run", str(config),
                                f"--state={tmp_path / 'state'}", f"--log={tmp_path / 'events.jsonl'}",
                                "--duration", "600"],
                               stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
        try:
            while b"READY=1" not in notify.recv(4096).split(b"\n"):
                pass
        finally:
            notify.close()
        jack.send_signal(signal.SIGKILL)  # the server dies as a crashed one does: no goodbye to its clients
        jack.wait()
        out, _ = run.communicate(timeout=120)  # hung for minutes before, until killed
    finally:
        for process in (run, jack):
            if process is not None and process.poll() is None:
                process.kill()
                process.wait()
        _free_the_name(env)
    assert run.returncode == AFRESH, out
    assert "audio output (default) lost" in out and "did not let go of the lost audio output" in out
    assert f"stopped to be started afresh, exit status {AFRESH}" in out
    assert (tmp_path / "state" / "ada.json").exists()  # only the stop saves (save_every 3600 s)
    events = [json.loads(line) for line in (tmp_path / "events.jsonl").read_text().splitlines()]
    device = [e["message"] for e in events if e["kind"] == "device"]  # the weekend's log says it too
    assert len(device) == 2 and "lost" in device[0] and "did not let go" in device[1]
    assert [e["why"] for e in events if e["kind"] == "afresh"] == [device[1].split(":")[0]]


def _free_the_name(env: dict[str, str]) -> None:
    """Start the killed server's name once more and stop it cleanly: its entry in JACK's table
    of server names is let go (see the module docstring)."""
    env = {key: value for key, value in env.items() if key != "NOTIFY_SOCKET"}
    again = subprocess.Popen(["jackd", "-n", env["JACK_DEFAULT_SERVER"], "--no-realtime", "-d", "dummy", "-r", "44100",
                              "-p", "512"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env)
    try:
        subprocess.run(["jack_wait", "-w", "-t", "15"], env=env, capture_output=True)
    finally:
        again.terminate()
        again.wait(timeout=30)
