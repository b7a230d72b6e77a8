"""The rendered body: headless frames that follow the pose, notes coloured by pitch, frame timing."""

from __future__ import annotations

import colorsys
import os
import subprocess
import sys

import imageio.v2 as imageio_v2
import imageio.v3 as iio
import numpy as np
import pytest

from creatures.body import render
from creatures.body.frames import FrameClock, FrameWriter
from creatures.body.render import BodyRenderer, NoteMark, RenderUnavailable, pitch_colour

# A tiny stick figure: pelvis, spine, head, two arms, two legs (parents as the motor Skeleton has them).
PARENTS = np.array([-1, 0, 1, 1, 3, 1, 5, 0, 7, 0, 9])
STANDING = np.array([
    [0.0, 1.0, 0.0], [0.0, 1.5, 0.0], [0.0, 1.8, 0.0],
    [-0.3, 1.45, 0.0], [-0.6, 1.2, 0.0], [0.3, 1.45, 0.0], [0.6, 1.2, 0.0],
    [-0.15, 0.5, 0.0], [-0.15, 0.0, 0.0], [0.15, 0.5, 0.0], [0.15, 0.0, 0.0],
])


@pytest.fixture(scope="module")
def renderer():
    try:
        r = BodyRenderer(160, 120, camera_pose=render.look_at((0.0, 1.0, 3.0), (0.0, 1.0, 0.0)))
    except RenderUnavailable as exc:
        pytest.skip(f"no GL platform: {exc}")
    yield r
    r.close()


@pytest.mark.gl
def test_silhouette_follows_the_pose(renderer):
    colour, depth = renderer.render_with_depth(STANDING, PARENTS)
    body = depth > 0
    assert colour.shape == (120, 160, 3) and colour.dtype == np.uint8
    assert 0.005 < body.mean() < 0.5  # something drawn, not everything

    raised = STANDING.copy()
    raised[6] = [0.55, 2.0, 0.0]  # right hand up
    _, raised_depth = renderer.render_with_depth(raised, PARENTS)
    changed = body ^ (raised_depth > 0)
    assert changed.sum() > 50
    rows, cols = np.nonzero(changed)
    assert cols.mean() > 80  # the change is on the (image) right, where the arm moved

    _, moved_depth = renderer.render_with_depth(STANDING + [0.5, 0.0, 0.0], PARENTS)
    shift = np.nonzero(moved_depth > 0)[1].mean() - np.nonzero(body)[1].mean()
    assert shift > 10  # the whole silhouette slides right with the body


@pytest.mark.gl
def test_notes_are_spheres_coloured_by_pitch(renderer):
    notes = [NoteMark((-0.9, 1.6, 0.0), 60, radius=0.12), NoteMark((0.9, 1.6, 0.0), 67, radius=0.12)]
    colour, depth = renderer.render_with_depth(STANDING, PARENTS, notes)
    _, body_only = renderer.render_with_depth(STANDING, PARENTS)
    note_pixels = (depth > 0) & ~(body_only > 0)
    left = note_pixels & (np.arange(160) < 50)[None, :]
    right = note_pixels & (np.arange(160) > 110)[None, :]
    assert left.sum() > 20 and right.sum() > 20

    def hue(mask):
        r, g, b = colour[mask].mean(axis=0) / 255
        return colorsys.rgb_to_hsv(r, g, b)[0]

    for mask, pitch in ((left, 60), (right, 67)):
        expected = colorsys.rgb_to_hsv(*pitch_colour(pitch))[0]
        distance = abs(hue(mask) - expected)
        assert min(distance, 1.0 - distance) < 0.05  # hue is circular


@pytest.mark.gl
def test_bad_pose_shapes_are_refused(renderer):
    with pytest.raises(ValueError, match=r"positions \(J, 3\) and parents \(J,\)"):
        renderer.render(STANDING[:, :2], PARENTS)


