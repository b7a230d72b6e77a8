"""The rendered body: headless frames that follow the pose, notes coloured by pitch, frame timing."""

from __future__ import annotations

import colorsys
import os
import subprocess
import sys
import tracemalloc
from pathlib import Path

import imageio.v2 as imageio_v2
import imageio.v3 as iio
import numpy as np
import pytest
from scipy.ndimage import binary_dilation, binary_erosion

from creatures.body import render
from creatures.body.frames import FrameClock, FrameWriter, VideoUnavailable
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


THREE = np.concatenate([STANDING + [dx, 0.0, 0.0] for dx in (-1.5, 0.0, 1.5)])
THREE[6] = [-0.95, 2.0, 0.2]  # the first creature's right hand raised towards the viewer
THREE_PARENTS = np.concatenate([np.where(PARENTS >= 0, PARENTS + 11 * k, -1) for k in range(3)])
THREE_NOTES = [NoteMark((-1.2 + 0.5 * i, 2.2, 0.1 * i), 55 + 3 * i, radius=0.08 + 0.01 * i) for i in range(6)]
PYRENDER_FRAME = Path(__file__).parent / "data" / "frames" / "three_bodies_pyrender.png"
"""THREE drawn at 640×480 by the pyrender renderer this module replaced (4× multisampled)."""


@pytest.mark.gl
def test_frames_match_the_pyrender_renderer_within_the_stated_tolerance():
    """Same meshes, camera, light and materials (pyrender's shading model, ported): the frames
    differ only where pyrender antialiased edges. Tolerance: at most 1% of pixels differ by more
    than 8 levels (of 255) in any channel; at most 0.05% do so away from the outlines (more than
    one pixel from either frame's silhouette edge, e.g. where a joint meets a bone); inside the
    silhouettes the mean difference is under 3 levels; the silhouettes overlap by IoU ≥ 0.8
    (pyrender's partial-coverage edge pixels count as drawn)."""
    try:
        renderer = BodyRenderer(640, 480)
    except RenderUnavailable as exc:
        pytest.skip(f"no GL platform: {exc}")
    with renderer:
        ours = renderer.render(THREE, THREE_PARENTS, THREE_NOTES).astype(int)
    theirs = iio.imread(PYRENDER_FRAME).astype(int)
    difference = np.abs(ours - theirs).max(axis=2)
    background = np.round(np.array([0.08, 0.08, 0.1]) * 255)
    drawn_ours, drawn_theirs = (np.abs(f - background).max(axis=2) > 0 for f in (ours, theirs))
    inside = binary_erosion(drawn_ours & drawn_theirs)
    outlines = binary_dilation(drawn_ours | drawn_theirs) & ~inside
    assert (difference > 8).mean() <= 0.01
    assert ((difference > 8) & ~outlines).mean() <= 0.0005
    assert difference[inside].mean() < 3.0
    assert (drawn_ours & drawn_theirs).sum() / (drawn_ours | drawn_theirs).sum() >= 0.8
    assert drawn_ours.sum() > 3000  # three bodies and six notes, not an empty frame


@pytest.mark.gl
def test_a_frame_rendered_into_a_buffer_is_the_frame(renderer):
    """The frame loop's path (``out=``, no allocation) gives what a fresh array gets, and later
    frames do not change an earlier returned one."""
    fresh = renderer.render(STANDING, PARENTS, [NoteMark((0.5, 1.5, 0.0), 64)])
    buffer = np.zeros_like(fresh)
    assert renderer.render(STANDING, PARENTS, [NoteMark((0.5, 1.5, 0.0), 64)], out=buffer) is buffer
    assert np.array_equal(buffer, fresh)
    kept = fresh.copy()
    renderer.render(STANDING + [0.3, 0.0, 0.0], PARENTS, out=buffer)
    assert np.array_equal(fresh, kept) and not np.array_equal(buffer, fresh)


@pytest.mark.gl
def test_the_frame_loop_allocates_nothing_frame_sized(renderer):
    """Into a kept buffer, ten frames of a moving body allocate at their peak (numpy and Python,
    as tracemalloc sees them) less than one 160×120 frame: only small per-instance temporaries
    (~25 KB here, whatever the frame size); the meshes stay uploaded, the instance rows and the
    read-back buffer are reused."""
    buffer = np.empty((120, 160, 3), np.uint8)
    renderer.render(STANDING, PARENTS, out=buffer)
    tracemalloc.start()
    try:
        for i in range(10):
            renderer.render(STANDING + [0.01 * i, 0.0, 0.0], PARENTS, [NoteMark((0.5, 1.5, 0.0), 60 + i)], out=buffer)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < buffer.nbytes


@pytest.mark.gl
def test_more_instances_than_reserved_are_all_drawn(renderer):
    """A crowd beyond the instance buffer's first capacity grows it and still draws everyone."""
    crowd = np.concatenate([STANDING * 0.3 + [dx, 0.7, 0.0] for dx in np.linspace(-1.2, 1.2, 30)])
    parents = np.concatenate([np.where(PARENTS >= 0, PARENTS + 11 * k, -1) for k in range(30)])
    _, depth = renderer.render_with_depth(crowd, parents)
    columns = np.flatnonzero((depth > 0).any(axis=0))
    assert len(crowd) > 256 and columns.min() < 30 and columns.max() > 130


@pytest.mark.gl
def test_bad_pose_shapes_are_refused(renderer):
    with pytest.raises(ValueError, match=r"positions \(J, 3\) and parents \(J,\)"):
        renderer.render(STANDING[:, :2], PARENTS)


