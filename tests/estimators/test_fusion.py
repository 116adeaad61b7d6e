"""Tests of estimators.fusion (the per-obstacle EKF) on closed-form flights.

Truth comes from the scene geometry written here (positions, poses, ranges by hand); bearings are
made from it with seeded noise. Nothing expected is computed with the code under test.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from estimators.cameras import DoubleSphere, Equidistant
from estimators.egomotion import ConstantVelocity, TumTrajectory
from estimators.errors import ConfigError, InputError
from estimators.fusion import FusionSettings, ObstacleFusion
from estimators.fusion_stats import chi2_cdf, chi2_ppf, nees_interval
from estimators.records import CameraView, ObstacleObservation
from estimators.rig import mono_forward_rig, stereo_forward_rig
from estimators.se3 import Pose

MODEL = Equidistant.from_deg_per_px(0.15, 1280, 1280)  # 0.15 deg/px, 192-degree circle
FPS = 30.0


def _bearing(rig_cam, T_W_B: Pose, p_W: np.ndarray, sigma: float, rng) -> np.ndarray:
    """Unit bearing of p_W in the camera frame, turned by isotropic noise of sigma rad."""
    p_C = (rig_cam.T_C_B @ T_W_B.inverse()).apply(p_W)
    b = p_C / np.linalg.norm(p_C)
    if sigma > 0:
        e = rng.normal(scale=sigma, size=3)
        b = b + e - (e @ b) * b
        b /= np.linalg.norm(b)
    return b


def _fly(rig, ego, p0_W, v_W=None, *, T_s=1.5, sigma=1e-3, seed=0, settings=None, cams=None):
    """Run a fusion over a flight; returns [(t, report, true range from the body origin, truth p_W)]."""
    rng = np.random.default_rng(seed)
    v_W = np.zeros(3) if v_W is None else v_W
    fus = ObstacleFusion(rig, ego, settings or FusionSettings())
    out = []
    for k in range(int(round(T_s * FPS)) + 1):
        t = k / FPS
        T_W_B = ego.pose_at(t)
        p_W = p0_W + v_W * t
        views = tuple(
            CameraView(c.name, _bearing(c, T_W_B, p_W, sigma, rng), np.zeros(2), max(sigma, 1e-4))
            for c in rig if cams is None or c.name in cams
        )
        reps = fus.step([ObstacleObservation(7, k, t, "confirmed", views)], k, t)
        assert len(reps) == 1
        out.append((t, reps[0], float(np.linalg.norm(p_W - T_W_B.t)), p_W, fus))
    return out


# ----------------------------------------------------------------------------- mono, stationary
def test_stationary_point_straight_flight_converges_within_sigma():
    rig = mono_forward_rig(MODEL)
    ego = ConstantVelocity(5.0)  # body along +x at 5 m/s from the origin, level
    p_W = np.array([14.0, 4.0, 1.5])
    run = _fly(rig, ego, p_W, sigma=1e-3)
    ranged = [(t, r, rt) for t, r, rt, _, _ in run if r.range_m is not None]
    assert ranged, "never initialised"
    t_first, r_first, _ = ranged[0]
    assert t_first < 0.5  # 1 degree of parallax at ~14 m and 5 m/s takes ~0.1 s
    t, r, rt, _, _ = run[-1]
    # at t = 1.5 s the body is at x = 7.5: true range sqrt(6.5^2 + 4^2 + 1.5^2)
    assert rt == pytest.approx(math.sqrt(6.5**2 + 16 + 2.25), abs=1e-9)
    assert abs(r.range_m - rt) <= 3 * r.range_sigma_m
    assert abs(r.range_m - rt) / rt < 0.02
    assert r.range_sigma_m < 0.5 * r_first.range_sigma_m  # the sigma shrinks as parallax grows
    assert r.source == "mono"
    assert r.velocity_world_mps is None  # mono never reports a velocity
    assert r.range_min_m is not None and r.range_min_m <= rt
    assert r.range_max_m is None or rt <= r.range_max_m
    # body-frame position: p_B = p_W - (7.5, 0, 0) (level flight along x)
    np.testing.assert_allclose(r.position_body_m, [6.5, 4.0, 1.5], atol=0.15)


def test_noise_free_flight_converges_tightly():
    run = _fly(mono_forward_rig(MODEL), ConstantVelocity(5.0), np.array([20.0, -6.0, 2.0]), sigma=0.0)
    t, r, rt, _, _ = run[-1]
    assert abs(r.range_m - rt) / rt < 2e-3


def test_obstacle_beyond_90_degrees_off_the_optical_axis():
    # 100 degrees off the forward axis (behind-left), still in the 192-degree lens: tangent-plane
    # residuals work with any ray direction
    rig = mono_forward_rig(MODEL)
    a = math.radians(95.0)
    p_W = np.array([6.0 * math.cos(a), 6.0 * math.sin(a), 0.0])
    run = _fly(rig, ConstantVelocity(3.0), p_W, T_s=1.0, sigma=5e-4)
    t, r, rt, _, _ = run[-1]
    assert r.range_m is not None and abs(r.range_m - rt) / rt < 0.03


def test_ttc_closed_form_for_a_stationary_obstacle():
    # body at 5 m/s along x, obstacle at (20, 0.5, 0): closest approach at t* = 20 / 5 = 4 s
    run = _fly(mono_forward_rig(MODEL), ConstantVelocity(5.0), np.array([20.0, 2.0, 0.0]), sigma=0.0)
    t, r, *_ = run[-1]
    assert r.ttc_s == pytest.approx(4.0 - t, rel=0.02)


def test_miss_distance_of_an_obstacle_passing_abeam_and_then_receding():
    # body at 5 m/s along x past a stationary point 2 m to its left (20, 2, 0): the closest approach
    # misses by 2 m; after passing it (3 m to the left of (3, 3, 0.5), passed at t = 0.6 s) the
    # obstacle recedes: no time to closest approach and no distance at it, while still ranged
    run = _fly(mono_forward_rig(MODEL), ConstantVelocity(5.0), np.array([20.0, 2.0, 0.0]), sigma=1e-3)
    ranged = [r for _t, r, *_ in run if r.range_m is not None]
    assert ranged
    for r in ranged:
        assert r.ttc_s is not None
        assert abs(r.miss_distance_m - 2.0) <= 3.0 * r.miss_distance_sigma_m
    r = ranged[-1]
    assert r.miss_distance_m == pytest.approx(2.0, rel=0.01)
    assert 0 < r.miss_distance_sigma_m < 0.05
    assert r.to_json()["miss_distance_m"] == r.miss_distance_m
    run = _fly(mono_forward_rig(MODEL), ConstantVelocity(5.0), np.array([3.0, 3.0, 0.5]), sigma=1e-3)
    for t, r, *_ in run:
        assert (r.miss_distance_m is None) == (r.ttc_s is None) == (r.miss_distance_sigma_m is None)
        if t < 0.5 and r.ttc_s is not None:
            assert r.miss_distance_m == pytest.approx(math.hypot(3.0, 0.5), rel=0.05)
        if t > 0.7:  # past it
            assert r.range_m is not None and r.ttc_s is None and r.miss_distance_m is None


def test_miss_distance_of_a_head_on_obstacle_is_zero_within_its_sigma():
    # a 0.30 m stereo pair at 3 m/s straight at a stationary point 8 m ahead: the miss is 0; each
    # report's miss is a distance from 0 no larger than 2 of its sigmas, and the sigma (the
    # filter's lateral position and velocity uncertainty at t*) shrinks as the range does
    run = _fly(stereo_forward_rig(MODEL, 0.30), ConstantVelocity(3.0), np.array([8.0, 0.0, 0.0]), sigma=1e-3)
    reps = [r for _t, r, *_ in run if r.miss_distance_m is not None]
    assert len(reps) >= 20
    for r in reps:
        assert 0.0 <= r.miss_distance_m <= 2.0 * r.miss_distance_sigma_m
    assert reps[-1].miss_distance_sigma_m < 0.6 * reps[0].miss_distance_sigma_m
    assert reps[-1].miss_distance_m < 0.1


def test_hover_mono_range_is_unobservable_with_bounds():
    run = _fly(mono_forward_rig(MODEL), ConstantVelocity(0.0), np.array([8.0, 2.0, 1.0]), T_s=1.0)
    for _t, r, _rt, _, _ in run[1:]:
        assert r.range_m is None and r.range_sigma_m is None and r.position_body_m is None
        assert "baseline" in r.unobservable_reason
        # zero baseline, zero max speed: the point can be anywhere on the ray
        assert r.range_min_m == pytest.approx(0.0, abs=1e-9) and r.range_max_m is None
        assert r.source == "bounds"
    j = run[-1][1].to_json()
    assert j["range_m"] is None and j["source"] == "bounds"


SLIDE_FEATS_W = np.array([14.0, 4.0, 0.5]) + np.array(
    [[0, 0.3, 0.3], [0, -0.3, 0.3], [0.2, 0, -0.3], [-0.2, 0.2, 0], [0, 0, 0.4], [0.1, -0.2, -0.1]]
)


def _slide_run(settings: FusionSettings):
    """Six fixed feature points around (14, 4, 0.5) while the representative point slides 1.2 m up
    the object over a 5 m/s flight. Returns (fusion, last report)."""
    rng = np.random.default_rng(3)
    rig = mono_forward_rig(MODEL)
    ego = ConstantVelocity(5.0)
    fus = ObstacleFusion(rig, ego, settings)
    sigma = 5e-4
    for k in range(46):
        t = k / FPS
        T_W_B = ego.pose_at(t)
        rep_W = np.array([14.0, 4.0, 0.5 + 0.8 * (t - 0.75)])
        fb = np.array([_bearing(rig[0], T_W_B, f, sigma, rng) for f in SLIDE_FEATS_W])
        view = CameraView("cam0", _bearing(rig[0], T_W_B, rep_W, sigma, rng), [0, 0], sigma,
                          feature_ids=np.arange(6), feature_b_C=fb)
        (r,) = fus.step([ObstacleObservation(5, k, t, "confirmed", (view,))], k, t)
    return fus, r


def test_feature_range_sigma_widens_by_one_plus_k_over_n():
    # (the range on the representative ray, feature_point off) six features, inner half n = 3:
    # k = 3 doubles the sigma (1 + 3 / 3), the range is unchanged
    f0, _ = _slide_run(FusionSettings(feature_small_n_inflate=0.0, feature_point=False))
    f3, _ = _slide_run(FusionSettings(feature_small_n_inflate=3.0, feature_point=False))
    z0, s0, n0 = f0._tracks[5].feature_range
    z3, s3, n3 = f3._tracks[5].feature_range
    assert n0 == n3 == 3
    assert z3 == z0
    assert s3 == pytest.approx(2.0 * s0, rel=1e-12)


def test_member_features_range_a_track_whose_representative_bearing_slides():
    # six fixed feature points around (14, 4, 0.5); the representative point slides 1.2 m up the
    # object over the flight (as a tracker's centroid does when members come and go): its bearing
    # parallax alone is biased, the features' multi-view triangulations are not
    _, r = _slide_run(FusionSettings())
    # truth: the median range of the feature points from the body at x = 5 * 1.5 = 7.5
    o = np.array([7.5, 0.0, 0.0])
    true_r = float(np.median(np.linalg.norm(SLIDE_FEATS_W - o, axis=1)))
    assert r.source == "mono"
    assert abs(r.range_m - true_r) / true_r < 0.03
    assert abs(r.range_m - true_r) <= 3 * r.range_sigma_m


# ----------------------------------------------------------------------------- stereo, moving
def test_stereo_constant_velocity_obstacle_velocity_recovered():
    rig = stereo_forward_rig(MODEL, 0.30)
    v_true = np.array([-1.0, 1.5, 0.0])
    run = _fly(rig, ConstantVelocity(3.0), np.array([7.0, -3.0, 0.5]), v_true, T_s=1.5, sigma=5e-4)
    t, r, rt, _, _ = run[-1]
    assert "stereo" in r.source
    assert r.velocity_world_mps is not None
    speed = float(np.linalg.norm(v_true))
    assert abs(r.speed_mps - speed) / speed < 0.10
    dh = math.atan2(r.velocity_world_mps[1], r.velocity_world_mps[0]) - math.atan2(1.5, -1.0)
    assert abs(math.degrees(math.atan2(math.sin(dh), math.cos(dh)))) < 10.0
    assert abs(r.range_m - rt) / rt < 0.04


def test_stereo_hover_stationary_point_first_frame_range():
    # one frame of a 0.30 m stereo pair, noise-free: range from the body origin (midpoint of the pair)
    rig = stereo_forward_rig(MODEL, 0.30)
    run = _fly(rig, ConstantVelocity(0.0), np.array([3.0, 0.4, -0.2]), T_s=0.0, sigma=0.0)
    _, r, rt, _, _ = run[0]
    assert rt == pytest.approx(math.sqrt(9 + 0.16 + 0.04))
    assert r.range_m == pytest.approx(rt, rel=1e-6)
    assert r.source == "stereo"


def _wall_stereo_run(shared_ids: bool, frames: int = 10):
    """A hovering 0.30 m stereo pair looks at eight corners on a wall at x = 5 m; each camera's
    representative point lies on a different part of the wall (the ghost of centroid stereo)."""
    rng = np.random.default_rng(11)
    rig = stereo_forward_rig(MODEL, 0.30)
    ego = ConstantVelocity(0.0)
    feats_W = np.array([[5.0, y, z] for y in (0.6, 1.0, 1.4, 1.8) for z in (-0.3, 0.3)])
    rep_W = {"cam0": np.array([5.0, 1.2, 0.1]), "cam1": np.array([5.0, 0.8, -0.1])}
    fus = ObstacleFusion(rig, ego, FusionSettings())
    sigma = 5e-4
    for k in range(frames):
        t = k / FPS
        T_W_B = ego.pose_at(t)
        views = []
        for c in rig:
            ids = np.arange(8) if shared_ids or c.name == "cam0" else np.arange(100, 108)
            fb = np.array([_bearing(c, T_W_B, f, sigma, rng) for f in feats_W])
            views.append(CameraView(c.name, _bearing(c, T_W_B, rep_W[c.name], sigma, rng), [0, 0], sigma,
                                    feature_ids=ids, feature_b_C=fb))
        (r,) = fus.step([ObstacleObservation(3, k, t, "confirmed", tuple(views))], k, t)
    return r


def test_stereo_from_physical_point_feature_ids_has_no_ghost():
    # truth: the wall point on cam0's representative ray, (5, 1.2, 0.1), from the body origin
    true_r = math.sqrt(25.0 + 1.44 + 0.01)
    r = _wall_stereo_run(shared_ids=True)
    assert "stereo" in r.source
    assert abs(r.range_m - true_r) / true_r < 0.02
    assert abs(r.range_m - true_r) <= 3 * r.range_sigma_m
    # the same scene without shared ids: only the two representative rays, which cross at the
    # wrong depth (or not at all): no range within 10 %
    r_ghost = _wall_stereo_run(shared_ids=False)
    assert r_ghost.range_m is None or abs(r_ghost.range_m - true_r) / true_r > 0.10


def _features_stereo_run(v_W: np.ndarray, T_s: float = 1.5, reports: list | None = None):
    """A 0.30 m stereo pair flying at 3 m/s sees six corners of an object near (7, -3, 0.5) that
    moves at v_W; both cameras list the corners under the same (physical-point) ids. Every
    frame's (t_s, report, pose T_W_B) is appended to reports when given."""
    rng = np.random.default_rng(21)
    rig = stereo_forward_rig(MODEL, 0.30)
    ego = ConstantVelocity(3.0)
    # a compact object (corners within 0.12 m of its centre): its range is the centre's within 3 %
    offsets = 0.3 * np.array([[0, 0.3, 0.3], [0, -0.3, 0.3], [0.2, 0, -0.3], [-0.2, 0.2, 0], [0, 0, 0.4],
                              [0.1, -0.2, -0.1]])
    fus = ObstacleFusion(rig, ego, FusionSettings())
    sigma = 5e-4
    for k in range(int(round(T_s * FPS)) + 1):
        t = k / FPS
        T_W_B = ego.pose_at(t)
        centre = np.array([7.0, -3.0, 0.5]) + v_W * t
        views = []
        for c in rig:
            fb = np.array([_bearing(c, T_W_B, centre + o, sigma, rng) for o in offsets])
            views.append(CameraView(c.name, _bearing(c, T_W_B, centre, sigma, rng), [0, 0], sigma,
                                    feature_ids=np.arange(6), feature_b_C=fb))
        (r,) = fus.step([ObstacleObservation(4, k, t, "confirmed", tuple(views))], k, t)
        if reports is not None:
            reports.append((t, r, T_W_B))
    true_r = float(np.linalg.norm(centre - T_W_B.t))
    return r, true_r, fus


