"""A mono pair's state (``_init_mono``) takes a second camera's bearing under ``_process``'s ghost rule.

Feature ids are physical-point ids: two views that list member features but share none give no
evidence that their representative bearings are of one point (``_ghost_prone``), so ``_process``
fuses only the first view's bearing. ``_init_mono`` fused every view of the sightings it replays and
the second camera's bearing of its own frame regardless; such a bearing pulled the pair's point
toward the two cameras' ghost triangulation and, since a pair's range is reported only once a further
bearing has tested it (``_Track.pair_tested``), counted as that test, or, gated, made the report say
the state's own bearing disagrees.

Geometry by hand: a stereo rig (0.30 m, ``stereo_forward_rig``) flies along +x; cam0 sees a stationary
point P = (1.0, 1.4, 0) m (its representative bearing and its one member feature, id 1: fewer than
``feature_min_count``, so the representative rays range it); cam1 sees another point Q (its one
member, id 2), Q = P turned by ``a`` about cam1's centre in the level plane: cam1's bearing is a deg
off P's, in the stereo pair's epipolar plane, where it moves the triangulated depth. Every bearing is
exact; truth is |P - o| from the pose.
"""

from __future__ import annotations

import numpy as np

from estimators.fusion import FusionSettings
from tests.estimators.fusion_helpers import exact_bearing

P_W = np.array([1.0, 1.4, 0.0])
SIGMA = 2.5e-3
NOT_TESTED = "mono triangulation not yet tested by a further bearing"


def _run(speed: float, a_deg: float, n_frames: int = 8):
    """[(frame, report, true range m)] of the one track, 30 fps."""
    from estimators.cameras import Equidistant
    from estimators.egomotion import ConstantVelocity
    from estimators.fusion import ObstacleFusion
    from estimators.records import CameraView, ObstacleObservation
    from estimators.rig import stereo_forward_rig

    rig = stereo_forward_rig(Equidistant.from_deg_per_px(0.15, 1280, 1280), 0.30)
    ego = ConstantVelocity(speed)
    fus = ObstacleFusion(rig, ego, FusionSettings())
    a = np.radians(a_deg)
    Rz = np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])
    out = []
    for k in range(n_frames):
        t = k / 30.0
        T_W_B = ego.pose_at(t)
        views = []
        for i, cam in enumerate(rig):
            c_W = (T_W_B @ cam.T_C_B.inverse()).t
            p = P_W if i == 0 else c_W + Rz @ (P_W - c_W)
            b = exact_bearing(cam, T_W_B, p)
            views.append(CameraView(cam.name, b, [0, 0], SIGMA, feature_ids=np.array([1 + i]),
                                    feature_b_C=b[None]))
        (r,) = fus.step([ObstacleObservation(1, k, t, "confirmed", tuple(views))], k, t)
        out.append((k, r, float(np.linalg.norm(P_W - T_W_B.t))))
    return out


def test_the_replay_tests_a_pair_with_its_own_camera_not_a_ghost():
    # 1.5 m/s: frames 0 and 1 are 1.35 deg apart (sigma 14 % > 10 %), frames 0 and 2 2.7 deg: the
    # state is triangulated at frame 2 and frame 1's bearing replayed. cam0's passes: reported at once
    # (at HEAD 01a6558 withheld as "its last bearing disagrees ... (gated)": cam1's ghost bearing,
    # 1.5 deg off, replayed after it)
    reps = _run(1.5, 1.5)
    assert reps[1][1].range_m is None
    for k, r, truth in reps[2:]:
        assert r.range_m is not None, (k, r.unobservable_reason)
        assert abs(r.range_m - truth) <= 0.01 * truth, (k, r.range_m, truth)


def test_a_ghost_bearing_in_the_pairs_own_frame_neither_tests_nor_moves_it():
    # 3 m/s: triangulated at frame 1 from frames 0 and 1 (2.7 deg), nothing to replay: withheld as not
    # yet tested, then exact. At 01a6558: +-0.6 deg off, cam1's bearing passed the gate and the state
    # was reported at frame 1 at 1.52 | 1.81 m against 1.66 m (9 % off, sigma 0.15 m), and 2-9 % off
    # for two frames more; +-1.5 deg off, it was gated and the report said the state's last bearing
    # disagreed
    for a in (0.6, -0.6, 1.5, -1.5):
        reps = _run(3.0, a)
        r1 = reps[1][1]
        assert r1.range_m is None, (a, r1.range_m)
        assert r1.unobservable_reason == NOT_TESTED, (a, r1.unobservable_reason)
        for k, r, truth in reps[2:]:
            assert r.range_m is not None, (a, k, r.unobservable_reason)
            assert abs(r.range_m - truth) <= 0.01 * truth, (a, k, r.range_m, truth)
