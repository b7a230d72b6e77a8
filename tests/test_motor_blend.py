"""Blending contributions on joints and scalars (creatures/motor/blend.py; issue 17's exact tests)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from creatures.motor import quaternion as quat
from creatures.motor.blend import Blend, Contribution, Limits, Oscillator, Policy, weighted_mean
from creatures.kinds.parts import shared_graph

Z = np.array([0.0, 0.0, 1.0])


def held(value: np.ndarray):
    return lambda t: value


def about_z(degrees: float) -> np.ndarray:
    return quat.from_axis_angle(Z, math.radians(degrees))


def test_weights_3_and_1_on_0_and_45_degrees_give_11_25():
    blend = Blend(1)
    blend.start(Contribution("zero", held(about_z(0.0)[None]), weight=3.0, fade=0.0), 0.0)
    blend.start(Contribution("forty-five", held(about_z(45.0)[None]), weight=1.0, fade=0.0), 0.0)
    out = blend.resolve(1.0)[0]
    assert math.degrees(quat.angle_between(out, about_z(0.0))) == pytest.approx(11.25, abs=1e-9)
    assert math.degrees(quat.angle_between(out, about_z(45.0))) == pytest.approx(33.75, abs=1e-9)
    scalars = Blend(1, rotations=False)
    scalars.start(Contribution("a", held(np.array([0.0])), weight=3.0, fade=0.0), 0.0)
    scalars.start(Contribution("b", held(np.array([45.0])), weight=1.0, fade=0.0), 0.0)
    assert scalars.resolve(1.0)[0] == pytest.approx(11.25, abs=1e-12)


def test_priority_mode_gives_the_higher_outright():
    for rotations, low, high in ((True, about_z(10.0)[None], about_z(70.0)[None]),
                                 (False, np.array([0.2]), np.array([0.9]))):
        blend = Blend(1, rotations=rotations)
        blend.start(Contribution("base", held(low), fade=0.0), 0.0)
        blend.start(Contribution("high", held(high), Policy.EXCLUSIVE, priority=2.0, fade=0.0), 0.0)
        blend.start(Contribution("low", held(low), Policy.EXCLUSIVE, priority=1.0, fade=0.0), 0.0)
        out = blend.resolve(1.0)
        if rotations:
            assert quat.angle_between(out, high).max() < 1e-9
        else:
            assert out[0] == pytest.approx(0.9, abs=1e-12)
        blend.stop("high", 1.0)  # gone: the next priority takes over outright
        out = blend.resolve(2.0)
        assert (quat.angle_between(out, low).max() < 1e-9) if rotations else out[0] == pytest.approx(0.2)


def test_budget_is_a_truncated_running_sum_in_priority_order():
    def total(amounts: list[float], priorities: list[float]) -> float:
        blend = Blend(1, rotations=False, budget=1.0)
        for k, (a, p) in enumerate(zip(amounts, priorities)):
            blend.start(Contribution(f"c{k}", held(np.array([a])), Policy.BUDGET, priority=p, fade=0.0), 0.0)
        return float(blend.resolve(1.0)[0])

    assert total([0.7, 0.6, 0.5], [3, 2, 1]) == pytest.approx(0.7 + 0.3 + 0.0, abs=1e-12)
    assert total([0.7], [3]) == pytest.approx(0.7)  # the first takes its whole amount
    assert total([0.7, 0.6], [3, 2]) == pytest.approx(1.0)  # the second only what is left
    assert total([0.5, 0.7, 0.6], [1, 3, 2]) == pytest.approx(1.0)  # order is by priority, not arrival
    # On a joint the budget is an angle: 0.7 + 0.3 + 0 radians about one axis.
    blend = Blend(1, budget=1.0)
    for k, a in enumerate([0.7, 0.6, 0.5]):
        blend.start(Contribution(f"c{k}", held(quat.from_axis_angle(Z, a)[None]), Policy.BUDGET,
                                 priority=-k, fade=0.0), 0.0)
    assert quat.angle_between(blend.resolve(1.0)[0], quat.identity()) == pytest.approx(1.0, abs=1e-12)


def test_additive_jitter_over_a_hold_returns_exactly_with_bounded_steps():
    rng = np.random.default_rng(17)
    joints, fade, dt, amplitude, rate = 19, 0.5, 1.0 / 60.0, 0.3, 2.0 * math.pi * 1.5
    hold = quat.normalize(rng.normal(size=(joints, 4)))
    axes = rng.normal(size=(joints, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    phases = rng.uniform(0, 2 * math.pi, joints)

    def jitter(t: float) -> np.ndarray:
        return quat.exp(axes * (amplitude * np.sin(rate * t + phases))[:, None])

    blend = Blend(joints)
    blend.start(Contribution("hold", held(hold), fade=0.0), 0.0)
    times = np.arange(0.0, 4.0, dt)
    shown = []
    for t in times:
        if abs(t - 1.0) < dt / 2:
            blend.start(Contribution("jitter", jitter, Policy.ADD, fade=fade), t)
        if abs(t - 2.5) < dt / 2:
            blend.stop("jitter", t)
        shown.append(blend.resolve(t))
    shown = np.array(shown)
    moved = quat.angle_between(shown, hold).max(axis=1)
    assert moved[(times > 1.6) & (times < 2.5)].max() > 0.2  # the jitter was really there
    after = times >= 2.5 + fade
    assert np.array_equal(shown[after], np.broadcast_to(hold, shown[after].shape))  # exactly the hold
    assert "jitter" not in blend
    # The steepest crossfade (smoothstep's 1.5 / fade) on the full amplitude, plus the jitter's own rate.
    allowed = (amplitude * 1.5 / fade + amplitude * rate) * dt
    steps = quat.angle_between(shown[1:], shown[:-1]).max(axis=1)
    assert steps.max() <= allowed + 1e-9
    # Switched without a fade, the same jitter jumps further in one tick than that.
    unfaded = Blend(joints)
    unfaded.start(Contribution("hold", held(hold), fade=0.0), 0.0)
    before = unfaded.resolve(1.2)
    unfaded.start(Contribution("jitter", jitter, Policy.ADD, fade=0.0), 1.2 + dt)
    assert quat.angle_between(unfaded.resolve(1.2 + dt), before).max() > allowed


unit = st.lists(st.floats(-1, 1, allow_nan=False), min_size=4, max_size=4).filter(
    lambda v: np.linalg.norm(v) > 0.1).map(lambda v: np.asarray(v) / np.linalg.norm(v))


SAME = np.array([-0.4, -0.4, -0.7, -0.2]) / np.linalg.norm([-0.4, -0.4, -0.7, -0.2])


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(unit, st.floats(0.01, 10.0), st.booleans()), min_size=1, max_size=8))
@example([(SAME, 1.0, False), (SAME, 2.0, False)])  # two equal rotations: arccos put them 3e-8 apart
def test_quaternion_means_stay_unit_and_take_the_short_way(items):
    rotations = np.array([q for q, _, _ in items])[:, None]
    weights = np.array([w for _, w, _ in items])
    flipped = np.array([-q if flip else q for q, _, flip in items])[:, None]
    mean = weighted_mean(rotations, weights)[0]
    assert abs(np.linalg.norm(mean) - 1.0) < 1e-12
    # q and −q are one rotation: flipping signs never changes the mean (it is the short way).
    assert quat.angle_between(mean, weighted_mean(flipped, weights)[0]) < 1e-7
    if len(items) == 2:
        a, b = rotations[0, 0], rotations[1, 0]
        # On the short arc between the two, at the weighted share of it.
        share = weights[1] / weights.sum()
        assert quat.angle_between(mean, quat.slerp(a, b, share)) < 1e-7
        assert quat.angle_between(mean, a) <= quat.angle_between(a, b) + 1e-9


def test_blended_frames_keep_joint_limits_and_the_source_speed():
    graph = shared_graph()
    poses = graph.poses
    limits = Limits.of(poses, graph.timing.max_speed)
    joints, dt = poses.rotations.shape[1], 1.0 / 60.0
    rng = np.random.default_rng(300)
    for _ in range(300):
        blend = Blend(joints, budget=rng.uniform(0.1, 2.0))
        for k in range(int(rng.integers(1, 9))):
            policy = Policy(int(rng.integers(0, 4)))
            value = poses.rotations[int(rng.integers(len(poses)))] if policy in (Policy.MEAN, Policy.EXCLUSIVE) \
                else quat.exp(rng.normal(scale=rng.uniform(0.1, 2.0), size=(joints, 3)))
            mask = rng.uniform(size=joints) if rng.random() < 0.5 else None
            blend.start(Contribution(f"c{k}", held(value), policy, weight=rng.uniform(0.0, 2.0),
                                     priority=float(rng.integers(0, 4)), mask=mask, fade=rng.uniform(0.0, 0.5)),
                        rng.uniform(0.0, 0.3))
        shown = None
        for t in np.arange(0.0, 0.6, dt):
            frame = limits.apply(blend.resolve(t), shown, dt)
            assert np.all(quat.angle_between(frame, quat.identity((joints,))) <= limits.range + 1e-7)  # acos rounding near 0
            if shown is not None:
                assert quat.angle_between(frame, shown).max() <= limits.max_speed * dt + 1e-7
            assert np.allclose(np.linalg.norm(frame, axis=1), 1.0)
            shown = frame


def test_masks_confine_a_layer_and_oscillators_breathe():
    names = ("pelvis", "chest", "head")
    breath = Oscillator(names, {"chest": (1.0, 0.0, 0.0)}, period=4.0, depth=0.1)
    assert breath.mask.tolist() == [0.0, 1.0, 0.0]
    blend = Blend(3)
    blend.start(Contribution("stand", held(quat.identity((3,)))), 0.0)
    blend.start(Contribution("look", held(quat.from_axis_angle(np.tile(Z, (3, 1)), np.full(3, 0.5))),
                             Policy.EXCLUSIVE, mask=np.array([0.0, 0.0, 1.0]), fade=0.0), 0.0)
    blend.start(Contribution("breathe", breath, Policy.ADD, mask=breath.mask, fade=0.0), 0.0)
    out = blend.resolve(1.0)  # a quarter period: the chest at full depth
    assert np.array_equal(out[0], quat.identity())
    assert quat.angle_between(out[1], quat.identity()) == pytest.approx(0.1, abs=1e-12)
    assert quat.angle_between(out[2], quat.identity()) == pytest.approx(0.5, abs=1e-12)
    with pytest.raises(ValueError, match="lacks"):
        Oscillator(names, {"rib": (1.0, 0.0, 0.0)}, period=4.0, depth=0.1)
    with pytest.raises(ValueError, match="mask has shape"):
        blend.start(Contribution("bad", held(quat.identity((3,))), mask=np.ones(2)), 0.0)
    blend.start(Contribution("short", held(quat.identity((2,)))), 1.0)
    with pytest.raises(ValueError, match=r"'short' gave a value of shape \(2, 4\).*\(3, 4\)"):
        blend.resolve(1.5)


def test_a_layer_restarted_as_it_fades_out_goes_on_from_its_level():
    blend = Blend(1, rotations=False)
    layer = held(np.array([1.0]))
    blend.start(Contribution("sway", layer, Policy.ADD, fade=1.0), 0.0)
    blend.stop("sway", 5.0)
    fading = blend.resolve(5.3)[0]
    assert 0.0 < fading < 1.0
    blend.start(Contribution("sway", layer, Policy.ADD, fade=1.0), 5.3)  # its tuple starts again
    assert blend.resolve(5.3)[0] == pytest.approx(fading, abs=1e-12)  # no dip to 0
    levels = [blend.resolve(t)[0] for t in np.arange(5.3, 7.0, 0.01)]
    assert np.all(np.diff(levels) >= -1e-12) and levels[-1] == 1.0  # and eases back in
