"""An obstacle whose every track coasts is revived by a track born in another tracker where it was
predicted (issue 4: a lost track re-born under a new id; FrontEnd._revive_across).
heldout_stereo_flying frame 28 by hand: cam0's box on the drone coasting, ORB's new track on it in
cam1 takes the box's id; refused when the newborn lies off the box's reach, when two newborns (or
two coasting obstacles) could be the one, and for an id never reported. The expected ids are the
hand-set ones, not values computed by the code under test."""

from __future__ import annotations

import numpy as np

from estimators.rig import stereo_forward_rig
from tests.trackers.conftest import equidistant, rot_axis
from trackers.frontend import FrontEnd
from trackers.grouping import ObstacleTrack

NONE = np.zeros(0, np.int64)


def _drone(off_deg: float = 0.0, extra_born_deg: float | None = None, reported: bool = True,
           range_m: float = 10.0):
    """A stereo rig (0.3 m baseline); obstacle ``range_m`` ahead (the two cameras' bearings 1.7 deg
    apart at 10 m): cam0's box track 10 (reported, seen 5
    frames, sigma 0.5 deg: reach 1.5 + 3 deg gate) coasting; in cam1 ORB's track 20 first seen this
    frame on the obstacle (turned ``off_deg`` about the vertical), and optionally a second newborn
    21 at ``extra_born_deg``. Returns (front end, this frame's seen tracks by camera)."""
    rig = stereo_forward_rig(equidistant(), baseline_m=0.3)
    fe = FrontEnd(rig, detector="orb+navlights")
    p_B = np.array([range_m, 0.0, 0.0])  # ahead (FLU)

    def bearing(cam, deg=0.0):
        c = rig[cam]
        p_C = c.T_C_B.apply(p_B)
        b = rot_axis([0, 1, 0], np.radians(deg)) @ (p_C / np.linalg.norm(p_C))
        return b / np.linalg.norm(b)

    box = ObstacleTrack(10, "cam0", NONE, bearing("cam0"), sigma_rad=np.radians(0.5), status="confirmed",
                        hits=5, label="drone")
    box.seen = False
    box.missed = 9
    fe.boxers["cam0"].tracks[10] = box
    born = [ObstacleTrack(20, "cam1", np.arange(3), bearing("cam1", off_deg), sigma_rad=0.002)]
    if extra_born_deg is not None:
        b21 = bearing("cam1", extra_born_deg)
        born.append(ObstacleTrack(21, "cam1", np.arange(3, 6), b21, sigma_rad=0.002))
    for t in born:
        fe.groupers["cam1"].tracks[t.id] = t
    if reported:
        fe._reported.add(10)
    return fe, {"cam0": [], "cam1": born}


def test_a_newborn_in_the_other_camera_takes_the_coasting_obstacles_id():
    """cam1's newborn 20 on the drone takes id 10 (before: reported under 20, an id switch); nothing
    is absorbed (20 was never reported); the next frame, 10 seen again, nothing more happens."""
    fe, seen = _drone()
    absorbed: list[int] = []
    fe._revive_across(seen, absorbed)
    assert fe._global(20) == 10 and absorbed == []
    seen["cam1"][0].hits = 2
    fe._revive_across(seen, absorbed)
    assert fe._global(20) == 10 and absorbed == []


def test_no_revival_off_the_reach_with_two_candidates_or_for_an_unreported_id():
    """Refused: the newborn 6 deg off the box's bearing (reach 4.5 deg); two newborns on it (0 and 1
    deg: ambiguous); the coasting box's id never reported; the box seen this frame; the obstacle 3 m
    ahead (the bearings from the two cameras 5.7 deg apart: the rule allows no parallax beyond the
    reach)."""
    for kw in ({"off_deg": 6.0}, {"extra_born_deg": 1.0}, {"reported": False}, {"range_m": 3.0}):
        fe, seen = _drone(**kw)
        fe._revive_across(seen, [])
        assert fe._global(20) == 20, kw
    fe, seen = _drone()
    fe.boxers["cam0"].tracks[10].seen = True
    fe._revive_across(seen, [])
    assert fe._global(20) == 20


def test_two_coasting_obstacles_at_the_newborn_revive_neither():
    """A second coasting box (cam0 12, reported) 1 deg from the first: the newborn could be either."""
    fe, seen = _drone()
    b = fe.boxers["cam0"].tracks[10]
    other = ObstacleTrack(12, "cam0", NONE, rot_axis([1, 0, 0], np.radians(1.0)) @ b.b_C,
                          sigma_rad=b.sigma_rad, status="confirmed", hits=5, label="drone")
    other.seen = False
    fe.boxers["cam0"].tracks[12] = other
    fe._reported.add(12)
    fe._revive_across(seen, [])
    assert fe._global(20) == 20


def test_two_feature_tracks_are_left_to_the_stereo_association():
    """The coasting track a feature track of cam0 (not a box): cam1's newborn feature track keeps its
    id (two feature tracks of two cameras are linked by the features they share, ``_associate``)."""
    fe, seen = _drone()
    box = fe.boxers["cam0"].tracks.pop(10)
    feat = ObstacleTrack(10, "cam0", NONE, box.b_C, sigma_rad=0.002, status="confirmed", hits=5)
    feat.seen = False
    fe.groupers["cam0"].tracks[10] = feat
    for gr in fe.groupers.values():
        gr.link_rad = np.radians(5.0)  # (set at a grouper's first update)
    fe._revive_across(seen, [])
    assert fe._global(20) == 20
