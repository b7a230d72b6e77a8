"""Bodies push strings: a moving joint reshapes the string and its sound; stillness lets it ring down."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from audio.coupling import BodyControl, BodyCoupling, joint_angle, joint_distance
from audio.scanned import ScannedString, StringParameters

SR = 48000
HAPTIC_BLOCK = SR // 100  # the body updates at 100 Hz, like a behaviour tick

# A tiny three-joint arm (shoulder → elbow → hand): parents as the motor Skeleton has them.
PARENTS = np.array([-1, 0, 1])
ARM = np.array([[0.5, 1.0, 0.0], [0.5, 0.6, 0.0], [0.5, 0.3, 0.0]])


def pose(positions: np.ndarray, time: float) -> SimpleNamespace:
    return SimpleNamespace(positions=positions, parents=PARENTS, time=time)


def play(string: ScannedString, coupling: BodyCoupling, hand_y, clock, seconds: float = 1.0) -> np.ndarray:
    """Drive ``string`` with the arm whose hand sits at ``hand_y(t)``; return the audio."""
    blocks = []
    end = clock.now() + seconds
    while clock.now() < end - 1e-9:
        positions = ARM.copy()
        positions[2, 1] = hand_y(clock.now())
        string.push(coupling.forces(pose(positions, clock.now())))
        blocks.append(string.render(HAPTIC_BLOCK))
        clock.advance(HAPTIC_BLOCK / SR)
    return np.concatenate(blocks)


def make_string() -> tuple[ScannedString, BodyCoupling]:
    params = StringParameters(n_masses=64)
    coupling = BodyCoupling.along((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), params.n_masses, radius=0.1, gain=200.0)
    return ScannedString(params, sample_rate=SR, frequency=220.0), coupling


def test_hand_moving_over_a_node_bends_the_string_there(clock):
    string, coupling = make_string()
    play(string, coupling, lambda t: 0.3 - 2.0 * t, clock, seconds=0.1)  # a quick swipe down
    node = np.argmax(np.abs(string.x))
    assert abs(coupling.nodes[node, 0] - 0.5) < 0.05  # bent under the hand (x = 0.5)
    assert string.x[node] < 0  # pushed the way the hand moved (down the y axis)
    assert np.abs(string.x[:10]).max() < 0.01 * np.abs(string.x).max()  # far nodes barely moved


def harmonic_levels(audio: np.ndarray, f0: float = 220.0, count: int = 12) -> np.ndarray:
    """Levels (dB) of the first ``count`` harmonics of ``f0``: the string's timbre."""
    spectrum = np.abs(np.fft.rfft(audio * np.hanning(len(audio))))
    bins = np.round(np.arange(1, count + 1) * f0 * len(audio) / SR).astype(int)
    return 20 * np.log10(spectrum[bins] + 1e-12)


def test_a_moving_hand_changes_the_sound_of_a_plucked_string(clock):
    still_string, still_coupling = make_string()
    still_string.pluck(amplitude=0.3)
    still = play(still_string, still_coupling, lambda t: 0.3, clock)

    alone, _ = make_string()
    alone.pluck(amplitude=0.3)
    np.testing.assert_array_equal(still, alone.render(len(still)))  # stillness adds nothing

    moved_string, moved_coupling = make_string()
    moved_string.pluck(amplitude=0.3)
    moved = play(moved_string, moved_coupling, lambda t: 0.3 - 0.2 * np.sin(2 * np.pi * 3.0 * t), clock)
    change = np.abs(harmonic_levels(moved) - harmonic_levels(still))
    assert change.mean() > 3.0  # dB, averaged over the first twelve harmonics


def test_a_still_body_does_not_excite_a_resting_string(clock):
    string, coupling = make_string()
    assert not play(string, coupling, lambda t: 0.3, clock).any()


def test_still_body_leaves_a_plucked_string_to_decay(clock):
    string, coupling = make_string()
    string.pluck(amplitude=0.5)
    rms = [np.sqrt(np.mean(play(string, coupling, lambda t: 0.3, clock) ** 2)) for _ in range(3)]
    assert rms[0] > rms[1] > rms[2] > 0


def test_a_pose_at_the_same_time_pushes_nothing():
    _, coupling = make_string()
    coupling.forces(pose(ARM, 1.0))
    moved = ARM + 0.1
    assert not coupling.forces(pose(moved, 1.0)).any()


def test_body_controls_map_distance_and_angle_into_a_clamped_range():
    rib = BodyControl(joint_distance(0, 2), low=0.5, high=0.9, out_low=0.0, out_high=1.0)
    assert rib(pose(ARM, 0.0)) == pytest.approx(0.5)  # shoulder–hand 0.7 → halfway
    back = BodyControl(joint_angle(0, 1, 2), low=0.0, high=np.pi, out_low=200.0, out_high=8000.0)
    assert back(pose(ARM, 0.0)) == pytest.approx(8000.0)  # straight arm: angle π
    bent = ARM.copy()
    bent[2] = [0.8, 0.6, 0.0]
    assert back(pose(bent, 0.0)) == pytest.approx(200.0 + 0.5 * 7800.0)
    with pytest.raises(ValueError, match="low != high"):
        BodyControl(joint_distance(0, 1), low=1.0, high=1.0, out_low=0.0, out_high=1.0)
