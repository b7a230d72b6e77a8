"""What creatures in a room see and hear, and where their sound comes from (issue 21)."""

from __future__ import annotations

import numpy as np
import pytest

from creatures.room.hearing import SPEED_OF_SOUND, DistanceLaw, Masking, arrive, db_velocity, velocity_db
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
    ear = [loud, quiet, later, far_pitch]
    heard = [Masking(margin=20.0, band=12.0).stands_out(a, ear) for a in ear]
    assert heard == [True, False, True, True]
    assert Masking(threshold=-30.0).stands_out(later, [later]) is False  # below the threshold of hearing


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
