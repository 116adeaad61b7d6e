"""A two-view observation gives a representative-ray (two-ray) stereo fix only when its views could be
one point: feature ids are physical-point ids, so two views that list member features but share none
of them give no evidence that their representative rays meet at one point (estimators/fusion.py
``_ghost_prone``).

Truth is the scene written here by hand (a hovering 0.30 m stereo pair, body = world frame): a box
whose centre is B = (2.0, 0.45, 0) and four corners around it, and a ground point G; bearings are made
from those points with seeded noise.
"""

from __future__ import annotations

import math

import numpy as np

from estimators.cameras import Equidistant
from estimators.egomotion import ConstantVelocity
from estimators.fusion import FusionSettings, ObstacleFusion
from estimators.records import CameraView, ObstacleObservation
from estimators.rig import stereo_forward_rig

MODEL = Equidistant.from_deg_per_px(0.15, 1280, 1280)
FPS = 30.0
SIGMA = 5e-4
C0 = np.array([0.0, 0.15, 0.0])  # cam0's centre (stereo_forward_rig: +baseline / 2 on body y)
C1 = np.array([0.0, -0.15, 0.0])  # cam1's
BOX_W = np.array([2.0, 0.45, 0.0])  # the box's centre
CORNERS_W = BOX_W + np.array([[0.0, 0.2, 0.2], [0.0, -0.2, 0.2], [0.0, 0.2, -0.2], [0.0, -0.2, -0.2]])
# cam1's representative ray goes to the box's centre; X on it, 0.36 m from the body origin
X_W = C1 + 0.18 * (BOX_W - C1)
# cam0's representative ray passes through X (so the two representative rays cross there, 0.36 m from
# the body); its one member feature is a ground point 3.5 m away, not on the box
GROUND_W = np.array([3.0, -1.45, -1.0])


def _bearing(cam, T_W_B, p_W: np.ndarray, rng) -> np.ndarray:
    p_C = (cam.T_C_B @ T_W_B.inverse()).apply(p_W)
    b = p_C / np.linalg.norm(p_C)
    e = rng.normal(scale=SIGMA, size=3)
    b = b + e - (e @ b) * b
    return b / np.linalg.norm(b)


def _run(rep_W: dict[str, np.ndarray], feats: dict[str, list[tuple[int, np.ndarray]]], frames: int = 6):
    """Each frame one observation of track 5 with a view per camera: its representative bearing
    towards rep_W[camera] and its member features feats[camera] = [(id, point), ...]."""
    rng = np.random.default_rng(3)
    rig = stereo_forward_rig(MODEL, 0.30)
    ego = ConstantVelocity(0.0)
    fus = ObstacleFusion(rig, ego, FusionSettings())
    out = []
    for k in range(frames):
        t = k / FPS
        T_W_B = ego.pose_at(t)
        views = []
        for c in rig:
            ids = np.array([i for i, _ in feats[c.name]], dtype=np.int64)
            fb = np.array([_bearing(c, T_W_B, p, rng) for _, p in feats[c.name]])
            views.append(CameraView(c.name, _bearing(c, T_W_B, rep_W[c.name], rng), [0, 0], SIGMA,
                                    feature_ids=ids, feature_b_C=fb))
        (r,) = fus.step([ObstacleObservation(5, k, t, "confirmed", tuple(views))], k, t)
        out.append(r)
    return out


def test_the_geometry_is_what_the_tests_say():
    # the two representative rays of the no-shared-id case meet (coplanar with the baseline, at X
    # ahead of both cameras) 0.36 m from the body, 45 deg apart, while the box is 2.05 m away
    d0, d1 = X_W - C0, BOX_W - C1
    assert abs(float(np.cross(d0, d1) @ (C1 - C0))) < 1e-12
    assert 0.35 < float(np.linalg.norm(X_W)) < 0.37
    ang = math.degrees(math.acos(float(d0 @ d1) / (np.linalg.norm(d0) * np.linalg.norm(d1))))
    assert 40.0 < ang < 50.0
    assert float(np.linalg.norm(BOX_W)) > 2.0


def test_views_sharing_no_feature_id_give_no_two_ray_fix():
    # cam0: one ground feature (id 1), its representative ray through X; cam1: four box corners
    # (ids 11-14), its representative ray on the box's centre. No id in common: the rays' crossing at
    # 0.36 m is no measurement (the box is 2 m away). Hovering, one camera per feature: nothing else
    # ranges the track, so it stays unranged instead of reported at 0.36 m
    feats = {"cam0": [(1, GROUND_W)], "cam1": [(11 + i, p) for i, p in enumerate(CORNERS_W)]}
    for r in _run({"cam0": X_W, "cam1": BOX_W}, feats):
        assert r.range_m is None
        assert "stereo" not in r.source


def test_views_sharing_a_feature_id_keep_the_two_ray_fix():
    # the same box, with cam0's one member feature a box corner cam1 lists too (id 11): the views are
    # one object's, and the representative rays (both on the box's centre) range it
    true_r = float(np.linalg.norm(BOX_W))
    feats = {"cam0": [(11, CORNERS_W[0])], "cam1": [(11 + i, p) for i, p in enumerate(CORNERS_W)]}
    reps = _run({"cam0": BOX_W, "cam1": BOX_W}, feats)
    for r in reps:
        assert "stereo" in r.source
        assert abs(r.range_m - true_r) / true_r < 0.03
        assert abs(r.range_m - true_r) <= 3.0 * r.range_sigma_m