def test_stereo_features_static_and_moving_obstacles():
    # static: the features' rays of both cameras and all frames meet (static points): the range
    # comes from them; moving at 1.8 m/s: they do not (chi test), the filter tracks the velocity
    reps: list = []
    r, true_r, fus = _features_stereo_run(np.zeros(3), reports=reps)
    assert "stereo" in r.source
    assert abs(r.range_m - true_r) / true_r < 0.03
    x, P, _ = fus.state(4)  # a measured velocity, zero within its sigma (chi2_3(0.999))
    assert float(x[3:] @ np.linalg.solve(P[3:, 3:], x[3:])) <= 16.27
    # the REPORTS of a static obstacle: no speed, or under 0.2 m/s, in every frame; and the time to
    # closest approach of a static point passed by a drone flying at 3 m/s along x: its x offset / 3
    assert all(rp.speed_mps is None or rp.speed_mps < 0.2 for _t, rp, _T in reps)
    assert r.ttc_s is not None and r.ttc_s == pytest.approx((7.0 - 3.0 * 1.5) / 3.0, rel=0.05)
    v_true = np.array([-1.0, 1.5, 0.0])
    reps = []
    r, true_r, _fus = _features_stereo_run(v_true, reports=reps)
    assert "stereo" in r.source
    assert abs(r.range_m - true_r) / true_r < 0.04
    assert r.velocity_world_mps is not None
    speed = float(np.linalg.norm(v_true))
    dh = math.atan2(r.velocity_world_mps[1], r.velocity_world_mps[0]) - math.atan2(1.5, -1.0)
    assert abs(math.degrees(math.atan2(math.sin(dh), math.cos(dh)))) < 10.0
    assert abs(r.speed_mps - speed) / speed < 0.10
    # one velocity per report: each ttc_s is the closed form from the report's own position and
    # velocity and the drone's (3, 0, 0) m/s, t* = -r.w / |w|^2, w = v - v_drone
    n_v = 0
    for _t, rp, T_W_B in reps:
        if rp.velocity_world_mps is None or rp.position_body_m is None:
            continue
        n_v += 1
        r_W = T_W_B.R @ np.asarray(rp.position_body_m)
        w = np.asarray(rp.velocity_world_mps) - np.array([3.0, 0.0, 0.0])
        closing = float(r_W @ w) < 0
        assert (rp.ttc_s is not None) == closing
        if closing:
            assert rp.ttc_s == pytest.approx(-float(r_W @ w) / float(w @ w), rel=1e-6)
    assert n_v >= 10