def test_missing_gl_platform_gives_a_clear_message(monkeypatch):
    monkeypatch.delenv("PYOPENGL_PLATFORM", raising=False)
    monkeypatch.setattr(render.subprocess, "run", lambda *a, **k: subprocess.CompletedProcess(
        a, 1, "", "ImportError: Unable to load EGL library"))
    with pytest.raises(RenderUnavailable, match=r"egl: ImportError.*osmesa: .*install EGL"):
        render.gl_platform.__wrapped__()


def test_unusable_platform_raises_render_unavailable_and_the_caller_carries_on():
    script = (
        "from creatures.body.render import BodyRenderer, RenderUnavailable\n"
        "try:\n    BodyRenderer(64, 48)\nexcept RenderUnavailable as exc:\n    print('no frames:', exc)\n"
        "print('still running')"
    )
    env = {**os.environ, "PYOPENGL_PLATFORM": "nosuchgl"}
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=120)
    assert done.returncode == 0, done.stderr
    assert "no frames:" in done.stdout and "nosuchgl" in done.stdout and "still running" in done.stdout


def test_frame_clock_counts_frames_from_elapsed_time(clock):
    frames = FrameClock(25.0, clock)
    assert frames.due() == 1  # frame 0 at the start
    clock.advance(0.01)
    assert frames.due() == 0  # a fast tick: no new frame
    clock.advance(0.2)
    assert frames.due() == 5  # a slow tick: the frames it spanned (t = 0.04 … 0.2)
    for _ in range(79):  # many uneven ticks still add up to elapsed × fps
        clock.advance(0.0123)
        frames.due()
    assert frames.emitted == int((0.21 + 79 * 0.0123) * 25) + 1
    with pytest.raises(ValueError, match="fps"):
        FrameClock(0.0, clock)


def test_frame_writer_writes_pngs_and_a_video(tmp_path, rng):
    frames = [rng.integers(0, 255, size=(48, 64, 3), dtype=np.uint8) for _ in range(3)]
    with FrameWriter(directory=tmp_path / "png", video=tmp_path / "body.mp4", fps=10) as writer:
        writer.write(frames[0])
        writer.write(frames[1], repeat=3)
        writer.write(frames[2])
    pngs = sorted((tmp_path / "png").glob("frame_*.png"))
    assert len(pngs) == 5 and writer.count == 5
    np.testing.assert_array_equal(iio.imread(pngs[3]), frames[1])
    with imageio_v2.get_reader(tmp_path / "body.mp4") as video:
        decoded = [frame for frame in video]
    assert len(decoded) == 5 and decoded[0].shape == (48, 64, 3)


@pytest.mark.gl
def test_renders_a_motor_system_body_pose(renderer):
    """Cross-check against the motor system's own types: a BodyPose's FK positions + parents."""
    from creatures.motor import quaternion as quat
    from creatures.motor.pose import BodyPose
    from creatures.motor.skeleton import Skeleton

    skeleton = Skeleton(("hips", "chest", "arm", "hand"), np.array([-1, 0, 1, 2]),
                        np.array([[0.0, 1.0, 0.0], [0.0, 0.5, 0.0], [0.0, 0.3, 0.0], [0.5, 0.0, 0.0]]),
                        np.ones(4), end_effectors=("hand",))

    def pose(elbow: float) -> BodyPose:
        rotations = quat.identity((4,))
        rotations[2] = quat.from_axis_angle(np.array([0.0, 0.0, 1.0]), elbow)
        return BodyPose(rotations, np.zeros((4, 3)), np.zeros(3), skeleton=skeleton)

    _, down = renderer.render_with_depth(pose(-1.2).positions, skeleton.parents)
    _, up = renderer.render_with_depth(pose(1.2).positions, skeleton.parents)
    assert (down > 0).sum() > 20
    rows_down, rows_up = np.nonzero(down > 0)[0], np.nonzero(up > 0)[0]
    assert rows_up.min() < rows_down.min() - 5  # the raised hand reaches higher in the image
