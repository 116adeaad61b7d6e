"""A report whose bearing from the body origin passes behind another track's nearer surface gets a
range sigma that reaches that surface (``ObstacleFusion._occluded_by_members``).

Truth worked by hand: a stereo rig (cameras at y = +-0.15 m) flies along +x at 1.5 m/s for 15
frames at 30 fps, so the body ends at o = (0.7, 0, 0). A plate of nine textured corners at x = 2,
y in {0.25, 0.35, 0.45}, z in {-0.1, 0, 0.1} (track 1, seen by both cameras) and three far corners
around P = (4, 1, 0) (track 2, seen by cam0 only: cam1's rays toward them cross the plate). The
body's line toward P crosses x = 2 at y = 1.3 / 3.3 = 0.394 (inside the plate's corners: hidden
from the body origin), cam0's (from y = 0.15) at y = 0.15 + 0.85 * 1.3 / 3.3 = 0.485 (past the
plate's edge at 0.45: cam0 sees P). Ranges from o: |P - o| = hypot(3.3, 1.0) = 3.448 m, the plate's
corners 1.32-1.38 m.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from estimators.cameras import Equidistant
from estimators.egomotion import ConstantVelocity
from estimators.fusion import FusionSettings, ObstacleFusion
from estimators.records import CameraView, ObstacleObservation
from estimators.rig import stereo_forward_rig

MODEL = Equidistant.from_deg_per_px(0.15, 1280, 1280)
FPS = 30.0
PLATE = [np.array([2.0, y, z]) for y in (0.25, 0.35, 0.45) for z in (-0.1, 0.0, 0.1)]


def _bearing(cam, T_W_B, p_W):
    p_C = (cam.T_C_B @ T_W_B.inverse()).apply(p_W)
    return p_C / np.linalg.norm(p_C)


def _run(far_y: float, settings: FusionSettings | None = None, frames: int = 15, hull_only: bool = False):
    """The far track's last report (three corners at (4, far_y, 0), (4, far_y, +-0.05)) and o.
    ``hull_only``: the camera-offset test off (offset 0, as on a mono rig whose camera sits at the
    body origin), so only the convex-hull test can act."""
    rig = stereo_forward_rig(MODEL, 0.30)
    ego = ConstantVelocity(1.5)
    fus = ObstacleFusion(rig, ego, settings or FusionSettings())
    if hull_only:
        fus._cam_offset_m = 0.0
    far = [np.array([4.0, far_y, z]) for z in (-0.05, 0.0, 0.05)]
    for k in range(frames):
        t = k / FPS
        T_W_B = ego.pose_at(t)
        plate_views, far_views = [], []
        for c in rig:
            fb = np.array([_bearing(c, T_W_B, p) for p in PLATE])
            plate_views.append(CameraView(c.name, _bearing(c, T_W_B, PLATE[4]), [0, 0], 1e-3,
                                          feature_ids=np.arange(9), feature_b_C=fb))
            if c.name == "cam0":
                fb = np.array([_bearing(c, T_W_B, p) for p in far])
                far_views.append(CameraView(c.name, _bearing(c, T_W_B, far[1]), [0, 0], 1e-3,
                                            feature_ids=np.arange(100, 103), feature_b_C=fb))
        reps = fus.step([ObstacleObservation(1, k, t, "confirmed", tuple(plate_views)),
                         ObstacleObservation(2, k, t, "confirmed", tuple(far_views))], k, t)
    return next(r for r in reps if r.id == 2), T_W_B.t


def test_a_point_hidden_from_the_body_origin_by_a_nearer_track_gets_a_sigma_reaching_it():
    r, o = _run(1.0)
    assert o[0] == pytest.approx(0.7)
    assert r.range_m == pytest.approx(math.hypot(3.3, 1.0), rel=1e-3)  # the far corner's own point
    near = max(float(np.linalg.norm(p - o)) for p in PLATE)  # 1.38 m
    assert r.range_sigma_m >= r.range_m - near
    # without the rule, the far point's own sigma
    r_off, _ = _run(1.0, FusionSettings(occluder_min_members=0))
    assert r_off.range_m == pytest.approx(r.range_m)
    assert r_off.range_sigma_m < 0.3  # (its own sigma: 15 frames of a 2.4 deg parallax)


def test_a_point_clear_of_the_nearer_track_keeps_its_sigma():
    # far corners at y = -1: the body's line toward them crosses x = 2 at y = -0.39, 0.64 m from
    # the plate's nearest corner, far beyond the cameras' 0.15 m offset
    r, _ = _run(-1.0)
    r_off, _ = _run(-1.0, FusionSettings(occluder_min_members=0))
    assert r.range_m == pytest.approx(math.hypot(3.3, 1.0), rel=1e-3)
    assert r.range_sigma_m == r_off.range_sigma_m < 0.3


def test_the_hull_test_alone_finds_the_plate_in_front_of_the_point():
    # the body's line toward P crosses x = 2 at (y, z) = (0.394, 0): inside the plate's corners
    # (y 0.25-0.45, z -0.1-0.1), so the hull test holds without the camera-offset test
    r, o = _run(1.0, hull_only=True)
    near = max(float(np.linalg.norm(p - o)) for p in PLATE)
    assert r.range_sigma_m >= r.range_m - near