def test_group_median_matches_numpy_median():
    from estimators.fusion import _group_median

    rng = np.random.default_rng(5)
    g = rng.integers(0, 6, size=50)
    v = rng.normal(size=50)
    med = _group_median(g, v, 7)
    for k in range(7):
        expect = float(np.median(v[g == k])) if np.any(g == k) else 0.0
        assert med[k] == pytest.approx(expect)


# ----------------------------------------------------------------------------- bounds
def test_bounds_contain_truth_for_random_moving_obstacles():
    rng = np.random.default_rng(42)
    rig = mono_forward_rig(MODEL)
    sigma = 1e-3
    n_reports = n_inside = 0
    for _ in range(300):
        v_drone = rng.uniform(1.0, 10.0)
        ego = ConstantVelocity(v_drone)
        az = math.radians(rng.uniform(-80, 80))
        el = math.radians(rng.uniform(-30, 30))
        rng_m = rng.uniform(3.0, 30.0)
        p0 = rng_m * np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
        d = rng.normal(size=3)
        v = rng.uniform(0.0, 1.0) * v_drone * d / np.linalg.norm(d)  # no faster than the drone
        fus = ObstacleFusion(rig, ego, FusionSettings())
        for k, t in enumerate((0.0, 0.1, 0.2, 0.3)):
            T_W_B = ego.pose_at(t)
            p = p0 + v * t
            b = _bearing(rig[0], T_W_B, p, sigma, rng)
            view = CameraView("cam0", b, [0, 0], sigma)
            (r,) = fus.step([ObstacleObservation(1, k, t, "confirmed", (view,))], k, t)
            if k == 0:
                assert r.range_min_m is None  # one sighting: no bound yet
                continue
            true_r = float(np.linalg.norm(p - T_W_B.t))
            n_reports += 1
            n_inside += r.range_min_m <= true_r and (r.range_max_m is None or true_r <= r.range_max_m)
    assert n_reports == 900
    assert n_inside / n_reports >= 0.99


