"""Quaternion maths of the motor system (thesis appendix "(quaternions)")."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.spatial.transform import Rotation

from creatures.motor import quaternion as quat
from creatures.motor.skeleton import Skeleton

finite = st.floats(-1.0, 1.0, allow_nan=False, allow_infinity=False)
raw_quaternion = arrays(np.float64, (4,), elements=finite).filter(lambda q: np.linalg.norm(q) > 0.1)
unit = raw_quaternion.map(quat.normalize)
alpha = st.floats(0.0, 1.0)


def to_scipy(q: np.ndarray) -> Rotation:
    return Rotation.from_quat(np.asarray(q)[..., [1, 2, 3, 0]])


@given(raw_quaternion, raw_quaternion, alpha)
def test_products_and_slerps_stay_unit(a, b, t):
    a, b = quat.normalize(a), quat.normalize(b)
    assert np.isclose(np.linalg.norm(quat.multiply(a, b)), 1.0)
    assert np.isclose(np.linalg.norm(quat.slerp(a, b, t)), 1.0)


@given(unit, unit)
def test_multiply_and_rotate_agree_with_scipy(a, b):
    product = quat.multiply(a, b)
    expected = (to_scipy(a) * to_scipy(b)).as_quat()[[3, 0, 1, 2]]
    assert quat.distance(product, expected) < 1e-9
    v = np.array([0.3, -1.2, 0.7])
    assert np.allclose(quat.rotate(a, v), to_scipy(a).apply(v), atol=1e-9)


@given(unit, unit)
def test_slerp_endpoints(a, b):
    assert quat.distance(quat.slerp(a, b, 0.0), a) < 1e-9
    assert quat.distance(quat.slerp(a, b, 1.0), b) < 1e-9


@given(unit, unit, alpha)
def test_slerp_takes_the_shortest_path(a, b, t):
    # Whichever sign b is given, slerp moves along the short arc: the angle covered
    # from a is t times the (at most half-turn) angle between them.
    total = quat.angle_between(a, b)
    for target in (b, -b):
        q = quat.slerp(a, target, t)
        assert np.isclose(quat.angle_between(a, q), t * total, atol=1e-6)
        assert np.isclose(quat.angle_between(q, b), (1 - t) * total, atol=1e-6)


@given(unit, unit)
def test_distance_is_sign_blind_and_bounded(a, b):
    assert quat.distance(a, -a) < 1e-12
    d = quat.distance(a, b)
    assert 0.0 <= d <= 1.0
    assert np.isclose(d, quat.distance(a, -b))


@given(unit, unit, st.floats(0.05, 0.95))
def test_closest_approach_recovers_points_on_the_arc(a, b, t):
    if quat.angle_between(a, b) < 1e-2:
        return
    p = quat.slerp(a, b, t)
    assert np.isclose(quat.closest_approach(a, b, p), t, atol=1e-6)


@settings(max_examples=50)
@given(unit, unit, unit)
def test_closest_approach_minimises_the_distance(a, b, p):
    if quat.angle_between(a, b) < 1e-2:
        return
    best = quat.closest_approach(a, b, p)
    grid = np.linspace(best - 2.0, best + 2.0, 2001)
    distances = quat.distance(quat.slerp(a, b, grid), p)
    assert quat.distance(quat.slerp(a, b, best), p) <= distances.min() + 1e-9


keyframes = arrays(np.float64, (5, 4), elements=finite).filter(lambda q: np.all(np.linalg.norm(q, axis=1) > 0.1))


@given(keyframes)
def test_squad_passes_through_keys_and_is_continuous(raw):
    keys = quat.hemisphere_align(quat.normalize(raw))
    controls = quat.squad_controls(keys)
    for i in range(len(keys) - 1):
        start = quat.squad(keys[i], keys[i + 1], controls[i], controls[i + 1], 0.0)
        end = quat.squad(keys[i], keys[i + 1], controls[i], controls[i + 1], 1.0)
        assert quat.distance(start, keys[i]) < 1e-9
        assert quat.distance(end, keys[i + 1]) < 1e-9
    # Tangent continuity at interior keys: the one-sided rates of change match.
    h = 1e-5
    for i in range(1, len(keys) - 1):
        if min(quat.angle_between(keys[i - 1], keys[i]), quat.angle_between(keys[i], keys[i + 1])) < 0.05:
            continue
        before = quat.squad(keys[i - 1], keys[i], controls[i - 1], controls[i], 1.0 - h)
        after = quat.squad(keys[i], keys[i + 1], controls[i], controls[i + 1], h)
        rate_in = quat.log(quat.multiply(keys[i], quat.conjugate(before))) / h
        rate_out = quat.log(quat.multiply(after, quat.conjugate(keys[i]))) / h
        # The segments have unit parameter length each, so matching rates = C1 in parameter.
        assert np.allclose(rate_in, rate_out, atol=1e-3 * (1 + np.abs(rate_in).max()))


signs = arrays(np.float64, (5,), elements=st.sampled_from([-1.0, 1.0]))


@given(keyframes, signs, alpha)
def test_squad_stays_unit(raw, flips, t):
    keys = quat.normalize(raw) * flips[:, None]
    controls = quat.squad_controls(keys)
    for i in range(len(keys) - 1):
        q = quat.squad(keys[i], keys[i + 1], controls[i], controls[i + 1], t)
        assert np.isclose(np.linalg.norm(q), 1.0)


@given(keyframes, signs, alpha)
def test_squad_takes_the_shortest_path(raw, flips, t):
    # q and −q are one rotation: the signs keys arrive with (e.g. straight from the graph's
    # nodes) must not send playback the long way round.
    keys = quat.normalize(raw)
    flipped = keys * flips[:, None]
    controls, flipped_controls = quat.squad_controls(keys), quat.squad_controls(flipped)
    for i in range(len(keys) - 1):
        q = quat.squad(keys[i], keys[i + 1], controls[i], controls[i + 1], t)
        p = quat.squad(flipped[i], flipped[i + 1], flipped_controls[i], flipped_controls[i + 1], t)
        assert quat.angle_between(p, q) < 1e-6
    # Unbent (controls at the keys), squad is slerp along the short arc, at constant speed.
    a, b = keys[0], keys[1] * flips[1]
    q = quat.squad(a, b, a, b, t)
    total = quat.angle_between(a, b)
    assert np.isclose(quat.angle_between(a, q), t * total, atol=1e-6)
    assert np.isclose(quat.angle_between(q, b), (1 - t) * total, atol=1e-6)


@given(keyframes)
def test_squad_rate_bounds_the_turn_of_each_segment(raw):
    keys = quat.hemisphere_align(quat.normalize(raw))
    controls = quat.squad_controls(keys)
    rate = quat.squad_rate(keys[:-1], keys[1:], controls[:-1], controls[1:])
    # A segment covers at least its straight angle in unit time, so its peak rate is no less.
    # (arccos near 1 resolves angles to ~1e-8 rad; the rate sums 16 of them.)
    straight = quat.angle_between(keys[:-1], keys[1:])
    assert np.all(rate >= straight - 1e-6)
    # Unbent, the rate is constant: exactly that angle.
    assert np.allclose(quat.squad_rate(keys[:-1], keys[1:], keys[:-1], keys[1:]), straight, atol=1e-6)


@settings(max_examples=300)
@given(keyframes, keyframes, arrays(np.float64, (5, 3), elements=st.floats(-0.6, 0.6)))
def test_squad_rate_bound_is_never_below_the_rate(raw, raw_controls, nudges):
    # squad_controls', controls near the keys (where the bound is finite) and any at all.
    keys = quat.normalize(raw)
    for controls in (quat.squad_controls(keys), quat.multiply(keys, quat.exp(nudges)), quat.normalize(raw_controls)):
        rate = quat.squad_rate(keys[:-1], keys[1:], controls[:-1], controls[1:], samples=64)
        # arccos near 1 resolves a step to ~3e-8 rad and the rate is a step times 64: a
        # segment that does not turn at all can read ~2e-6 (keys all (1, 1, 1, 1) did).
        assert np.all(rate <= quat.squad_rate_bound(keys[:-1], keys[1:], controls[:-1], controls[1:]) + 5e-6)


@given(unit)
def test_log_and_exp_are_inverse(q):
    assert quat.distance(quat.exp(quat.log(q)), q) < 1e-9


def test_forward_kinematics_of_a_bent_arm_and_its_batch():
    skeleton = Skeleton.from_dict(
        {
            "joints": [
                {"name": "root", "offset": [0, 0, 0]},
                {"name": "upper", "parent": "root", "offset": [0, 1, 0]},
                {"name": "hand", "parent": "upper", "offset": [0, 1, 0]},
            ],
            "end_effectors": ["hand"],
        }
    )
    rotations = quat.identity((3,))
    rotations[1] = quat.from_axis_angle(np.array([0, 0, 1.0]), np.pi / 2)
    positions = skeleton.forward_kinematics(rotations, np.array([1.0, 0, 0]))
    assert np.allclose(positions, [[1, 0, 0], [1, 1, 0], [0, 1, 0]])
    batch = skeleton.forward_kinematics(np.stack([rotations, quat.identity((3,))]), np.zeros((2, 3)))
    assert batch.shape == (2, 3, 3)
    assert np.allclose(batch[1], [[0, 0, 0], [0, 1, 0], [0, 2, 0]])
    assert np.allclose(skeleton.masses, [3, 2, 1])  # default: joints moved (subtree size)
