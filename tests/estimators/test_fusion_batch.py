"""The vectorised helpers of estimators.fusion against independent references (numpy, closed forms)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from estimators.fusion import (
    _REPORT_DEFAULTS,
    _adjugate_det3,
    _FeatureRays,
    _largest_depth_cluster,
    _new_full_report,
    _noisy_bound_rays_batch,
    _ray_covariance,
    _ray_covariances,
)
from estimators.records import TrackReport
from tests.estimators.fusion_helpers import noisy_bearing


def test_adjugate_det3_matches_numpy_inverse_and_determinant():
    rng = np.random.default_rng(1)
    A = rng.normal(size=(50, 3, 3))
    A = A @ A.transpose(0, 2, 1) + 0.1 * np.eye(3)
    adj, det = _adjugate_det3(A)
    np.testing.assert_allclose(det, np.linalg.det(A), rtol=1e-10)
    np.testing.assert_allclose(adj / det[:, None, None], np.linalg.inv(A), rtol=1e-8, atol=1e-12)


def test_ray_covariances_match_the_single_point_form():
    rng = np.random.default_rng(2)
    d = rng.normal(size=(7, 3)) * 5
    s_along = rng.uniform(0.01, 1.0, 7)
    s_rad = rng.uniform(1e-4, 1e-2, 7)
    R = _ray_covariances(d, s_along, s_rad)
    for k in range(7):
        np.testing.assert_allclose(R[k], _ray_covariance(d[k], s_along[k], s_rad[k]), rtol=1e-12, atol=1e-18)
        u = d[k] / np.linalg.norm(d[k])
        assert math.isclose(u @ R[k] @ u, s_along[k] ** 2 + 1e-12, rel_tol=1e-9)


def test_noisy_bound_rays_turn_ray_b_and_ray_a_by_delta_in_the_epipolar_plane():
    c_a = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    c_b = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 0.0]])  # second pair: zero baseline
    b_a = np.array([[0.6, 0.1, 0.8], [0.0, 0.0, 1.0]])
    b_b = np.array([[0.0, 0.0, 1.0], [0.0, math.sin(0.1), math.cos(0.1)]])
    delta = np.array([0.01, 0.2])
    own, ca, ba, cb, bb = _noisy_bound_rays_batch(c_a, b_a, c_b, b_b, delta)
    rows0 = np.flatnonzero(own == 0)
    # b_b and b_b +-delta with the projected ray a; the projected ray a +-delta with b_b (ray a is
    # ~0.64 rad away: not within delta)
    assert len(rows0) == 5
    n = np.array([0.0, -1.0, 0.0])  # (c_b - c_a) x b_b = x x z = -y
    ang = sorted(math.atan2(float(n @ np.cross(b_b[0], d)), float(b_b[0] @ d)) for d in bb[rows0])
    np.testing.assert_allclose(ang, [-0.01, 0.0, 0.0, 0.0, 0.01], atol=1e-12)
    a_in = np.array([0.6, 0.0, 0.8])  # ray a projected into the plane y = 0
    ang = sorted(math.atan2(float(n @ np.cross(a_in, d)), float(a_in @ d)) for d in ba[rows0])
    np.testing.assert_allclose(ang, [-0.01, 0.0, 0.0, 0.0, 0.01], atol=1e-12)
    np.testing.assert_allclose(bb[rows0] @ n, 0.0, atol=1e-12)
    np.testing.assert_allclose(ba[rows0] @ n, 0.0, atol=1e-12)  # ray a projected into the plane
    np.testing.assert_allclose(np.linalg.norm(ba[rows0], axis=1), 1.0)
    # zero baseline: plane of the two bearings, ray b within delta of ray a: ray a itself is added
    rows1 = np.flatnonzero(own == 1)
    assert len(rows1) == 6
    assert any(np.allclose(d, b_a[1]) for d in bb[rows1])
    np.testing.assert_array_equal(ca[own == 1], c_a[[1] * 6])
    np.testing.assert_array_equal(cb[own == 1], c_b[[1] * 6])


def test_noisy_bounds_cover_an_error_of_ray_a_at_the_speed_limit():
    # planar, A = 0, B = (5, 0, 0), D = 5 m (the obstacle as fast as the drone, 1 s). The obstacle was
    # at P_a = 5.59 (cos a, sin a), a = atan2(1, 5.5), and moved D across ray a: P_b = P_a + D (-sin a,
    # cos a), exactly D from ray a, so its depth on ray b is an end of the exact interval. Ray a is
    # seen 1 mrad too far from P_b (a - 1e-3): P_b is then D + 5.59 sin(1e-3) = D + 5.6 mm from it,
    # outside the exact interval of the two rays as seen. Ray b as seen is the truth's. The rays are
    # 83.5 deg apart, so turning ray b by delta = 4 sqrt(2) mrad changes the distance of its point at
    # r = 5.93 m from line a by only r delta cos(83.5 deg) = 5.93 * 5.66e-3 * 0.113 = 3.8 mm, short of
    # the 5.6 mm; turning ray a by delta back past its 1 mrad error covers it
    from estimators import geometry as g

    a = math.atan2(1.0, 5.5)
    P_a = math.hypot(5.5, 1.0) * np.array([math.cos(a), math.sin(a), 0.0])
    P_b = P_a + 5.0 * np.array([-math.sin(a), math.cos(a), 0.0])
    c_a, c_b = np.zeros(3), np.array([5.0, 0.0, 0.0])
    b_a = np.array([math.cos(a - 1e-3), math.sin(a - 1e-3), 0.0])
    b_b = (P_b - c_b) / np.linalg.norm(P_b - c_b)
    r_true = float(np.linalg.norm(P_b - c_b))
    exact = g.moving_obstacle_bounds(c_a, b_a, c_b, b_b, 5.0)
    assert exact.range_max_m < r_true  # the exact interval of the rays as seen misses the truth
    own, ca, ba, cb, bb = _noisy_bound_rays_batch(c_a[None], b_a[None], c_b[None], b_b[None],
                                                  np.array([4.0 * math.sqrt(2.0) * 1e-3]))
    r_min, r_max, _, _, ok = g.moving_obstacle_bounds_batch(ca, ba, cb, bb, np.full(len(own), 5.0), cb)
    assert ok.all()
    assert r_min.min() <= r_true <= r_max.max()


def test_feature_rows_first_appearance_and_prune():
    fr = _FeatureRays(capacity=2)
    b = np.tile([0.0, 0.0, 1.0], (5, 1))
    r = fr.rows(np.array([40, 7, 40, 9, 7]), b)
    np.testing.assert_array_equal(r, [0, 1, 0, 2, 1])
    r = fr.rows(np.array([9, 100, 40]), b[:3])
    np.testing.assert_array_equal(r, [2, 3, 0])
    fr.add(np.array([0, 1, 2, 3]), b[:4], np.zeros((4, 3)), t_s=0.0)
    fr.add(np.array([0, 3]), b[:2], np.zeros((2, 3)), t_s=1.0, unique=True)
    np.testing.assert_array_equal(fr.n[:4], [2, 1, 1, 2])
    fr.prune(1.0, max_unseen_s=0.5)  # ids 7 and 9 dropped: rows of 40 and 100 compacted
    assert fr.size == 2
    np.testing.assert_array_equal(fr.rows(np.array([100, 40]), b[:2]), [1, 0])
    np.testing.assert_array_equal(fr.n[:2], [2, 2])
    np.testing.assert_array_equal(fr.rows(np.array([7]), b[:1]), [2])  # a forgotten id is new again
    assert fr.n[2] == 0


def test_fast_report_equals_the_constructor():
    kw = dict(id=3, status="confirmed", camera=["cam0", "cam1"], bearing_body=np.array([1.0, 0.0, 0.0]),
              range_m=4.0, range_sigma_m=0.2, range_min_m=1.0, range_max_m=None, label="orb", gated=2,
              nis=1.5, innovation=np.array([1e-3, -2e-3]), attributes={"a": 1},
              position_body_m=np.array([4.0, 0.0, 0.0]), source="mono+stereo", ttc_s=3.0)
    ref = TrackReport(**kw)
    # the hot path's: a dict of every field (the defaults updated with the given ones)
    full = _new_full_report({**_REPORT_DEFAULTS, **kw})
    assert type(full) is TrackReport
    assert full == ref and full.to_json() == ref.to_json()
    assert set(vars(full)) == set(vars(ref))


# ----------------------------------------------------------------- feature_point (closed form)
def _features_run(settings, feats_W, rep_W, T_s=1.5, sigma=5e-4, seed=5, rig_kind="mono", speed=5.0,
                  feature_cams=None):
    """A straight flight (speed m/s along x) sees fixed feature points feats_W (N, 3); the track's
    representative point is rep_W (3,) (not one of them). Returns the last report and the body
    origin of the last frame."""
    from estimators.cameras import Equidistant
    from estimators.egomotion import ConstantVelocity
    from estimators.fusion import FusionSettings, ObstacleFusion
    from estimators.records import CameraView, ObstacleObservation
    from estimators.rig import mono_forward_rig, stereo_forward_rig

    model = Equidistant.from_deg_per_px(0.15, 1280, 1280)
    rig = mono_forward_rig(model) if rig_kind == "mono" else stereo_forward_rig(model, 0.30)
    ego = ConstantVelocity(speed)
    rng = np.random.default_rng(seed)
    fus = ObstacleFusion(rig, ego, settings or FusionSettings())

    bearing = noisy_bearing(rng, sigma)

    n = int(round(T_s * 30.0))
    for k in range(n + 1):
        t = k / 30.0
        T_W_B = ego.pose_at(t)
        views = tuple(CameraView(c.name, bearing(c, T_W_B, rep_W), [0, 0], sigma,
                                 feature_ids=np.arange(len(feats_W)),
                                 feature_b_C=np.array([bearing(c, T_W_B, f) for f in feats_W]))
                      if feature_cams is None or c.name in feature_cams
                      else CameraView(c.name, bearing(c, T_W_B, rep_W), [0, 0], sigma)
                      for c in rig)
        (r,) = fus.step([ObstacleObservation(3, k, t, "confirmed", views)], k, t)
    return r, ego.pose_at(n / 30.0)


def test_feature_point_reports_the_median_features_own_point():
    # five corners of a box face at 12-13 m; the representative point (a centroid of members at
    # different depths) lies 1 m in front of the face, off every corner. The report must be the
    # corner whose range is the (lower) median of the inner ones, along its own bearing.
    feats_W = np.array([[12.0, 4.0, 0.4], [12.3, 4.2, -0.3], [12.6, 3.7, 0.1], [12.9, 4.4, 0.3],
                        [13.2, 3.9, -0.2]])
    rep_W = np.array([11.0, 4.05, 0.05])
    from estimators.fusion import FusionSettings

    r, T_W_B = _features_run(FusionSettings(feature_inner_half=False), feats_W, rep_W)
    rng_true = np.linalg.norm(feats_W - T_W_B.t, axis=1)
    k = int(np.argsort(rng_true)[(len(rng_true) - 1) // 2])  # lower median (odd: the median)
    assert r.range_m == pytest.approx(rng_true[k], rel=0.01)
    b_true = T_W_B.R.T @ (feats_W[k] - T_W_B.t) / rng_true[k]
    assert math.degrees(math.acos(min(1.0, float(b_true @ r.bearing_body)))) < 0.2
    # sigma >= the floor, and honest
    assert r.range_sigma_m >= FusionSettings().feature_range_floor_frac * r.range_m * 0.999
    assert abs(r.range_m - rng_true[k]) <= 3 * r.range_sigma_m
    # feature_point off: the same median range, but along the representative ray
    r_old, _ = _features_run(FusionSettings(feature_inner_half=False, feature_point=False), feats_W, rep_W)
    b_rep = T_W_B.R.T @ (rep_W - T_W_B.t)
    b_rep /= np.linalg.norm(b_rep)
    assert math.degrees(math.acos(min(1.0, float(b_rep @ r_old.bearing_body)))) < 0.2


def test_hover_bounds_of_a_moving_obstacle_are_inconsistent_not_zero():
    # hovering drone (max speed = its own speed = 0) and an obstacle crossing at 1 m/s, 5 m ahead:
    # the two rays leave one centre at different angles, so the only common point is the camera
    # itself. No range interval is consistent with "no faster than 0 m/s": no bounds (never
    # [0, 0], which the bound pseudo-measurement would turn into a 0 m range).
    from estimators.cameras import Equidistant
    from estimators.egomotion import ConstantVelocity
    from estimators.fusion import FusionSettings, ObstacleFusion
    from estimators.records import CameraView, ObstacleObservation
    from estimators.rig import mono_forward_rig

    rig = mono_forward_rig(Equidistant.from_deg_per_px(0.15, 1280, 1280))
    ego = ConstantVelocity(0.0)
    fus = ObstacleFusion(rig, ego, FusionSettings())
    cam = rig[0]
    for k in range(20):
        t = k / 30.0
        p_W = np.array([5.0, -1.0 + 1.0 * t, 0.0])
        p_C = (cam.T_C_B @ ego.pose_at(t).inverse()).apply(p_W)
        view = CameraView("cam0", p_C / np.linalg.norm(p_C), [0, 0], 5e-4)
        (r,) = fus.step([ObstacleObservation(1, k, t, "confirmed", (view,))], k, t)
    assert r.range_m is None
    assert r.range_max_m is None and r.range_min_m is None
    assert r.unobservable_reason  # (why: the mono pair has zero baseline)


def test_moving_track_seen_by_one_camera_loses_its_range_after_moving_mono_max_s():
    # a stereo pair flying at 3 m/s ranges an obstacle crossing at 1.8 m/s (moving hypothesis);
    # then the second camera loses it. One bearing does not range a moving obstacle: the range
    # stays reported for moving_mono_max_s (0.3 s) after the last stereo fix, then is null.
    from estimators.cameras import Equidistant
    from estimators.egomotion import ConstantVelocity
    from estimators.fusion import FusionSettings, ObstacleFusion
    from estimators.records import CameraView, ObstacleObservation
    from estimators.rig import stereo_forward_rig

    rig = stereo_forward_rig(Equidistant.from_deg_per_px(0.15, 1280, 1280), 0.30)
    ego = ConstantVelocity(3.0)
    fus = ObstacleFusion(rig, ego, FusionSettings())
    rng = np.random.default_rng(8)
    v_W = np.array([-1.0, 1.5, 0.0])
    ranged = []
    for k in range(46):  # 1.5 s; cam1 sees it for the first 0.8 s only
        t = k / 30.0
        T_W_B = ego.pose_at(t)
        p_W = np.array([8.0, -3.0, 0.3]) + v_W * t
        views = []
        for c in rig:
            if c.name == "cam1" and t > 0.8:
                continue
            p_C = (c.T_C_B @ T_W_B.inverse()).apply(p_W)
            b = p_C / np.linalg.norm(p_C) + rng.normal(scale=3e-4, size=3)
            views.append(CameraView(c.name, b / np.linalg.norm(b), [0, 0], 5e-4))
        (r,) = fus.step([ObstacleObservation(2, k, t, "confirmed", tuple(views))], k, t)
        ranged.append((t, r.range_m is not None))
    assert all(ok for t, ok in ranged if 0.3 <= t <= 0.8 + 0.3 - 1e-6)
    assert not any(ok for t, ok in ranged if t > 0.8 + 0.3 + 1e-6)


def test_largest_depth_cluster_keeps_each_groups_biggest_cluster():
    # group 0: 10, 10.5, 11 | 20, 21 (11 -> 20 is a gap > 30 %): the three near ones; group 1:
    # 5, 5.2 | 9, 9.5: two clusters of two, the nearer one; a masked-out entry is never kept
    g = np.array([0, 0, 0, 0, 0, 1, 1, 1, 1, 0])
    r = np.array([20.0, 10.0, 21.0, 10.5, 11.0, 9.0, 5.0, 9.5, 5.2, 10.2])
    m = np.array([True] * 9 + [False])
    out = _largest_depth_cluster(g, r, m, 0.3)
    assert out.tolist() == [False, True, False, True, True, False, True, False, True, False]


def _spread_case(ranges, cos_to_report, r_rep, var0, sigma_i=0.1):
    """_member_spread of one static track whose member points have ranges (n,) m and directions
    at the given cosines to the reported direction (each turned about z), reported range r_rep,
    variance so far var0 m^2, every member's range sigma sigma_i m."""
    from estimators.fusion import FusionSettings, ObstacleFusion, _Track

    fus = ObstacleFusion.__new__(ObstacleFusion)
    fus.settings = FusionSettings()
    tr = _Track(4, "box")
    fus._gidx = {4: 0}
    ang = np.arccos(np.asarray(cos_to_report, dtype=float))
    dirs = np.stack([np.cos(ang), np.sin(ang), np.zeros_like(ang)], axis=1)
    n = len(ranges)
    fus._members_ls = (np.zeros(n, dtype=np.int64), np.asarray(ranges, dtype=float), dirs,
                       np.full(n, sigma_i))
    fus._members_st = None
    return float(fus._member_spread([tr], np.array([r_rep]), np.array([[1.0, 0.0, 0.0]]),
                                    np.array([var0]))[0])