def test_bounds_constrain_a_mono_estimate_of_a_moving_obstacle():
    # obstacle receding along the flight at the drone's speed: the stationary hypothesis is wrong,
    # the bounds (which hold the truth) keep the estimate inside them
    rig = mono_forward_rig(MODEL)
    run = _fly(rig, ConstantVelocity(4.0), np.array([10.0, 3.0, 0.0]), np.array([-4.0, 0.0, 0.0]),
               T_s=1.5, sigma=5e-4)
    for _t, r, rt, _, _ in run[5:]:
        assert r.range_min_m <= rt and (r.range_max_m is None or rt <= r.range_max_m)
        if r.range_m is not None:
            assert r.range_min_m * 0.97 <= r.range_m
            assert r.range_max_m is None or r.range_m <= r.range_max_m * 1.03


# ----------------------------------------------------------------------------- consistency
def test_nees_monte_carlo_within_95_percent_interval():
    rig = mono_forward_rig(MODEL)
    ego = ConstantVelocity(5.0)
    p_W = np.array([12.0, -5.0, 1.0])
    nees = []
    for seed in range(30):
        run = _fly(rig, ego, p_W, T_s=1.0, sigma=1e-3, seed=seed)
        _, _, _, p_true, fus = run[-1]
        x, P, _ = fus.state(7)
        e = x[:3] - p_true
        nees.append(float(e @ np.linalg.solve(P[:3, :3], e)))
    lo, hi = nees_interval(3, len(nees), 0.95)
    assert lo <= float(np.mean(nees)) <= hi


