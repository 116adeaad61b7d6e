"""A two-ray mono triangulation is not reported until a further bearing has tested it.

Geometry worked by hand. Two rays of one camera meet at a point whatever their errors: the pair's
one residual dof is the miss across their epipolar plane (the plane of the baseline and the point),
which says nothing of the range, so an error along that plane moves the triangulated point with no
residual. For a point at distance d off a straight flight line at speed V, seen at angle phi from the
line, the bearing turns by V sin(phi) dt / r per dt, and the pair's range is r0 = V dt sin(phi) / dtheta:
a bearing that steps 3 frames' turn in one frame ranges it at a third of its distance.

The case: fps100_stereo_flying track 259 (a one-feature track on the stationary box #3, 1.3-1.5 m
away): its feature's KLT chains (``tracker.features.klt_step_s``: at 100 fps each frame steps from
the position 3 frames back) were offset by 0, 2 and 1 frames of motion, so its bearing stepped ~2.8
deg, then ~0.2, ~0.1 deg, and so on. After each restart (``reinit_after_gated`` gated bearings) the
track was triangulated from its next frame's pair, 0.5 m (sigma 0.04 m) against 1.4 m, reported at
once and then for the 5 frames whose bearings the gate rejected: 25 reports with z^2 350-400 on both
arms of the harness. Here the same: a stationary point 1.4 m off the flight line, one camera at
100 fps, the bearing of frame k taken from the pose (0, 2, 1)[k % 3] frames ahead.

The state's life cycle at 30 fps, every bearing exact (truth by hand: the point's distance from the
body's pose): a state triangulated from two consecutive frames (nothing between them to replay) is
withheld in its own frame ("not yet tested") and reported from the next frame on, when that frame's
bearing passes the gate; a single bearing that jumps is gated (withheld: "gated") and the next one,
which agrees again, is reported again.
"""

from __future__ import annotations

import numpy as np

from estimators.fusion import FusionSettings
from tests.estimators.fusion_helpers import exact_bearing

FPS = 100.0
SPEED = 3.0
POINT_W = np.array([1.0, 1.4, 0.0])  # stationary, 1.4 m off the flight line (+x), passed at 0.33 s
SIGMA = 2.5e-3  # the representative bearing's sigma (rad) of track 259
LEAD = (0, 2, 1)  # frames of motion each KLT chain is ahead (frame k: LEAD[k % 3])


def _run(lead=LEAD, n_frames: int = 60):
    """[(frame, report, true range m)] of the one track (representative bearing only) per frame."""
    from estimators.cameras import Equidistant
    from estimators.egomotion import ConstantVelocity
    from estimators.fusion import ObstacleFusion
    from estimators.records import CameraView, ObstacleObservation
    from estimators.rig import mono_forward_rig

    rig = mono_forward_rig(Equidistant.from_deg_per_px(0.15, 1280, 1280))
    ego = ConstantVelocity(SPEED)
    fus = ObstacleFusion(rig, ego, FusionSettings())
    out = []
    for k in range(n_frames):
        t = k / FPS
        T_W_B = ego.pose_at(t)
        T_seen = ego.pose_at(t + lead[k % len(lead)] / FPS)
        views = tuple(CameraView(c.name, exact_bearing(c, T_seen, POINT_W), [0, 0], SIGMA) for c in rig)
        (r,) = fus.step([ObstacleObservation(1, k, t, "confirmed", views)], k, t)
        out.append((k, r, float(np.linalg.norm(POINT_W - T_W_B.t))))
    return out


def test_a_two_ray_triangulation_is_reported_only_once_a_further_bearing_agrees():
    reps = _run()
    ranged = [(k, r.range_m, r.range_sigma_m, truth) for k, r, truth in reps if r.range_m is not None]
    for k, rng, sig, truth in ranged:  # a range must be honest: its sigma covers the truth
        assert abs(rng - truth) <= 3.0 * sig, (k, rng, sig, truth)
    # (at HEAD f16ef4e: 0.47-0.56 m, sigma 0.025-0.046 m, against 1.40-1.70 m: 25-37 sigma short,
    # every frame but the restarts'); each unranged frame says why
    reasons = {r.unobservable_reason for _k, r, _truth in reps if r.range_m is None}
    assert None not in reasons
    assert "mono triangulation not yet tested by a further bearing" in reasons
    assert "its last bearing disagrees with its mono triangulation (gated)" in reasons