def test_member_disagreement_closed_form():
    # seven members, the reported point at 10 m (variance 0.01 m^2), every member sigma 0.1 m; the
    # six nearest the reported direction (cosines 1 ... 0.995; the 0.9 one is left out):
    # 10, 10.2, 9.9, 20, 20.5, 21 -> median (10.2 + 20) / 2 = 15.1, d = 5.1,
    # extra^2 = 5.1^2 - 0.01 - (pi / 2) 0.1^2 / 6 = 26.01 - 0.01 - 0.0026180 = 25.9973820
    ranges = [10.0, 10.2, 9.9, 20.0, 20.5, 21.0, 10.1]
    cos = [1.0, 0.999, 0.998, 0.997, 0.996, 0.995, 0.9]
    assert _spread_case(ranges, cos, 10.0, 0.01) == pytest.approx(math.sqrt(25.9973820), rel=1e-6)
    # members that agree: 10, 10.2, 9.9, 10.1, 10.05, 9.95 -> median 10.025, d^2 = 0.000625, below
    # the noise 0.01 + 0.0026: nothing added
    assert _spread_case([10.0, 10.2, 9.9, 10.1, 10.05, 9.95], cos[:6], 10.0, 0.01) == 0.0
    # the far members beyond the six nearest do not count: 10, 10.2, 9.9, 10.1, 10.05, 9.95 nearest,
    # 30 and 31 farther
    assert _spread_case([10.0, 10.2, 9.9, 10.1, 10.05, 9.95, 30.0, 31.0], cos[:6] + [0.9, 0.8],
                        10.0, 0.01) == 0.0