def test_gated_outlier_is_counted_not_fused():
    rig = mono_forward_rig(MODEL)
    ego = ConstantVelocity(5.0)
    p_W = np.array([15.0, 4.0, 0.0])
    run = _fly(rig, ego, p_W, T_s=1.0, sigma=1e-3)
    fus = run[-1][4]
    x_before = fus.state(7)[0].copy()
    k = 31
    t = k / FPS
    T_W_B = ego.pose_at(t)
    b = _bearing(rig[0], T_W_B, p_W + np.array([0.0, 0.0, 3.0]), 0.0, None)  # 3 m off: ~20 sigma
    (r,) = fus.step([ObstacleObservation(7, k, t, "confirmed", (CameraView("cam0", b, [0, 0], 1e-3),))], k, t)
    assert r.gated == run[-1][1].gated + 1
    x_after = fus.state(7)[0]
    # only the prediction moved it (stationary hypothesis: the velocity is ~0)
    assert np.linalg.norm(x_after[:3] - x_before[:3]) < 0.05


# ----------------------------------------------------------------------------- track lifetime
def test_lost_track_is_reported_once_then_removed():
    rig = mono_forward_rig(MODEL)
    run = _fly(rig, ConstantVelocity(5.0), np.array([15.0, 4.0, 0.0]), T_s=0.5, sigma=1e-3)
    fus = run[-1][4]
    k = 16
    t = k / FPS
    (r,) = fus.step([ObstacleObservation(7, k, t, "lost", ())], k, t)
    assert r.status == "lost" and r.id == 7
    assert 7 not in fus.track_ids
    assert fus.step([], k + 1, (k + 1) / FPS) == []


def test_unobserved_track_ends_after_lost_after_s():
    rig = mono_forward_rig(MODEL)
    run = _fly(rig, ConstantVelocity(5.0), np.array([15.0, 4.0, 0.0]), T_s=0.5, sigma=1e-3,
               settings=FusionSettings(lost_after_s=0.2))
    fus = run[-1][4]
    assert fus.step([], 16, 16 / FPS) == []  # 0.033 s unseen: kept
    reps = fus.step([], 22, 22 / FPS)  # 0.233 s unseen: ended
    assert [(r.id, r.status) for r in reps] == [(7, "lost")]
    assert fus.step([], 23, 23 / FPS) == []


# ----------------------------------------------------------------------------- bad input
def _obs(k, t, cam="cam0"):
    return [ObstacleObservation(1, k, t, "confirmed", (CameraView(cam, [0.0, 0.0, 1.0], [0, 0], 1e-3),))]


