"""The feature that ranges a stereo track avoids the track's outline (occlusion boundaries).

Truth is worked by hand here: a hull drawn on a grid, and a box corner whose silhouette two cameras
see on different edges (the closed-form crossing of their rays). Nothing expected is computed with
the code under test.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from estimators.cameras import Equidistant
from estimators.egomotion import ConstantVelocity
from estimators.fusion import FusionSettings, ObstacleFusion, _outline_flags
from estimators.records import CameraView, ObstacleObservation
from estimators.rig import stereo_forward_rig

MODEL = Equidistant.from_deg_per_px(0.15, 1280, 1280)
FPS = 30.0


def _unit(P: np.ndarray) -> np.ndarray:
    return P / np.linalg.norm(P, axis=1, keepdims=True)


def test_outline_flags_are_the_hull_vertices_of_each_view():
    # view 0 on the plane x = 4: a pentagon (its 5 vertices: outline) around four inner points, one
    # of them just inside the edge between the vertices (0.3, 0) and (0.1, 0.3) (at 3/4 of the way
    # from the second to the first vertex, moved 0.01 inwards); view 1: three points (all outline);
    # view 2: four points, one inside their triangle
    pent = [(0.3, 0.0), (0.1, 0.3), (-0.25, 0.2), (-0.25, -0.2), (0.1, -0.3)]
    inner = [(0.0, 0.0), (0.1, 0.1), (-0.1, -0.1), (0.25 - 0.01, 0.075 - 0.01)]
    tri = [(0.5, 0.0), (0.6, 0.0), (0.55, 0.1)]
    quad = [(0.0, 0.0), (0.2, 0.0), (0.0, 0.2), (0.05, 0.05)]
    b = _unit(np.array([(4.0, y, z) for y, z in pent + inner]
                       + [(1.0, y, z) for y, z in tri] + [(2.0, y, z) for y, z in quad]))
    view = np.array([0] * 9 + [1] * 3 + [2] * 4)
    expected = [True] * 5 + [False] * 4 + [True] * 3 + [True, True, True, False]
    assert _outline_flags(b, view).tolist() == expected
    # moved 0.02 outwards instead, that point is a vertex
    b[8] = _unit(np.array([(4.0, 0.25 + 0.02, 0.075 + 0.02)]))[0]
    assert _outline_flags(b, view)[8]


# A box whose front face runs from its left front edge F = (2, 0) along U = (0.6, -0.6) (a face
# receding to the right, seen by both cameras) and whose side face y = 0 runs from F back to
# K = (2.5, 0) (box on y < 0: the side face is seen from y > 0 only, i.e. by cam0 at y = +0.15, not by
# cam1 at y = -0.15). A texture line round the box at the cameras' height z = 0 meets the silhouette
# in a corner: cam0 sees it at the back edge K, cam1 at the front edge F. The two rays are coplanar
# (z = 0), so they fit; they cross where 0.15 - 0.06 x = -0.15 + 0.075 x: x = 0.3 / 0.135 = 2.2222,
# y = 0.0167, a point in front of nothing: its direction from the body origin passes the box at
# y = 0.015 > 0 at x = 2.
F_W = np.array([2.0, 0.0, 0.0])
K_W = np.array([2.5, 0.0, 0.0])
U_W = np.array([0.6, -0.6, 0.0])


def _bearing(cam, T_W_B, p_W):
    p_C = (cam.T_C_B @ T_W_B.inverse()).apply(p_W)
    return p_C / np.linalg.norm(p_C)


def _box_corner_run(settings: FusionSettings | None = None, frames: int = 10):
    rig = stereo_forward_rig(MODEL, 0.30)
    ego = ConstantVelocity(0.0)
    fus = ObstacleFusion(rig, ego, settings or FusionSettings())
    # physical corners on the front face (id 0..7) and the silhouette corner (id 8); the
    # representative ray near the face's left part, as a group's centre can be
    faces = [F_W + s * U_W + np.array([0.0, 0.0, z]) for s in (0.1, 0.25, 0.4, 0.55) for z in (-0.2, 0.2)]
    for k in range(frames):
        t = k / FPS
        T_W_B = ego.pose_at(t)
        views = []
        for c in rig:
            pts = faces + [K_W if c.name == "cam0" else F_W]
            fb = np.array([_bearing(c, T_W_B, p) for p in pts])
            views.append(CameraView(c.name, _bearing(c, T_W_B, F_W + 0.2 * U_W), [0, 0], 1e-3,
                                    feature_ids=np.arange(9), feature_b_C=fb))
        (r,) = fus.step([ObstacleObservation(3, k, t, "confirmed", tuple(views))], k, t)
    return r, faces


def _face_hit(b_B: np.ndarray) -> tuple[float, float]:
    """Range along b_B (body = world here: hovering at the origin) to the front face's plane and
    the face coordinate s of the hit (on the face for 0 <= s <= 1)."""
    n = np.array([-1.0, -1.0, 0.0]) / math.sqrt(2.0)  # the front face's outward normal
    t = float(F_W @ n) / float(b_B @ n)
    s = float((t * b_B - F_W) @ U_W) / float(U_W @ U_W)
    return t, s


def test_stereo_fix_is_not_ranged_on_a_silhouette_corner():
    r, faces = _box_corner_run()
    assert r.range_m is not None and "stereo" in r.source
    b = np.asarray(r.bearing_body, float)
    t, s = _face_hit(b / np.linalg.norm(b))
    # the report is one of the face's physical corners: its bearing meets the face, at its range
    assert 0.0 <= s <= 1.0
    assert r.range_m == pytest.approx(t, rel=1e-3)
    assert min(abs(r.range_m - float(np.linalg.norm(p))) for p in faces) < 1e-3 * r.range_m
    # with the rule off, the silhouette corner is the one chosen (the lower median of the inner
    # ones by range): the crossing of its two rays, x = 2.2222, y = 0.0167, off the face
    r_off, _ = _box_corner_run(FusionSettings(feature_avoid_outline=False))
    assert r_off.range_m == pytest.approx(math.hypot(0.3 / 0.135, 0.15 - 0.06 * 0.3 / 0.135), rel=1e-3)
    b = np.asarray(r_off.bearing_body, float)
    assert _face_hit(b / np.linalg.norm(b))[1] < 0.0


# The static-point (multi-frame) fix on a stereo rig: the rig flies forward (+x, 1.5 m/s) past a
# box like the one above, whose side face y = 0 is only 0.2 m deep (back edge K2 = (2.2, 0)). cam0
# (y = +0.15) sees the side face, so its silhouette corner on the texture line z = 0 is the back
# edge K2, a static point (feature 12, cam0 only); cam1 (y = -0.15) sees the front edge F (feature
# 13, cam1 only). The face's corners (ids 0..11) are seen by both, in rows z = -0.15, 0, 0.25 (the
# middle row inside each view's hull). All rays are exact, so every feature fits a static point
# and the static fix (not the stereo one) ranges the track. After 14 frames the body is at
# x = 14 / 30 * 1.5 = 0.7 m; the inner half (nearest the representative ray, towards F + 0.2 U)
# holds the face corners s = 0.1 (z = 0), s = 0.25 and 0.4 (z = -0.15, 0), s = 0.55 (z = 0) and
# K2, at ranges |F + s U + (0, 0, z) - o| = 1.3613, 1.4654, 1.4577, 1.5658, 1.5586, 1.6631 and
# |K2 - o| = 2.2 - 0.7 = 1.5 m: K2 is their lower median (4th of 7), the one chosen without the
# outline rule; the nearest face corner to 1.5 m is 1.4790 (s = 0.25, z = 0.25).
K2_W = np.array([2.2, 0.0, 0.0])


def _box_flight_run(settings: FusionSettings | None = None, frames: int = 15):
    rig = stereo_forward_rig(MODEL, 0.30)
    ego = ConstantVelocity(1.5)
    fus = ObstacleFusion(rig, ego, settings or FusionSettings())
    faces = [F_W + s * U_W + np.array([0.0, 0.0, z])
             for s in (0.1, 0.25, 0.4, 0.55) for z in (-0.15, 0.0, 0.25)]
    for k in range(frames):
        t = k / FPS
        T_W_B = ego.pose_at(t)
        views = []
        for c in rig:
            cam0 = c.name == "cam0"
            fb = np.array([_bearing(c, T_W_B, p) for p in faces + [K2_W if cam0 else F_W]])
            views.append(CameraView(c.name, _bearing(c, T_W_B, F_W + 0.2 * U_W), [0, 0], 1e-3,
                                    feature_ids=np.r_[np.arange(12), 12 if cam0 else 13], feature_b_C=fb))
        (r,) = fus.step([ObstacleObservation(3, k, t, "confirmed", tuple(views))], k, t)
    return r, faces, T_W_B.t


def test_static_fix_on_a_stereo_rig_is_not_ranged_on_a_silhouette_corner():
    r, faces, o = _box_flight_run()
    assert o[0] == pytest.approx(0.7)
    assert r.range_m is not None and "mono" in r.source
    # the report is one of the face's physical corners: its bearing from the body meets the face
    # at its range, and that range is a face corner's
    b = np.asarray(r.bearing_body, float)
    n = np.array([-1.0, -1.0, 0.0]) / math.sqrt(2.0)  # the front face's outward normal
    b = b / np.linalg.norm(b)
    t = float((F_W - o) @ n) / float(b @ n)
    s = float((o + t * b - F_W) @ U_W) / float(U_W @ U_W)
    assert min(abs(r.range_m - float(np.linalg.norm(p - o))) for p in faces) < 1e-3 * r.range_m
    assert 0.05 <= s <= 1.0  # (the ray toward K2 meets the face's plane at its edge F: s = 0)
    assert r.range_m == pytest.approx(t, rel=1e-3)
    # with the rule off, the static fix is ranged on the silhouette corner K2: 1.5 m
    r_off, _, _ = _box_flight_run(FusionSettings(feature_avoid_outline=False))
    assert r_off.range_m == pytest.approx(1.5, rel=1e-3)
