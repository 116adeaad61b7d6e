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
    # views not asked for are not tested (False)
    todo = np.array([False, True, False])
    assert _outline_flags(b, view, todo).tolist() == [False] * 9 + [True] * 3 + [False] * 4


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
