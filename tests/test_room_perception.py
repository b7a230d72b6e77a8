"""What creatures in a room see and hear, and where their sound comes from (issue 21)."""

from __future__ import annotations

import numpy as np
import pytest

from creatures.room.hearing import SPEED_OF_SOUND, DistanceLaw, Ears, Masking, arrive, db_velocity, velocity_db
from creatures.room.space import Obstacle, Room
from creatures.room.speakers import DOME, Dome, azimuth, direction, ring, stereo, vbap
from creatures.room.vision import visible

ROOM = Room(10, 10, (Obstacle(5.0, 5.0, 0.5),))


def test_an_obstacle_hides_what_is_behind_it():
    eye, heading = np.array([[2.0, 5.0]]), np.array([[1.0, 0.0]])
    things = np.array([[8.0, 5.0], [8.0, 7.0], [4.0, 5.0]])  # behind the pillar, beside it, before it
    assert visible(eye, heading, things, ROOM, fov=120, range_=10).tolist() == [[False, True, True]]
    assert visible(eye, heading, things, Room(10, 10), fov=120, range_=10).tolist() == [[True, True, True]]


def test_the_cone_and_range_limit_sight():
    eye, heading = np.array([[2.0, 2.0]]), np.array([[1.0, 0.0]])
    things = np.array([[4.0, 2.0], [2.0, 4.0], [0.5, 2.0], [4.0, 3.0], [9.5, 2.0]])
    # ahead; 90° left (outside a 120° cone); behind; 26.6° left (inside); ahead but 7.5 m away
    seen = visible(eye, heading, things, Room(10, 10), fov=120, range_=6.0)[0]
    assert seen.tolist() == [True, False, False, True, False]
    assert visible(eye, heading, things, Room(10, 10), fov=200, range_=6.0)[0].tolist()[1] is True


@pytest.mark.parametrize("law, db_at_4", [("inverse", -12.0412), ("inverse_square", -24.0824),
                                          ("linear", 20 * np.log10(1 - 3 / 19))])
def test_a_note_four_metres_away_arrives_attenuated_and_late(law, db_at_4):
    rule = DistanceLaw(law, reference=1.0, silent=20.0)
    a = arrive(10.0, 0.5, velocity_db(100), 60, "note", 4.0, rule)
    assert a.start == pytest.approx(10.0 + 4.0 / SPEED_OF_SOUND)
    assert a.end - a.start == pytest.approx(0.5)
    assert a.db - velocity_db(100) == pytest.approx(db_at_4, abs=1e-3)
    assert db_velocity(a.db) < 100
    near = arrive(10.0, 0.5, 0.0, 60, "note", 0.5, rule)
    assert near.db == 0.0  # inside the reference distance: no louder than at 1 m


def test_a_quiet_sound_under_a_loud_one_is_masked():
    law = DistanceLaw("inverse")
    loud = arrive(1.0, 1.0, 0.0, 60, "loud", 1.0, law)
    quiet = arrive(1.2, 0.3, -20.0, 62, "quiet", 8.0, law)  # −38 dB at the ear, during the loud one
    later = arrive(3.0, 0.3, -20.0, 62, "later", 8.0, law)  # same, after the loud one ended
    far_pitch = arrive(1.2, 0.3, -20.0, 90, "high", 8.0, law)  # 30 semitones away: another band
    heard = _hear([loud, quiet, far_pitch, later], Masking(margin=20.0, band=12.0))  # in the order they arrive
    assert heard == [True, False, True, True]
    assert _hear([later], Masking(threshold=-30.0)) == [False]  # below the threshold of hearing


def _hear(sounds: list, masking: Masking, ears: list[int] | None = None) -> list[bool]:
    """Whether each of ``sounds`` (in arrival order) stands out at its ear (all at ear 0 unless given)."""
    ear = np.zeros(len(sounds), dtype=np.int64) if ears is None else np.array(ears)
    pitch = np.array([np.nan if a.pitch is None else a.pitch for a in sounds], dtype=float)
    return Ears(int(ear.max()) + 1, masking).hear(ear, np.array([a.start for a in sounds]), np.array([a.end for a in sounds]),
                                                 np.array([a.db for a in sounds]), pitch).tolist()


