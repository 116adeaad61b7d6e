"""A filter goes on under the id its track was merged into (``ObstacleFusion._continued``).

The front end merges two ids into one (``FrontEnd._merge_gids``: a stereo association, a box lending
or handing its id, a fold) and reports the dropped id lost once with ``attributes["merged_into"]``.
When the dropped id's filter was ranged more recently than the kept id's (or the kept id has no
filter), the dropped id's filter carries on under the kept id, so the merge keeps the range and the
velocity it had (stereo_flying's near drone at frame 68: the box's id, bounds only, took the feature
track that ranged the drone; before, the drone's last ranged report was lost).

Closed-form scene: a 0.30 m stereo pair flying forward at 2 m/s; a compact static cluster of six
corners 4 m ahead and 0.8 m aside, listed by both cameras as track 9 for frames 0-14 (stereo ranges
it); at frame 15 the front end reports it under id 5, a new id, with one camera and ONE corner
(corner 5, the one 9's range was measured on; a single feature ranges nothing at once), and reports
9 lost, merged into 5. The truth is the cluster's centre, written here.
"""

from __future__ import annotations

import numpy as np
import pytest

from estimators.cameras import Equidistant
from estimators.egomotion import ConstantVelocity
from estimators.errors import InputError
from estimators.fusion import FusionSettings, ObstacleFusion
from estimators.records import CameraView, ObstacleObservation
from estimators.rig import stereo_forward_rig
from tests.estimators.fusion_helpers import exact_bearing

MODEL = Equidistant.from_deg_per_px(0.15, 1280, 1280)
FPS = 30.0
OFFSETS = 0.1 * np.array([[0, 0.6, 0.5], [0, -0.6, 0.5], [0.3, 0, -0.6], [-0.3, 0.5, 0], [0, 0, 0.8],
                          [0.2, -0.4, -0.3]])
CENTRE = np.array([4.0, 0.8, 0.2])


def _before_merge():
    """The fusion after frames 0-14 of the scene above (id 9 seen by both cameras with its 6 member
    corners), and what frame 15 needs: the rig, the ego-motion, the corners."""
    rig = stereo_forward_rig(MODEL, 0.30)
    ego = ConstantVelocity(2.0)
    fus = ObstacleFusion(rig, ego, FusionSettings())
    pts = CENTRE + OFFSETS
    for k in range(15):
        t = k / FPS
        T_W_B = ego.pose_at(t)
        views = tuple(
            CameraView(c.name, exact_bearing(c, T_W_B, CENTRE), [0, 0], 1e-3, feature_ids=np.arange(6),
                       feature_b_C=np.array([exact_bearing(c, T_W_B, q) for q in pts]))
            for c in rig)
        fus.step([ObstacleObservation(9, k, t, "confirmed", views)], k, t)
    return fus, rig, ego, pts


def _merge_obs(rig, ego, pts, corners, merged_into: bool, t_5: float | None = None):
    """Frame 15's observations (id 5's, 9's): id 5 seen by cam0 with ``corners`` of 9's members at
    frame 15's time (or ``t_5``), and 9 lost (``merged_into`` 5 or not)."""
    t = 15 / FPS
    c = rig["cam0"]
    T_W_B = ego.pose_at(t)
    view = CameraView(c.name, exact_bearing(c, T_W_B, CENTRE), [0, 0], 1e-3, feature_ids=np.array(corners),
                      feature_b_C=np.array([exact_bearing(c, T_W_B, pts[i]) for i in corners]))
    into = {"merged_into": 5} if merged_into else {}
    return (ObstacleObservation(5, 15, t if t_5 is None else t_5, "confirmed", (view,)),
            ObstacleObservation(9, 15, t, "lost", (), attributes=into))


def _merge_frame(merged_into: bool, corners=(5,)):
    """The reports of frame 15 (the merge) of the scene above (id 5 with ``corners`` of 9's members)."""
    fus, rig, ego, pts = _before_merge()
    reps = fus.step(list(_merge_obs(rig, ego, pts, corners, merged_into)), 15, 15 / FPS)
    r_true = float(np.linalg.norm(CENTRE - ego.pose_at(15 / FPS).t))
    return {r.id: r for r in reps}, r_true


def test_the_merged_ids_filter_goes_on_under_the_kept_id():
    """9 is reported lost once; 5's report is 9's filter carried on: ranged, within 3 sigma (+1 %)
    of the true range and within 5 % of it. Without ``merged_into`` 5 is a new filter: unranged."""
    reps, r_true = _merge_frame(True)
    assert reps[9].status == "lost"
    r5 = reps[5]
    assert r5.range_m is not None and abs(r5.range_m - r_true) <= 3 * r5.range_sigma_m + 0.01 * r_true
    assert abs(r5.range_m - r_true) < 0.05 * r_true
    reps, _ = _merge_frame(False)
    assert reps[9].status == "lost" and reps[5].range_m is None


def test_the_continued_filter_keeps_its_members_and_is_not_restarted():
    """Id 5 reported with two of 9's member corners (4 and 5): the continued filter's members are the
    same features, now under 5 (the previous frame's members re-owned), so the member-replacement
    check (``_member_resets``: 2 or more member rays now and then) does not restart it: still ranged,
    as above (fails without the re-owning: all its members counted new, the filter restarted)."""
    reps, r_true = _merge_frame(True, corners=(4, 5))
    r5 = reps[5]
    assert r5.range_m is not None and abs(r5.range_m - r_true) < 0.05 * r_true


def test_a_frame_with_a_bad_observation_changes_no_filter():
    """The observations are all checked before any filter changes: a frame whose merged id's lost report
    comes before an observation with another frame's time is an InputError that ends and re-keys
    nothing (9 still ranged under its own id), so the corrected frame continues 9's filter under 5
    (before, the failed frame had already ended 9 and moved its filter)."""
    fus, rig, ego, pts = _before_merge()
    t = 15 / FPS
    bad5, lost9 = _merge_obs(rig, ego, pts, (5,), True, t_5=t + 0.01)
    with pytest.raises(InputError, match="track 5 has t_s"):
        fus.step([lost9, bad5], 15, t)
    assert set(fus._tracks) == {9} and fus._tracks[9].id == 9
    obs5, lost9 = _merge_obs(rig, ego, pts, (5,), True)
    reps = {r.id: r for r in fus.step([lost9, obs5], 15, t)}
    assert reps[9].status == "lost" and reps[5].range_m is not None
