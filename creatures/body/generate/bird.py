"""A small bird: 24 joints and four clips — perch, peck, flap and hop (with root motion).

The second shipped body beside the dog (issue 16). Its beak is the end-effector that strikes
notes: a peck brings it to the ground in front of the feet. The hop is the root-motion clip:
both feet planted, a crouch, a flight of 0.12 m with the feet off the ground, a landing; the
planted feet are solved by :func:`~creatures.body.generate.rig.planar_leg` so they stay put.
"""

from __future__ import annotations

import math

import numpy as np

from creatures.body.generate.rig import FPS, X, Z, Clip, Frame, Rig, planar_leg, smooth
from creatures.motor.pose import LOW_ENERGY
from creatures.motor.skeleton import Skeleton

THIGH, SHIN, FOOT = 0.05, 0.06, 0.03
"""Leg bones: hip to knee, knee to ankle, ankle to foot (metres)."""
HOP = 0.12
"""Metres one hop travels."""


def skeleton() -> Skeleton:
    r = Rig()
    r.chain(None, ("pelvis", (0.0, 0.0, 0.0)), ("chest", (0.0, 0.02, 0.06)), ("neck", (0.0, 0.04, 0.03)),
            ("head", (0.0, 0.04, 0.01)), ("beak", (0.0, 0.0, 0.02)), ("beak_end", (0.0, -0.005, 0.03)))
    r.chain("pelvis", ("tail", (0.0, 0.01, -0.04)), ("tail_end", (0.0, -0.01, -0.07)))
    for side, x in (("l", 0.025), ("r", -0.025)):
        r.chain("chest", (f"shoulder_{side}", (x, 0.02, 0.0)), (f"wing_{side}", (np.sign(x) * 0.05, 0.0, -0.02)),
                (f"wing_{side}_end", (np.sign(x) * 0.06, 0.0, -0.04)))
        r.chain("pelvis", (f"hip_{side}", (x * 0.6, -0.01, 0.0)), (f"knee_{side}", (0.0, -THIGH, 0.0)),
                (f"ankle_{side}", (0.0, -SHIN, 0.0)), (f"foot_{side}", (0.0, -FOOT, 0.0)),
                (f"foot_{side}_end", (0.0, 0.0, 0.03)))
    return r.skeleton()


def frame(sk: Skeleton, *, z: float, height: float, pitch: float, bow: float, flap: float,
          feet: float, lift: float = 0.0) -> Frame:
    """A pose: body at ``height`` and ``z``, leaning ``pitch``, head bowed ``bow`` (a peck),
    wings raised ``flap`` (0 folded … 1 up), feet at world z ``feet``, ``lift`` off the ground."""
    f = Frame(root=np.array([0.0, height, z]))
    f.pitch("pelvis", pitch)
    f.pitch("neck", 1.2 * bow - 0.3 * pitch)
    f.pitch("head", 0.6 * bow)
    f.pitch("tail", -0.3 * pitch)
    for side, sign in (("l", 1.0), ("r", -1.0)):
        f.turn(f"shoulder_{side}", Z, sign * 1.4 * flap)
        f.turn(f"wing_{side}", Z, sign * 0.6 * flap)
        hip = np.array([height - 0.01 * math.cos(pitch), z])
        w1, w2 = planar_leg(hip, np.array([FOOT + lift, feet]), THIGH, SHIN, 1.0)
        f.pitch(f"hip_{side}", w1 - pitch)
        f.pitch(f"knee_{side}", w2 - w1)
        f.pitch(f"ankle_{side}", -w2)
        f.turn(f"foot_{side}", X, 0.0)
    return f


def _frames(seconds: float) -> np.ndarray:
    return np.arange(int(round(seconds * FPS)) + 1) / FPS


STANDING = 0.12
"""Height of the pelvis on a perch (legs a little bent)."""


def clips(sk: Skeleton) -> list[Clip]:
    """perch, peck, flap, hop."""
    still = dict(z=0.0, height=STANDING, pitch=-0.2, bow=0.0, flap=0.0, feet=0.0)
    perch = Clip("perch", [frame(sk, **dict(still, bow=0.05 * math.sin(math.pi * t))) for t in _frames(2.0)])
    perch.label("perch", range(len(perch.frames)))
    perch.label(LOW_ENERGY, range(len(perch.frames)))
    times = _frames(1.2)
    down = smooth(times / 0.5) - smooth((times - 0.6) / 0.6)
    peck = Clip("peck", [frame(sk, **dict(still, pitch=-0.2 + 0.7 * d, bow=1.1 * d, height=STANDING - 0.02 * d))
                         for d in down])
    peck.label("peck", [int(np.argmax(down))])
    peck.label("perch", [0, len(times) - 1])
    times = _frames(1.6)
    beat = np.sin(2.0 * math.pi * 3.0 * times / 1.6) * smooth(times / 0.2) * smooth((1.6 - times) / 0.2)
    flap = Clip("flap", [frame(sk, **dict(still, flap=0.5 + 0.5 * b, pitch=-0.4)) for b in beat])
    flap.label("flap", range(3, len(times) - 3))
    times = _frames(1.0)
    hop_frames = []
    for t in times:
        crouch = math.sin(math.pi * min(t / 0.3, 1.0)) * (t < 0.3) + math.sin(math.pi * max(t - 0.7, 0.0) / 0.3) * (t > 0.7)
        air = min(max((t - 0.3) / 0.4, 0.0), 1.0)
        z = HOP * float(smooth(air))
        height = STANDING - 0.03 * crouch + 0.06 * math.sin(math.pi * air)
        # The feet fly with the body and leave and meet the ground steeply (√ of a sine arc).
        hop_frames.append(frame(sk, z=z, height=height, pitch=-0.2, bow=0.0, flap=0.4 * math.sin(math.pi * air),
                                feet=z, lift=0.04 * math.sqrt(math.sin(math.pi * air))))
    hop = Clip("hop", hop_frames, root_motion=True)
    hop.label("hop", range(len(times)))
    # Standing, crouched, the top of the flight, crouched on landing: the last frame is the first
    # again (in place), so a motor program hops on by getting to each in turn ("hop 1" … "hop 4").
    last = len(times) - 1
    for k, at in enumerate((0.0, 0.15, 0.5, 0.85)):
        hop.label(f"hop {k + 1}", [int(round(at * FPS))] + ([last] if at == 0.0 else []))
    return [perch, peck, flap, hop]


ABOUT = """The shipped bird (creatures/body/generate/bird.py): perch, peck (the beak to the ground),
flap, hop (root motion); "low energy" marks the perch."""
