"""feature_point off (the features' median range along the representative ray) with tracks of
different feature counts in one frame."""

from __future__ import annotations

import numpy as np
import pytest


def test_feature_point_off_with_a_track_of_too_few_features_beside_a_ranged_one():
    # two tracks in one frame: track 3 sees five static corners at 12-13 m, track 4 one corner
    # (fewer than feature_min_count: no feature range). With feature_point off, track 3 is ranged
    # by the median of its features' points (true ranges worked from the geometry below), and
    # track 4's lone feature must not shift the per-feature arrays (db064e9 filtered the range
    # sigmas of the tracks with enough features only in the feature_point branch: IndexError)
    from estimators.cameras import Equidistant
    from estimators.egomotion import ConstantVelocity
    from estimators.fusion import FusionSettings, ObstacleFusion
    from estimators.records import CameraView, ObstacleObservation
    from estimators.rig import mono_forward_rig

    feats_a = np.array([[12.0, 4.0, 0.4], [12.3, 4.2, -0.3], [12.6, 3.7, 0.1], [12.9, 4.4, 0.3],
                        [13.2, 3.9, -0.2]])
    rep_a = np.array([12.6, 4.05, 0.05])
    feats_b = np.array([[10.0, -3.0, 0.2]])
    rep_b = feats_b[0]
    model = Equidistant.from_deg_per_px(0.15, 1280, 1280)
    rig = mono_forward_rig(model)
    ego = ConstantVelocity(5.0)
    settings = FusionSettings(feature_point=False, feature_inner_half=False)
    assert settings.feature_min_count > len(feats_b)
    fus = ObstacleFusion(rig, ego, settings)
    sigma = 5e-4

    def bearing(cam, T_W_B, p_W):
        p_C = (cam.T_C_B @ T_W_B.inverse()).apply(p_W)
        return p_C / np.linalg.norm(p_C)

    n = 45  # 1.5 s at 30 fps
    for k in range(n + 1):
        t = k / 30.0
        T_W_B = ego.pose_at(t)
        obs = []
        for oid, feats, rep, f0 in ((3, feats_a, rep_a, 0), (4, feats_b, rep_b, 100)):
            views = tuple(CameraView(c.name, bearing(c, T_W_B, rep), [0, 0], sigma,
                                     feature_ids=np.arange(f0, f0 + len(feats)),
                                     feature_b_C=np.array([bearing(c, T_W_B, f) for f in feats]))
                          for c in rig)
            obs.append(ObstacleObservation(oid, k, t, "confirmed", views))
        reports = {r.id: r for r in fus.step(obs, k, t)}
    T_W_B = ego.pose_at(n / 30.0)
    rng_true = np.sort(np.linalg.norm(feats_a - T_W_B.t, axis=1))
    assert reports[3].range_m == pytest.approx(rng_true[2], rel=0.01)  # the median of five