@pytest.mark.parametrize("n_box, n_wall", [(6, 5), (8, 3)])
def test_members_at_another_depth_away_from_the_reported_point_do_not_widen_it(n_box, n_wall):
    # n_box corners of a box face at 12-13 m and n_wall features of a wall at ~30 m in one track
    # (the wall ~14 degrees away from the box as seen at the end). The report is a box corner and
    # its nearest members are box corners: they agree on its depth, so its sigma is the one
    # without the disagreement term (member_spread_weight 0).
    from estimators.fusion import FusionSettings

    box = np.array([[12.0, 4.0, 0.4], [12.3, 4.2, -0.3], [12.6, 3.7, 0.1], [12.9, 4.4, 0.3],
                    [13.2, 3.9, -0.2], [12.4, 3.8, 0.5], [12.8, 4.1, -0.4], [12.2, 4.3, 0.0]])[:n_box]
    wall = np.array([[30.0, 9.0, 0.5], [30.0, 10.0, -0.5], [30.0, 11.0, 0.2], [30.0, 9.5, -1.0],
                     [30.0, 10.5, 1.0]])[:n_wall]
    r_off, _ = _features_run(FusionSettings(feature_inner_half=False, member_spread_weight=0.0),
                             np.vstack([box, wall]), np.array([11.0, 4.05, 0.05]))
    r, _ = _features_run(FusionSettings(feature_inner_half=False), np.vstack([box, wall]),
                         np.array([11.0, 4.05, 0.05]))
    assert r.range_m == pytest.approx(r_off.range_m)  # the same point: the box's
    assert r.range_m < 14.0
    assert r.range_sigma_m == pytest.approx(r_off.range_sigma_m, rel=0.05)