def test_a_clean_track_is_still_ranged():
    # the same point with exact bearings: triangulated, tested by the next bearing, reported
    reps = _run(lead=(0,))
    ranged = [(k, r.range_m, r.range_sigma_m, truth) for k, r, truth in reps if r.range_m is not None]
    assert len(ranged) >= 0.8 * len(reps)
    for k, rng, sig, truth in ranged:
        assert abs(rng - truth) <= 3.0 * sig, (k, rng, sig, truth)


def _run_30fps(turn_deg, n_frames: int = 12):
    """[(frame, report, true range m)] of the one track at 30 fps, 3 m/s, every bearing exact but
    frame k's turned by turn_deg.get(k, 0) deg about W z (in the flight's plane: a bearing's jump).
    The first pair, frames 0 and 1, has 2.7 deg of parallax (the bearing turns by V dt sin(phi) / r
    = 0.1 m * sin(54 deg) / 1.72 m a frame) and a range sigma of ~7 %: the state is triangulated at
    frame 1 with no sighting in between to replay, so nothing has tested it yet."""
    from estimators.cameras import Equidistant
    from estimators.egomotion import ConstantVelocity
    from estimators.fusion import ObstacleFusion
    from estimators.records import CameraView, ObstacleObservation
    from estimators.rig import mono_forward_rig

    rig = mono_forward_rig(Equidistant.from_deg_per_px(0.15, 1280, 1280))
    ego = ConstantVelocity(SPEED)
    fus = ObstacleFusion(rig, ego, FusionSettings())
    out = []
    for k in range(n_frames):
        t = k / 30.0
        T_W_B = ego.pose_at(t)
        a = np.radians(turn_deg.get(k, 0.0))
        Rz = np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])
        p_seen = T_W_B.t + Rz @ (POINT_W - T_W_B.t)  # the point turned about the body: the bearing turned
        views = tuple(CameraView(c.name, exact_bearing(c, T_W_B, p_seen), [0, 0], SIGMA) for c in rig)
        (r,) = fus.step([ObstacleObservation(1, k, t, "confirmed", views)], k, t)
        out.append((k, r, float(np.linalg.norm(POINT_W - T_W_B.t))))
    return out


def test_a_pair_state_is_withheld_until_tested_then_reported():
    reps = _run_30fps({})
    (_k0, r0, _), (_k1, r1, _), (_k2, r2, truth2) = reps[:3]
    assert r0.range_m is None and r0.unobservable_reason == "no earlier sighting yet"
    # frame 1: triangulated from frames 0 and 1, no further bearing yet: withheld, and says so
    assert r1.range_m is None
    assert r1.unobservable_reason == "mono triangulation not yet tested by a further bearing"
    # frame 2: its exact bearing passes the gate: reported from then on, honestly
    for k, r, truth in reps[2:]:
        assert r.range_m is not None, (k, r.unobservable_reason)
        assert abs(r.range_m - truth) <= 3.0 * r.range_sigma_m, (k, r.range_m, r.range_sigma_m, truth)
        assert r.unobservable_reason is None


def test_a_pair_state_whose_bearing_is_gated_once_is_reported_again_when_the_next_agrees():
    reps = _run_30fps({6: 3.0})  # frame 6's bearing jumps 3 deg: 21 bearing sigmas, far over the gate
    r6 = reps[6][1]
    assert r6.range_m is None
    assert r6.unobservable_reason == "its last bearing disagrees with its mono triangulation (gated)"
    for k, r, truth in reps[2:6] + reps[7:]:  # tested and passing before and after the jump
        assert r.range_m is not None, (k, r.unobservable_reason)
        assert abs(r.range_m - truth) <= 3.0 * r.range_sigma_m, (k, r.range_m, r.range_sigma_m, truth)