def test_masking_is_per_ear_and_by_what_sounds_there_when_a_sound_begins():
    """A loud sound masks only at its own ear; a sound that ended before another began masks
    nothing (it has left the ear), an unpitched one masks every band, and a faint sound masks a
    fainter one as a loud one does a quiet one."""
    law = DistanceLaw("inverse")
    loud = arrive(1.0, 1.0, 0.0, 60, "loud", 1.0, law)
    quiet = arrive(1.2, 0.3, -20.0, 62, "quiet", 8.0, law)
    assert _hear([loud, quiet], Masking(), ears=[0, 1]) == [True, True]  # at two ears
    short = arrive(1.0, 0.1, 0.0, 60, "short", 1.0, law)
    assert _hear([short, quiet], Masking()) == [True, True]  # over before the quiet one began
    noise = arrive(1.0, 1.0, 0.0, None, "noise", 1.0, law)
    high = arrive(1.2, 0.3, -20.0, 100, "high", 8.0, law)
    assert _hear([noise, high], Masking(band=12.0)) == [True, False]
    faint = arrive(1.0, 1.0, -40.0, 60, "faint", 1.0, law)
    fainter = arrive(1.2, 0.3, -60.0, 60, "fainter", 1.0, law)  # above the threshold, 20 dB under the faint one
    assert _hear([faint, fainter], Masking(margin=20.0, threshold=-70.0)) == [True, False]
    many = [arrive(1.0 + 0.01 * k, 2.0, 0.0, 60 + k, k, 1.0, law) for k in range(12)]  # an ear's store grows
    assert _hear(many, Masking()) == [True] * 12


def test_vbap_pans_between_the_adjacent_pair_at_unit_power():
    speakers = ring(8)
    for az in (0.0, 22.5, 100.0, 359.0):
        g = vbap(az, speakers)
        assert np.sum(g ** 2) == pytest.approx(1.0)
        assert np.count_nonzero(g > 1e-9) <= 2
        # The gains' vector sum points at the source (VBAP's defining property).
        v = (g[:, None] * np.stack([np.cos(np.radians(speakers)), np.sin(np.radians(speakers))], 1)).sum(0)
        assert np.degrees(np.arctan2(v[1], v[0])) % 360 == pytest.approx(az % 360, abs=1e-6)
    assert vbap(45.0, speakers)[1] == pytest.approx(1.0)  # on a speaker: that speaker alone


def test_dome_vbap_pans_over_one_triangle_at_unit_power_pointing_at_the_source():
    dome, rng = Dome(), np.random.default_rng(5)
    for az, el in zip(rng.uniform(0, 360, 200), rng.uniform(0, 90, 200)):
        g = dome.gains(az, el)[0]
        assert np.sum(g ** 2) == pytest.approx(1.0)
        assert np.count_nonzero(g > 1e-9) <= 3
        v = g @ dome.speakers  # the gains' vector sum points at the source (VBAP's defining property)
        assert v / np.linalg.norm(v) == pytest.approx(direction(np.array(az), np.array(el)), abs=1e-9)
    assert dome.gains(0.0, 90.0)[0][12] == pytest.approx(1.0)  # overhead: the top speaker alone
    below = dome.gains(200.0, -10.0)[0]  # under ear height: the ring pair, the nadir dropped
    assert np.count_nonzero(below > 1e-9) == 2 and below[4] > 0 and below[5] > 0
    assert len(DOME) == len(dome.speakers) == 13


def test_stereo_pan_follows_position():
    listener = np.array([5.0, 0.0])
    centre = stereo(azimuth(np.array([5.0, 5.0]), listener))
    left = stereo(azimuth(np.array([2.0, 5.0]), listener))
    hard_left = stereo(azimuth(np.array([0.0, 0.0]), listener))
    behind_right = stereo(azimuth(np.array([9.0, -1.0]), listener))
    assert centre[0] == pytest.approx(centre[1])
    assert left[0] > left[1] > 0
    assert hard_left == pytest.approx([1.0, 0.0])
    assert behind_right[1] > 0.9 and np.sum(behind_right ** 2) == pytest.approx(1.0)
