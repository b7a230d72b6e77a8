"""The first connection (thesis, "artificial gestural control", figure 48): limbs push strings
through a motion flow field, so movement spreads, reaches farther strings later and weaker,
and lingers after the limb is still, where direct coupling reaches only its radius."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from audio.coupling import BodyCoupling
from audio.flow import FlowCoupling

NODES = np.column_stack([np.linspace(0, 1, 32), np.full(32, 1.0), np.zeros(32)])  # a string at 1 m


def pushes(kind: type, distance: float, seconds: float = 3.0) -> np.ndarray:
    """Largest force on the string each 20 ms while a hand below it rises 0.2 m in 0.1 s, then
    holds still."""
    coupling = kind(NODES, radius=0.25, gain=40.0)
    trace = []
    for k in range(int(seconds / 0.02)):
        t = k * 0.02
        y = 1.0 - distance + 0.2 * min(t / 0.1, 1.0)
        force = coupling.forces(SimpleNamespace(positions=np.array([[0.5, y, 0.0]]), time=t))
        trace.append(np.abs(force).max())
    return np.array(trace)


def test_movement_reaches_a_far_string_through_the_flow_only():
    direct, flow = pushes(BodyCoupling, 1.0), pushes(FlowCoupling, 1.0)
    assert direct.max() < 1.0 < 4.0 < flow.max()


def test_movement_spreads_later_to_farther_strings_and_lingers():
    near, far = pushes(FlowCoupling, 0.4), pushes(FlowCoupling, 1.0)
    assert far.argmax() > near.argmax()  # the farther string's push peaks later
    assert near[10:].max() > 5.0 and pushes(BodyCoupling, 0.4)[10:].max() == 0.0  # still hand: the flow lingers
    assert near[-1] < 0.01 * near.max()  # and dies away (half-life 0.5 s)


def test_a_string_in_a_still_room_is_not_pushed():
    coupling = FlowCoupling(NODES, radius=0.25, gain=40.0)
    for k in range(50):
        force = coupling.forces(SimpleNamespace(positions=np.array([[0.5, 0.6, 0.0]]), time=k * 0.02))
    assert not force.any()