def test_stereo_velocity_from_the_shared_features_own_displacements():
    # a stereo rig flies along x at 3 m/s; six feature points of an obstacle 4 m ahead move together
    # at v = (0, -1.2, 0.3) m/s and both cameras list them under shared ids. The velocity is reported
    # only once the features' displacements measured it (not from the prior), and then it is
    # within 10 % / 10 degrees of v.
    from estimators.cameras import Equidistant
    from estimators.egomotion import ConstantVelocity
    from estimators.fusion import FusionSettings, ObstacleFusion
    from estimators.records import CameraView, ObstacleObservation
    from estimators.rig import stereo_forward_rig

    model = Equidistant.from_deg_per_px(0.15, 1280, 1280)
    rig = stereo_forward_rig(model, 0.30)
    ego = ConstantVelocity(3.0)
    fus = ObstacleFusion(rig, ego, FusionSettings())
    rng = np.random.default_rng(7)
    v = np.array([0.0, -1.2, 0.3])
    p0 = np.array([[6.0, 1.5, 0.2], [6.1, 1.7, -0.1], [6.0, 1.3, 0.0], [6.2, 1.6, 0.3], [6.1, 1.4, -0.2],
                   [6.0, 1.8, 0.1]])
    sigma = 5e-4

    bearing = noisy_bearing(rng, sigma)

    first_v = None
    for k in range(46):
        t = k / 30.0
        T_W_B = ego.pose_at(t)
        pts = p0 + v * t
        views = tuple(CameraView(c.name, bearing(c, T_W_B, pts.mean(axis=0)), [0, 0], sigma,
                                 feature_ids=np.arange(len(pts)),
                                 feature_b_C=np.array([bearing(c, T_W_B, q) for q in pts])) for c in rig)
        (r,) = fus.step([ObstacleObservation(3, "obstacle", t, "confirmed", views)], k, t)
        if r.velocity_world_mps is not None and first_v is None:
            first_v = t
    assert first_v is not None and first_v >= FusionSettings().feature_velocity_lag_s - 1e-9
    ve = np.asarray(r.velocity_world_mps)
    assert abs(np.linalg.norm(ve) - np.linalg.norm(v)) <= 0.1 * np.linalg.norm(v)
    ang = math.degrees(math.acos(float(ve @ v) / (np.linalg.norm(ve) * np.linalg.norm(v))))
    assert ang <= 10.0