@pytest.mark.parametrize(
    "times, egomotion, message",
    [
        ([0.0, 0.1, 0.1], ConstantVelocity(2.0), r"frame 2: t_s=0\.100000 s repeats .* \(frame 1\)"),
        ([0.0, 0.2, 0.1], ConstantVelocity(2.0), r"frame 2: t_s=0\.100000 s goes back .* \(frame 1\)"),
        ([0.0, 0.1, float("nan")], ConstantVelocity(2.0), r"frame 2: t_s must be finite"),
        (
            [0.0, 0.5, 1.5],
            TumTrajectory(np.array([0.0, 1.0]), np.zeros((2, 3)), np.array([[0, 0, 0, 1.0]] * 2), "traj.tum"),
            r"frame 2 \(t_s=1\.500000 s\): ego-motion: traj\.tum: time 1\.500000 s is outside",
        ),
    ],
    ids=["duplicated", "decreasing", "nan", "trajectory-gap"],
)
def test_bad_time_input(times, egomotion, message):
    fus = ObstacleFusion(mono_forward_rig(MODEL), egomotion, FusionSettings())
    for k, t in enumerate(times[:-1]):
        fus.step(_obs(k, t), k, t)
    k = len(times) - 1
    with pytest.raises(InputError, match=message):
        fus.step([] if math.isnan(times[-1]) else _obs(k, times[-1]), k, times[-1])


def test_bad_observation_input():
    fus = ObstacleFusion(mono_forward_rig(MODEL), ConstantVelocity(1.0), FusionSettings())
    with pytest.raises(InputError, match="unknown camera 'cam9'"):
        fus.step(_obs(0, 0.0, cam="cam9"), 0, 0.0)
    with pytest.raises(InputError, match="expected the frame's t_s"):
        fus.step(_obs(1, 0.5), 1, 0.4)
    with pytest.raises(InputError, match="appears twice"):
        fus.step(_obs(2, 0.6) + _obs(2, 0.6), 2, 0.6)


@pytest.mark.parametrize(
    "kw", [{"max_accel_mps2": -1.0}, {"gate_probability": 1.0}, {"lost_after_s": 0.0},
           {"max_speed_mps": float("nan")}, {"reinit_after_gated": 0}, {"feature_point_quantile": 1.5}]
)
def test_settings_validation(kw):
    with pytest.raises(ConfigError, match="FusionSettings"):
        FusionSettings(**kw)


@pytest.mark.parametrize(
    "kw, expected",
    [({"feature_point": 2.5}, "feature_point: expected true or false"),
     ({"feature_ranging": 1}, "feature_ranging: expected true or false"),
     ({"feature_avoid_outline": "yes"}, "feature_avoid_outline: expected true or false"),
     ({"feature_min_count": 2.5}, "feature_min_count: expected an integer"),
     ({"max_accel_mps2": True}, "max_accel_mps2: expected a finite number")],
)
def test_settings_refuse_wrong_types(kw, expected):
    # a switch is true or false, a count an integer: 2.5 read as truthy (or int(2.5) = 2) would
    # run another configuration than the one asked for, silently
    with pytest.raises(ConfigError, match=expected):
        FusionSettings(**kw)
    assert FusionSettings(feature_point=False, feature_min_count=3.0).feature_min_count == 3


# ----------------------------------------------------------------------------- chi-square helpers
@pytest.mark.parametrize(
    "p, k, x",  # textbook table values (Abramowitz & Stegun 26.8; any chi-square table)
    [(0.95, 1, 3.841), (0.95, 2, 5.991), (0.95, 3, 7.815), (0.99, 2, 9.210), (0.999, 3, 16.266),
     (0.975, 6, 14.449), (0.025, 3, 0.216), (0.05, 10, 3.940), (0.95, 300, 341.395)],
)
def test_chi2_ppf_table_values(p, k, x):
    assert chi2_ppf(p, k) == pytest.approx(x, abs=2e-3)
    if k <= 200:
        assert chi2_cdf(x, k) == pytest.approx(p, abs=5e-4)


def test_nees_interval_bar_shalom_example():
    # Bar-Shalom et al. (2001) sec. 5.4.2: 50 runs, 2 dof -> [1.5, 2.6] (74.2 / 50, 129.6 / 50)
    lo, hi = nees_interval(2, 50, 0.95)
    assert lo == pytest.approx(1.5, abs=0.02) and hi == pytest.approx(2.6, abs=0.02)


