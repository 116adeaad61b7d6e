"""A feature stereo fix from shared ids that name different points in the two cameras (a
cross-camera id mismatch on a repeated texture) is gated against the track's own static member
points of the frame (``ObstacleFusion._process``).

Truth worked by hand: a stereo rig (cam0 at y = +0.15 m, cam1 at y = -0.15 m, both along +x)
flies along +x at 1.5 m/s for 16 frames at 30 fps, so at the last frame (t = 0.5 s) the body
origin is o = (0.75, 0, 0) and the cameras are 3.5 m short of a plate at x = 4.25 with four
textured corners P0..P3 = (4.25, y, z), y in {1.45, 1.55}, z in {-0.05, 0.05}; from o they are at
sqrt(3.5^2 + y^2 + 0.05^2) = 3.7889 m (y = 1.45: P0, P1) and 3.8282 m (y = 1.55: P2, P3).
cam0 tracks all four (ids 0-3); cam1 tracks P0, P1 under its own ids 100, 101, then in the last
frame under cam0's ids 0, 1 (its features matched to cam0's).

Mismatched: in that last frame cam1's ids 0 and 1 name Q_j = P_j + (0, 0.3, 0) (the next copy of a
repeated texture). Both rays of id j lie in the plane z(x) = z_j (x - 0.75) / 3.5; with
s = (x - 0.75) / 3.5, cam0's has y = 0.15 + (y_j - 0.15) s, cam1's y = -0.15 + (y_j + 0.45) s:
equal at 0.3 = 0.6 s, s = 1/2: the point (2.5, 0.15 + (y_j - 0.15) / 2, z_j / 2) = (2.5, 0.8,
+-0.025), at sqrt(1.75^2 + 0.8^2 + 0.025^2) = 1.9244 m from o: half-way, while P2 and P3 (cam0 only,
unchanged; their least-squares points over 16 frames) still put the plate at 3.83 m. The two
members left (P0, P1's points now take a ray that misses them by 0.3 m / 3.5 m) are fewer than
feature_min_count (3), so they do not range the track themselves: with the fix refused the frame
reports no range (instead of 1.92 m).
Consistent: cam1's ids 0, 1 name P0, P1 and cam0 has lost P2, P3 (so, as above, the members do not
range the track alone and the fix is weighed): it meets at P0, P1, 3.7889 m, and is used.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from estimators.cameras import Equidistant
from estimators.egomotion import ConstantVelocity
from estimators.fusion import ObstacleFusion
from estimators.records import CameraView, ObstacleObservation
from estimators.rig import stereo_forward_rig

MODEL = Equidistant.from_deg_per_px(0.15, 1280, 1280)
FPS = 30.0
FRAMES = 16
CORNERS = [np.array([4.25, y, z]) for y in (1.45, 1.55) for z in (-0.05, 0.05)]
R_P01 = math.sqrt(3.5 ** 2 + 1.45 ** 2 + 0.05 ** 2)  # 3.7889 m
R_SHORT = math.sqrt(1.75 ** 2 + 0.8 ** 2 + 0.025 ** 2)  # 1.9244 m, the mismatched ids' rays meet


def _bearing(cam, T_W_B, p_W):
    p_C = (cam.T_C_B @ T_W_B.inverse()).apply(p_W)
    return p_C / np.linalg.norm(p_C)


def _run(mismatch: bool):
    """The track's last report, its feature stereo range, its gated count and the last body origin."""
    rig = stereo_forward_rig(MODEL, 0.30)
    ego = ConstantVelocity(1.5)
    fus = ObstacleFusion(rig, ego)
    for k in range(FRAMES):
        t = k / FPS
        T_W_B = ego.pose_at(t)
        last = k == FRAMES - 1
        views = []
        for c in rig:
            if c.name == "cam0":
                ids = [0, 1] if (last and not mismatch) else [0, 1, 2, 3]
                pts = [CORNERS[i] for i in ids]
            else:  # its own ids for P0, P1 until its features are matched to cam0's
                ids = [0, 1] if last else [100, 101]
                shift = np.array([0.0, 0.3, 0.0]) if (last and mismatch) else np.zeros(3)
                pts = [CORNERS[i] + shift for i in range(2)]
            fb = np.array([_bearing(c, T_W_B, p) for p in pts])
            views.append(CameraView(c.name, _bearing(c, T_W_B, np.mean(pts, axis=0)), [0, 0], 1e-3,
                                    feature_ids=np.array(ids), feature_b_C=fb))
        reps = fus.step([ObstacleObservation(1, k, t, "confirmed", tuple(views))], k, t)
    tr = fus._tracks[1]
    return next(r for r in reps if r.id == 1), tr.feature_stereo, tr.gated, T_W_B.t


def test_shared_ids_meeting_short_of_the_members_are_gated():
    r, fst, gated, o = _run(mismatch=True)
    assert o[0] == pytest.approx(0.75)
    assert fst[0] == pytest.approx(R_SHORT, abs=0.01)  # the fix the scenario sets up
    assert gated == 1
    assert r.range_m is None  # (not 1.92 m: the fused range before the gate)


def test_consistent_shared_ids_are_not_gated():
    r, fst, gated, _o = _run(mismatch=False)
    assert fst[0] == pytest.approx(R_P01, abs=0.01)
    assert gated == 0
    assert "stereo" in r.source
    assert r.range_m == pytest.approx(R_P01, abs=0.05)