def test_posterior_sigma_closed_form():
    from estimators.fusion import _posterior_sigma

    # the conjugate (scaled inverse chi-square) estimate of a feature's noise variance factor:
    # a prior of nu0 dof at the nominal sigma_f (factor 1) pooled with the fit's own 2n - 3
    # residual dof at s2 = chi 2n / (2n - 3):  s2_post = (nu0 + 2n chi) / (nu0 + 2n - 3)
    # many rays (2n = 3e6): the prior does not count, s2_post = chi (to 1e-6)
    many = np.full(3, 1.5e6)
    out = _posterior_sigma(np.array([0.1, 0.1, 0.3]), np.array([1.0, 4.0, 0.25]), many, 3.0)
    np.testing.assert_allclose(out, [0.1, 0.2, 0.15], rtol=1e-5)
    # n = 3 rays, nu0 = 3: (3 + 6 chi) / 6; chi 0.5 is its expectation at the nominal noise
    # ((2n - 3) / 2n = 1/2): factor 1 for any nu0; chi 4: 27 / 6 = 4.5
    out = _posterior_sigma(np.array([0.1, 0.1, 0.1]), np.array([0.5, 0.5, 4.0]), np.array([3.0, 3.0, 3.0]),
                           3.0)
    np.testing.assert_allclose(out, [0.1, 0.1, 0.1 * math.sqrt(4.5)], rtol=1e-12)
    np.testing.assert_allclose(_posterior_sigma(np.array([0.1]), np.array([0.5]), np.array([3.0]), 0.0),
                               [0.1], rtol=1e-12)
    # a strong prior keeps the nominal noise whatever the fit says; nu0 = 0: the fit's own factor
    np.testing.assert_allclose(_posterior_sigma(np.array([0.1]), np.array([9.0]), np.array([4.0]), 1e12),
                               [0.1], rtol=1e-9)
    np.testing.assert_allclose(_posterior_sigma(np.array([0.1]), np.array([9.0]), np.array([4.0]), 0.0),
                               [0.1 * math.sqrt(9.0 * 8.0 / 5.0)], rtol=1e-12)
    # n = 1 ray (2n - 3 = -1): the denominator nu0 + 2n - 3 floored at 1; nu0 = 3: (3 + 2 chi) / 2
    out = _posterior_sigma(np.array([0.1, 0.1]), np.array([2.0, 2.0]), np.array([1.0, 1.0]), 3.0)
    np.testing.assert_allclose(out, [0.1 * math.sqrt(3.5)] * 2, rtol=1e-12)