# ----------------------------------------------------------------------- member-set replacement
def _takeover_run(settings: FusionSettings, frames_a: int = 30, frames_b: int = 12):
    """A hovering 0.30 m stereo pair: track 9's two member corners (ids 0, 1, both cameras) lie at
    range 3 m from the body origin; from frame ``frames_a`` on the id's members are two other
    corners (ids 10, 11) of a point at 4.5 m in nearly the same direction (the front end handing
    the id to another set of points). Returns [(frame, report, true range)]."""
    rng = np.random.default_rng(5)
    rig = stereo_forward_rig(MODEL, 0.30)
    ego = ConstantVelocity(0.0)
    fus = ObstacleFusion(rig, ego, settings)
    sigma = 5e-4

    def corners(r):  # two corners at exactly range r from the body origin (0, 0, 0)
        d = np.array([[1.0, 0.30, 0.05], [1.0, 0.34, -0.05]])
        return r * d / np.linalg.norm(d, axis=1)[:, None]

    out = []
    for k in range(frames_a + frames_b):
        t = k / FPS
        T_W_B = ego.pose_at(t)
        r_true, ids = (3.0, np.array([0, 1])) if k < frames_a else (4.5, np.array([10, 11]))
        pts = corners(r_true)
        views = tuple(
            CameraView(c.name, _bearing(c, T_W_B, pts.mean(axis=0), sigma, rng), [0, 0], sigma,
                       feature_ids=ids,
                       feature_b_C=np.array([_bearing(c, T_W_B, p, sigma, rng) for p in pts]))
            for c in rig)
        (r,) = fus.step([ObstacleObservation(9, k, t, "confirmed", views)], k, t)
        out.append((k, r, r_true))
    return out


def test_track_whose_members_are_replaced_reports_the_new_range_honestly():
    # closed form: every corner of a frame lies at exactly r_true from the body origin, so the
    # reported range (a corner's stereo point) must be r_true within its sigma at every report
    run = _takeover_run(FusionSettings())
    k_switch = 30
    before = [r for k, r, _ in run if 20 <= k < k_switch]
    assert all(r.range_m is not None and abs(r.range_m - 3.0) <= 3 * r.range_sigma_m for r in before)
    after = [(r, rt) for k, r, rt in run if k >= k_switch]
    ranged = [(r, rt) for r, rt in after if r.range_m is not None]
    assert len(ranged) >= len(after) - 1  # re-initialised from the new corners' stereo at once
    for r, rt in ranged:  # the new range at once, within 3 sigma, and a sigma that says something
        assert abs(r.range_m - rt) <= 3 * r.range_sigma_m, (r.range_m, r.range_sigma_m)
        assert r.range_sigma_m < 0.1 * rt
    r_last, rt_last = ranged[-1]
    assert abs(r_last.range_m - rt_last) / rt_last < 0.02
    # (this passes without the restart too: the feature stereo fix re-anchors the position on the
    # new corner; the old state's VELOCITY is what the restart must drop, tested below)


def _velocity_takeover_run(settings: FusionSettings, frames_a: int = 36, frames_b: int = 30):
    """A hovering 0.30 m stereo pair: track 9's six member corners (ids 0-5, both cameras) move at
    1 m/s along y (across the line of sight, 4 m ahead) for frames_a frames, so its velocity is
    measured; then the id's members are six other corners (ids 10-15) of a STATIC object 0.1 m
    beside where the first one is then (the front end handing the id to a neighbour). Feature
    noise at the fusion's model, feature_point_sigma_k x feature_sigma_rad. Returns
    [(frame, report, T_W_B)]."""
    rng = np.random.default_rng(5)
    rig = stereo_forward_rig(MODEL, 0.30)
    ego = ConstantVelocity(0.0)
    fus = ObstacleFusion(rig, ego, settings)
    sig = settings.feature_point_sigma_k * settings.feature_sigma_rad
    off = 0.1 * np.array([[0, 0.6, 0.5], [0, -0.6, 0.5], [0.3, 0, -0.6], [-0.3, 0.5, 0], [0, 0, 0.8],
                          [0.2, -0.4, -0.3]])
    v = np.array([0.0, 1.0, 0.0])
    c0 = np.array([4.0, -0.5, 0.2])
    c_static = c0 + v * (frames_a / FPS) + np.array([0.0, 0.1, 0.0])
    out = []
    for k in range(frames_a + frames_b):
        t = k / FPS
        T_W_B = ego.pose_at(t)
        if k < frames_a:
            pts, ids = c0 + v * t + off, np.arange(6)
        else:
            pts, ids = c_static + off[::-1], np.arange(10, 16)
        views = tuple(
            CameraView(c.name, _bearing(c, T_W_B, pts.mean(axis=0), sig, rng), [0, 0], sig, feature_ids=ids,
                       feature_b_C=np.array([_bearing(c, T_W_B, p, sig, rng) for p in pts]))
            for c in rig)
        (r,) = fus.step([ObstacleObservation(9, k, t, "confirmed", views)], k, t)
        out.append((k, r, T_W_B))
    return out


def _across_ray_speed(r, T_W_B) -> float:
    """|v - (v.u) u| (m/s) of a report's velocity, u the unit line of sight in W: the component the
    stereo points measure ~40x better than the along-ray one."""
    u = T_W_B.R @ np.asarray(r.position_body_m)
    u /= np.linalg.norm(u)
    v = np.asarray(r.velocity_world_mps)
    return float(np.linalg.norm(v - (v @ u) * u))


