"""The command line's own choices: offline pictures on request, and a live run that says when
it will keep nothing it learns."""

from __future__ import annotations

from pathlib import Path

import imageio.v3 as iio
import pytest

import installations
from creatures.cli import NO_STATE, main

LIVE = """
title = "live check"
tick = 0.02
{state}
[audio]
output_device = "NoSuchCard"
[midi]
output_port = "NoSuchSynth"
[[creature]]
name = "ada"
kind = "exchange"
"""


def _offline(out: Path, *flags: str) -> int:
    return main(["offline", str(installations.path("exchange")), "--out", str(out), "--duration", "1.0",
                 "--no-progress", *flags])


def test_offline_draws_no_pictures_unless_asked(tmp_path, capsys):
    assert _offline(tmp_path) == 0
    assert "no frames" not in capsys.readouterr().out
    assert not (tmp_path / "frames").exists() and not (tmp_path / "out.mp4").exists()


@pytest.mark.gl
@pytest.mark.parametrize("flag", ["--frames", "--video"])
def test_offline_frames_and_video_on_request(flag, tmp_path, capsys):
    assert _offline(tmp_path, flag) == 0
    out = capsys.readouterr().out
    if "no frames:" in out:  # the flag was honoured; this machine has no offscreen GL
        pytest.skip(out[out.index("no frames:"):].splitlines()[0])
    frames = sorted((tmp_path / "frames").glob("*.png"))
    assert len(frames) == 13  # 12 frames per second (exchange.toml's fps default), 0 s to 1 s inclusive
    assert iio.imread(frames[-1]).ndim == 3
    assert (tmp_path / "out.mp4").is_file() == (flag == "--video")
    assert ("frames" in out) and (("out.mp4" in out) == (flag == "--video"))


@pytest.mark.parametrize("state", ["none", "option", "config"])
def test_live_run_says_when_learned_state_will_not_be_kept(state, tmp_path, capsys):
    config = tmp_path / "live.toml"
    config.write_text(LIVE.format(state='state = "kept"' if state == "config" else ""))
    argv = ["run", str(config), "--duration", "0.1"] + (["--state", str(tmp_path / "s")] if state == "option" else [])
    assert main(argv) == 0
    out = capsys.readouterr().out
    if state == "none":
        assert out.index(f"note: {NO_STATE}") < out.index("stopped after")
    else:
        assert NO_STATE not in out
        assert (tmp_path / ("s" if state == "option" else "kept") / "ada.json").is_file()


def test_python_dash_m_creatures_is_the_creatures_command():
    """Where the ``creatures`` script is not on PATH (a venv not activated), ``python -m
    creatures`` runs the same command (it once said 'No module named creatures.__main__')."""
    import subprocess
    import sys

    root = str(Path(__file__).resolve().parents[1])
    done = subprocess.run([sys.executable, "-m", "creatures", "version"], cwd=root, capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0 and done.stdout.startswith("creature-music "), done.stderr