@pytest.mark.gl
@pytest.mark.parametrize("follow", [False, True])
def test_a_pose_with_a_nan_joint_does_not_blind_the_camera_for_the_frames_after_it(follow):
    """The camera is framed on the first body drawn (and, following, anchored on its roots): one
    NaN joint there made it NaN, and every later frame the background alone."""
    try:
        renderer = BodyRenderer(160, 120, follow=follow)
    except RenderUnavailable as exc:
        pytest.skip(f"no GL platform: {exc}")
    with renderer:
        broken = STANDING.copy()
        broken[0, 0] = np.nan  # the root: the anchor a following camera moves from
        renderer.render(broken, PARENTS)
        assert np.isfinite(renderer.camera_pose).all()
        with BodyRenderer(160, 120, follow=follow) as fresh:
            np.testing.assert_array_equal(renderer.render(STANDING, PARENTS), fresh.render(STANDING, PARENTS))


@pytest.mark.gl
def test_a_crowd_over_a_floor_is_seen_from_above_and_every_one_of_it_is_drawn():
    """Fifteen room markers (creatures/room/stage.py: a 0.6 m post, an arm to the heading) over a
    12 × 8 m floor in a 320 × 240 frame: seen from the front, 10° up, they stood in one line,
    their 2.5 cm bones under a pixel. Each is drawn where it stands, apart from the others."""
    from creatures.room.stage import MARKER, MARKER_PARENTS

    rng = np.random.default_rng(5)
    at = np.column_stack([rng.uniform(0.0, 12.0, 15), np.zeros(15), rng.uniform(-8.0, 0.0, 15)])
    positions = np.concatenate([MARKER + p for p in at])
    parents = np.concatenate([MARKER_PARENTS + 3 * i * (MARKER_PARENTS >= 0) for i in range(15)])
    try:
        renderer = BodyRenderer(320, 240)
    except RenderUnavailable as exc:
        pytest.skip(f"no GL platform: {exc}")
    with renderer:
        _, depth = renderer.render_with_depth(positions, parents)
        assert renderer.camera_pose[1, 3] > 5.0  # above the floor, looking down
        view = np.linalg.inv(renderer.camera_pose)
        seen = []
        for p in at:  # each post's foot, projected: something is drawn within 3 px of it
            x, y, z, _ = view @ np.r_[p, 1.0]
            f = 120 / np.tan(BodyRenderer.YFOV / 2)
            u, v = int(round(160 + f * x / -z)), int(round(120 - f * y / -z))
            seen.append(bool((depth[max(v - 3, 0):v + 4, max(u - 3, 0):u + 4] > 0).any()))
        assert all(seen)
        assert (depth > 0).sum() > 15 * 12  # each a few pixels wide, not a hairline


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


def test_frames_of_a_clock_gap_are_skipped_not_written_again_and_again(clock):
    """A machine suspended for a night: one frame falls due on waking, the gap's are counted
    as skipped (the drawing process wrote the last picture once per frame of the night)."""
    frames = FrameClock(12.0, clock)
    assert frames.due() == 1
    clock.advance(8 * 3600.0)
    assert frames.due() == 1 and frames.skipped == 8 * 3600 * 12 - 1
    clock.advance(0.25)  # and on at the frame rate from there
    assert frames.due() == 3 and frames.skipped == 8 * 3600 * 12 - 1
    assert frames.emitted == 8 * 3600 * 12 + 4  # frame numbers keep to the clock: no drift after it


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


def test_without_a_video_encoder_the_writer_says_so_before_writing_anything(tmp_path, no_video_encoder):
    """imageio looks for ffmpeg at the first frame: a run asked for a video died there with a
    traceback (its RuntimeError, or a FileNotFoundError naming only the missing program)."""
    with pytest.raises(VideoUnavailable) as caught:
        FrameWriter(directory=tmp_path / "png", video=tmp_path / "body.mp4", fps=10)
    said = str(caught.value)
    assert said.startswith("cannot write body.mp4: no video encoder") and "ffmpeg" in said.lower()
    assert isinstance(caught.value, OSError)  # what the commands say in a line and exit 2 on
    assert not any(tmp_path.iterdir())


@pytest.mark.gl
def test_a_run_without_a_video_encoder_draws_its_frames_and_says_why_no_video(tmp_path, clock, no_video_encoder):
    from creatures.runtime.bodies import BodyFrames
    from creatures.runtime.schema import OutputSection

    messages: list[str] = []
    frames = BodyFrames(OutputSection(frames=True, video=True, width=32, height=24, fps=10.0), tmp_path, clock,
                        messages)
    if frames.renderer is None:
        pytest.skip(messages[0])
    frames.paint((STANDING, PARENTS, []), 2)
    frames.close()
    assert len(messages) == 1 and messages[0].startswith("no video: ") and "out.mp4" in messages[0]
    assert frames.writer.video is None and len(list((tmp_path / "frames").glob("frame_*.png"))) == 2
    assert not (tmp_path / "out.mp4").exists()


def test_a_video_of_odd_size_is_padded_to_even_not_rescaled(tmp_path, caplog):
    """H.264 needs even sizes: 201×301 frames make a 202×302 video, the picture unscaled."""
    frame = np.zeros((301, 201, 3), dtype=np.uint8)
    frame[:, 100:] = 255  # a vertical edge, which a rescale would move
    with FrameWriter(video=tmp_path / "odd.mp4", fps=10) as writer:
        writer.write(frame, repeat=2)
    with imageio_v2.get_reader(tmp_path / "odd.mp4") as video:
        decoded = [f for f in video]
    assert len(decoded) == 2 and decoded[0].shape == (302, 202, 3)
    row = decoded[0][150, :, 0].astype(int)
    assert row[:98].max() < 40 and row[102:].min() > 215  # the edge stays at column 100
    assert "macro_block_size" not in caplog.text  # imageio resized with a logged warning


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
