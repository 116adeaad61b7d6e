"""A frame's sightings (``ObstacleFusion._sightings``) keep each track's views in the rig's order, with
their own camera centres, and the first view's centre as the sighting's baseline origin ``c0``.

Two tracks on a 0.30 m stereo pair (one seen by both cameras, one by cam1 alone) and a mono track's
frame after them: the centres are the rig's camera positions at the body pose, worked here as
T_W_B.t + R_W_B t_B_C (the drone flies along x at 2 m/s, so R_W_B = I)."""

from __future__ import annotations

import numpy as np

from estimators.cameras import Equidistant
from estimators.egomotion import ConstantVelocity
from estimators.fusion import FusionSettings, ObstacleFusion
from estimators.records import CameraView, ObstacleObservation
from estimators.rig import stereo_forward_rig
from tests.estimators.fusion_helpers import noisy_bearing

MODEL = Equidistant.from_deg_per_px(0.15, 1280, 1280)


def test_sightings_carry_each_views_camera_centre_and_the_first_views_as_c0():
    rig = stereo_forward_rig(MODEL, 0.30)
    ego = ConstantVelocity(2.0)
    fus = ObstacleFusion(rig, ego, FusionSettings())
    bearing = noisy_bearing(np.random.default_rng(1), 1e-4)
    pts = np.array([4.0, 0.5, 0.2]) + 0.1 * np.array([[0, 0.6, 0.5], [0, -0.6, 0.5], [0.3, 0, -0.6]])
    for k in range(3):
        t = k / 30.0
        T_W_B = ego.pose_at(t)

        def view(cam, ids, T_W_B=T_W_B):
            return CameraView(cam.name, bearing(cam, T_W_B, pts.mean(0)), [0, 0], 1e-3,
                              feature_ids=np.asarray(ids),
                              feature_b_C=np.array([bearing(cam, T_W_B, q) for q in pts]))

        obs = [ObstacleObservation(1, "obstacle", t, "confirmed", (view(rig["cam0"], [0, 1, 2]),
                                                                    view(rig["cam1"], [0, 1, 2]))),
               ObstacleObservation(2, "obstacle", t, "confirmed", (view(rig["cam1"], [10, 11, 12]),))]
        fus.step(obs, k, t)
        expect = {c.name: T_W_B.t + T_W_B.R @ c.T_C_B.inverse().t for c in rig}
        for tid, cams in ((1, ("cam0", "cam1")), (2, ("cam1",))):
            sg = fus._tracks[tid].history[-1]
            assert tuple(v.camera for v in sg.views) == cams
            for v in sg.views:
                np.testing.assert_allclose(v.c_W, expect[v.camera], atol=1e-12)
            np.testing.assert_allclose(sg.c0, expect[cams[0]], atol=1e-12)
            assert sg.f0[0] >= 0 and len(sg.f0) == len(cams)
    # cam0 and cam1 sit 0.30 m apart: c0 of the stereo track is cam0's, not cam1's
    assert abs(np.linalg.norm(np.subtract(fus._tracks[1].history[-1].c0, expect["cam1"])) - 0.30) < 1e-9