def test_member_replacement_drops_the_old_points_velocity():
    # the static neighbour's reports must not carry the mover's 1 m/s across the line of sight (the
    # across-ray velocity sigma of one 0.1 s measurement is ~0.05 m/s here: s_f d / sqrt 2 = 7 mm per
    # point and end); without the restart (member_reset_frac = 1) the old velocity is reported for
    # ~0.5 s, until the gated feature velocities restart the filter (measured: 1.05 -> 0.85 m/s)
    k_switch = 36
    before = [(r, T) for k, r, T in _velocity_takeover_run(FusionSettings()) if 24 <= k < k_switch]
    assert all(r.velocity_world_mps is not None and _across_ray_speed(r, T) > 0.7 for r, T in before)
    after = [(r, T) for k, r, T in _velocity_takeover_run(FusionSettings()) if k >= k_switch]
    with_v = [_across_ray_speed(r, T) for r, T in after if r.velocity_world_mps is not None]
    assert with_v and max(with_v) < 0.3, with_v
    old = [(r, T) for k, r, T in _velocity_takeover_run(FusionSettings(member_reset_frac=1.0))
           if k >= k_switch]
    assert max(_across_ray_speed(r, T) for r, T in old if r.velocity_world_mps is not None) > 0.7


def test_gated_restart_drops_the_old_sightings_and_bounds():
    # mono, flying at 3 m/s along x, no member features: track 9's representative ray is on a point
    # A at (12, 3, 0.5) for 1 s, then on another point B at (14, 5.5, -0.5) (the id handed over
    # without features to tell). The bearings of B are gated against A's state; after
    # reinit_after_gated of them the filter restarts. From then on every range must be B's within
    # 3 sigma: pairing A's old sightings with B's bearings (the restart keeping them) triangulated
    # B at 2.8 m with a 0.01 m sigma (measured), and A's bounds do not bound B
    rng = np.random.default_rng(7)
    rig = mono_forward_rig(MODEL)
    ego = ConstantVelocity(3.0)
    s = FusionSettings()
    fus = ObstacleFusion(rig, ego, s)
    A, B = np.array([12.0, 3.0, 0.5]), np.array([14.0, 5.5, -0.5])
    reports = []
    for k in range(70):
        t = k / FPS
        T_W_B = ego.pose_at(t)
        p = A if k < 30 else B
        v = CameraView("cam0", _bearing(rig[0], T_W_B, p, 5e-4, rng), [0, 0], 5e-4)
        (r,) = fus.step([ObstacleObservation(9, k, t, "confirmed", (v,))], k, t)
        reports.append((k, r, float(np.linalg.norm(p - T_W_B.t))))
    restarted = [k for k, r, _ in reports if r.unobservable_reason and "restarted" in r.unobservable_reason]
    assert restarted and restarted[0] == 30 + s.reinit_after_gated - 1  # the 5th gated bearing of B
    after = [(r, rt) for k, r, rt in reports if k >= restarted[0]]
    assert len(restarted) == 1  # restarted once, then B's own sightings range it
    ranged = [(r, rt) for r, rt in after if r.range_m is not None]
    assert len(ranged) >= 20
    for r, rt in ranged:
        assert abs(r.range_m - rt) <= 3 * r.range_sigma_m, (r.range_m, r.range_sigma_m, rt)
    for r, rt in after:  # bounds, when given, contain B's range (A's old sightings are gone)
        if r.range_max_m is not None:
            assert r.range_min_m <= rt <= r.range_max_m


def test_feature_sigma_scales_with_the_rigs_pixel_size():
    # the pixel part of a feature's bearing error: at the reference focal length (px/rad) the
    # setting is used as it is; a rig of half that focal length (pixels twice as wide) gets twice
    # the angle, one of 1 / 1.6 of it 1.6 times it; finer pixels (1.5 times the focal length) keep
    # the setting; None keeps it on every rig
    f_ref = FusionSettings().feature_sigma_focal_px
    ego = ConstantVelocity(3.0)

    def rig(f):
        return stereo_forward_rig(Equidistant(fx=f, fy=f, cx=319.5, cy=179.5, width=640, height=360), 0.30)

    s = FusionSettings(feature_sigma_rad=1e-3)
    assert ObstacleFusion(rig(f_ref), ego, s).settings.feature_sigma_rad == 1e-3
    assert ObstacleFusion(rig(f_ref / 2), ego, s).settings.feature_sigma_rad == pytest.approx(2e-3, rel=1e-12)
    assert ObstacleFusion(rig(f_ref / 1.6), ego, s).settings.feature_sigma_rad == pytest.approx(
        1.6e-3, rel=1e-12)
    assert ObstacleFusion(rig(1.5 * f_ref), ego, s).settings.feature_sigma_rad == 1e-3
    # a lens whose px per rad at the centre is not fx: DoubleSphere's projection on the axis is
    # u - cx = fx x / (alpha d2 + (1 - alpha)(xi + z)), d2 = xi + 1 there, so du/dx = fx / (1 + xi)
    ds = DoubleSphere(fx=f_ref, fy=f_ref, cx=319.5, cy=179.5, width=640, height=360, xi=0.5, alpha=0.6)
    assert ObstacleFusion(stereo_forward_rig(ds, 0.30), ego, s).settings.feature_sigma_rad == pytest.approx(
        1.5e-3, rel=1e-9)
    s0 = FusionSettings(feature_sigma_rad=1e-3, feature_sigma_focal_px=None)
    assert ObstacleFusion(rig(f_ref / 2), ego, s0).settings.feature_sigma_rad == 1e-3
    with pytest.raises(ConfigError):
        FusionSettings(feature_sigma_focal_px=0.0)
