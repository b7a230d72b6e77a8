"""A hand-written three-joint body (a heron's neck and beak) as BVH, for the body-from-files tests."""

from __future__ import annotations

from pathlib import Path

import numpy as np

HIERARCHY = """HIERARCHY
ROOT base
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT neck
  {
    OFFSET 0 50 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    JOINT head
    {
      OFFSET 0 40 0
      CHANNELS 3 Zrotation Xrotation Yrotation
      End Site
      {
        OFFSET 0 0 30
      }
    }
  }
}
"""


def heron_frames(seconds: float = 12.0, fps: float = 20.0) -> np.ndarray:
    """Rows of channel values: the neck sweeps side to side and dips, the head nods
    (incommensurate, so the beak fills a volume in front of the body), in centimetres/degrees."""
    t = np.arange(int(round(seconds * fps))) / fps
    phase = 2.0 * np.pi * t / seconds
    rows = np.zeros((len(t), 12))
    rows[:, 1] = 10.0  # the base stands 10 cm up
    rows[:, 6] = 20.0 * np.sin(3.0 * phase)          # neck Z roll
    rows[:, 7] = 25.0 + 30.0 * np.sin(5.0 * phase)   # neck X pitch
    rows[:, 8] = 60.0 * np.sin(phase)                # neck Y yaw
    rows[:, 10] = 35.0 * (1.0 - np.cos(7.0 * phase))  # head X nod
    return rows


def write_bvh(path: Path, rows: np.ndarray, fps: float = 20.0, hierarchy: str = HIERARCHY) -> Path:
    body = "\n".join(" ".join(f"{x:.5f}" for x in row) for row in rows)
    path.write_text(f"{hierarchy}MOTION\nFrames: {len(rows)}\nFrame Time: {1.0 / fps!r}\n{body}\n")
    return path


BODY = """
[creature.body]
effectors = ["head_end"]
scale = 0.01
rest_pose = {{ neck = [20.0, 0.0, 0.0] }}
joint_limits = {{ neck = 1.2, head = 1.3 }}
{extra}
[[creature.body.animations]]
file = "heron.bvh"
labels = {{ peck = [[100, 104]] }}
"""


def heron_config(directory: Path, *, kind: str = "exchange", extra: str = "", duration: float = 40.0) -> Path:
    """An installation of one exchange creature on the heron body (files in ``directory``)."""
    if not (directory / "heron.bvh").exists():
        write_bvh(directory / "heron.bvh", heron_frames())
    path = directory / "heron.toml"
    path.write_text(f"""title = "heron"
seed = 3
tick = 0.04
duration = {duration}

[audio]
sample_rate = 22050

[[creature]]
name = "heron"
kind = "{kind}"
channel = 0
""" + BODY.format(extra=extra))
    return path
