"""Information per second, not per frame (``FusionSettings.measurement_correlation_s``): a track's
measurements come from the same tracked features, whose errors are correlated over ~0.1-0.4 s
(renderer truth, docs/ARCHITECTURE.md "Measurements per second at 100 fps"), so a stationary point
seen at 100 Hz over the same seconds as at 30 Hz carries about the same evidence. Expected values
from the closed form: n independent updates of noise R give a sigma ~ sqrt(R / n); with R scaled
by tau / dt, 100 Hz for a second is 100 / 3 updates of R against 30 at 30 Hz (ratio ~0.95), without
it 100 against 30 (~0.55). The same for a feature's rays in the static-point sums (``_FeatureRays``):
a ray less than tau after the row's last one counts dt / tau of a ray."""

from __future__ import annotations

import math

import numpy as np
import pytest

from estimators.cameras import Equidistant
from estimators.egomotion import ConstantVelocity
from estimators.fusion import FusionSettings, ObstacleFusion, _FeatureRays
from estimators.records import CameraView, ObstacleObservation
from estimators.rig import mono_forward_rig, stereo_forward_rig

MODEL = Equidistant.from_deg_per_px(0.15, 1280, 1280)
TAU = FusionSettings().measurement_correlation_s


def _unit(v):
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


def _filter_sigma(fps: float, settings: FusionSettings, seconds: float = 1.5) -> float:
    """Range sigma of a mono track without member features (its filter's own sigma: representative
    bearings fused every frame) on a static point 12 m ahead, 4 m to the side, flown past at 5 m/s
    for ``seconds``, exact bearings at sigma 2e-3 rad."""
    rig = mono_forward_rig(MODEL)
    ego = ConstantVelocity(5.0)
    fus = ObstacleFusion(rig, ego, settings)
    p = np.array([12.0, 4.0, 0.5])
    cam = rig[0]
    rep = None
    for k in range(int(round(seconds * fps)) + 1):
        t = k / fps
        T_C_W = cam.T_C_B @ ego.pose_at(t).inverse()
        view = CameraView("cam0", _unit(T_C_W.apply(p)), [0, 0], 2e-3)
        (rep,) = fus.step([ObstacleObservation(5, k, t, "confirmed", (view,))], k, t)
    assert rep.range_m is not None and rep.range_sigma_m is not None
    return rep.range_sigma_m


def test_a_filtered_static_point_at_30_and_100_hz_converges_to_about_the_same_sigma():
    s = FusionSettings()
    r = _filter_sigma(100.0, s) / _filter_sigma(30.0, s)
    assert 0.8 < r < 1.15, r
    off = FusionSettings(measurement_correlation_s=0.0)
    assert _filter_sigma(100.0, off) / _filter_sigma(30.0, off) < 0.7  # (per frame: 3.3x the updates)


def test_a_mono_track_just_initialised_at_30_and_100_hz_has_about_the_same_sigma():
    # half a second in (initialised at ~0.22 s from the longest baseline, the sightings between
    # the pair replayed as bearing updates): the replay weighs each sighting by its time since the
    # one before as the filter's updates do; at 100 fps unweighted it was 3.3x the 30-fps evidence
    # (the ratio 0.77, and 0.87 a second later)
    s = FusionSettings()
    r = _filter_sigma(100.0, s, 0.5) / _filter_sigma(30.0, s, 0.5)
    assert 0.85 < r < 1.1, r
    off = FusionSettings(measurement_correlation_s=0.0)
    assert _filter_sigma(100.0, off, 0.5) / _filter_sigma(30.0, off, 0.5) < 0.7


def _stereo_sigma(fps: float, settings: FusionSettings, seconds: float = 1.0) -> float:
    """Range sigma of a stereo track without member features (the two cameras' representative
    bearings triangulated and fused as a point every frame) on a static point 6 m ahead, 1 m to the
    side, the rig flying at 2 m/s (0.3 m baseline), exact bearings at sigma 2e-3 rad."""
    rig = stereo_forward_rig(MODEL, 0.3)
    ego = ConstantVelocity(2.0)
    fus = ObstacleFusion(rig, ego, settings)
    p = np.array([6.0, 1.0, 0.2])
    rep = None
    for k in range(int(round(seconds * fps)) + 1):
        t = k / fps
        T_W_B = ego.pose_at(t)
        views = tuple(CameraView(c.name, _unit((c.T_C_B @ T_W_B.inverse()).apply(p)), [0, 0], 2e-3)
                      for c in rig)
        (rep,) = fus.step([ObstacleObservation(5, k, t, "confirmed", views)], k, t)
    assert rep.range_m is not None and rep.range_sigma_m is not None
    return rep.range_sigma_m


def test_a_stereo_fixed_static_point_at_30_and_100_hz_has_about_the_same_sigma():
    s = FusionSettings()
    r = _stereo_sigma(100.0, s) / _stereo_sigma(30.0, s)
    off = FusionSettings(measurement_correlation_s=0.0)
    r_off = _stereo_sigma(100.0, off) / _stereo_sigma(30.0, off)
    assert 0.8 < r < 1.15, r
    assert r_off < 0.7, r_off


def _point_sigma(fps: float, correlation_s: float, seconds: float = 1.0) -> float:
    """Range sigma (per unit bearing sigma) of a static point 10 m ahead, 3 m to the side, from a
    camera flying along x at 5 m/s, every ray exact, one per frame at fps, 0.5 s forgetting: the
    first-order sigma sqrt(D2) sqrt(u^T A^-1 u) of ``_features_batch`` from the store's sums."""
    p = np.array([10.0, 3.0, 0.0])
    fs = _FeatureRays(capacity=2)
    n = int(round(seconds * fps)) + 1
    rows = None
    for k in range(n):
        t = k / fps
        c = np.array([5.0 * t, 0.0, 0.0])
        b = _unit(p - c)[None]
        if rows is None:
            rows = fs.rows(np.array([7]), b)
        fs.add(rows, b, c[None], t, 0.5, unique=True, correlation_s=correlation_s)
    A = fs.A[rows[0]]  # (the depth factor sqrt(D2) is the same at both rates: left out)
    u = _unit(p - np.array([5.0 * (n - 1) / fps, 0.0, 0.0]))
    return float(np.sqrt(u @ np.linalg.inv(A) @ u))


def test_a_ray_within_tau_of_the_last_counts_as_dt_over_tau():
    # two rays 0.01 s apart, 0.5 s forgetting: n = exp(-0.01 / 0.5) * 1 + 0.01 / tau (the first
    # ray of a new row counts 1, whatever the time since t = 0)
    fs = _FeatureRays(capacity=2)
    b = np.array([[0.0, 0.0, 1.0]])
    rows = fs.rows(np.array([3]), b)
    fs.add(rows, b, np.zeros((1, 3)), 5.0, 0.5, unique=True, correlation_s=TAU)
    assert fs.n[rows[0]] == 1.0
    fs.add(rows, b, np.array([[0.1, 0.0, 0.0]]), 5.01, 0.5, unique=True, correlation_s=TAU)
    assert fs.n[rows[0]] == pytest.approx(math.exp(-0.01 / 0.5) + 0.01 / TAU, rel=1e-12)
    # the slide test's short-memory sums (a test of the newest rays, not a sigma) count each ray 1
    fs = _FeatureRays(capacity=2)
    rows = fs.rows(np.array([3]), b)
    for t, cx in ((5.0, 0.0), (5.01, 0.1)):
        fs.add(rows, b, np.array([[cx, 0.0, 0.0]]), t, 0.5, short_memory_s=0.1, correlation_s=TAU)
    assert fs.S_new[rows[0], 17] == pytest.approx(math.exp(-0.01 / 0.1) + 1.0, rel=1e-12)
    assert fs.n[rows[0]] == pytest.approx(math.exp(-0.01 / 0.5) + 0.01 / TAU, rel=1e-12)
    # rays tau or more apart count 1 each: the sums are those without the rule
    fs, fs0 = _FeatureRays(capacity=2), _FeatureRays(capacity=2)
    r, r0 = fs.rows(np.array([3]), b), fs0.rows(np.array([3]), b)
    for t, cx in ((5.0, 0.0), (5.04, 0.1), (5.07, 0.2)):
        fs.add(r, b, np.array([[cx, 0.0, 0.0]]), t, 0.5, unique=True, correlation_s=TAU)
        fs0.add(r0, b, np.array([[cx, 0.0, 0.0]]), t, 0.5, unique=True, correlation_s=0.0)
    assert np.array_equal(fs.S[r], fs0.S[r0])


def test_30_fps_rays_are_counted_as_before():
    # tau is below the 30-fps frame interval (timestamps k / 30 rounded to 1e-9 s included): the
    # sums are bit-identical to those without the rule
    p = np.array([10.0, 3.0, 0.0])
    a, b0 = _FeatureRays(capacity=2), _FeatureRays(capacity=2)
    ra = rb = None
    for k in range(31):
        t = round(k / 30.0, 9)
        c = np.array([5.0 * t, 0.0, 0.0])
        b = _unit(p - c)[None]
        if ra is None:
            ra, rb = a.rows(np.array([1]), b), b0.rows(np.array([1]), b)
        a.add(ra, b, c[None], t, 0.5, unique=True, correlation_s=TAU)
        b0.add(rb, b, c[None], t, 0.5, unique=True, correlation_s=0.0)
    assert np.array_equal(a.S[: a.size], b0.S[: b0.size])


def test_a_static_point_seen_at_30_and_100_hz_has_about_the_same_sigma():
    # without the rule 100 Hz has 3.3x the rays, so its sigma is ~1 / sqrt(3.3) = 0.55 of 30 Hz's;
    # with it each 100-Hz ray counts 0.01 / tau = 1/3, 33 rays a second against 30: ratio ~0.95
    s30 = _point_sigma(30.0, TAU)
    s100 = _point_sigma(100.0, TAU)
    assert 0.85 < s100 / s30 < 1.1
    assert _point_sigma(100.0, 0.0) / _point_sigma(30.0, 0.0) < 0.6  # (per frame: the old count)


def _mono_init_scales(fps: float) -> list[float]:
    """The scales (``_repeat_scale``) of every bearing update ``_init_mono`` makes for a track seen
    by both cameras of a stereo rig whose stereo fixes are all refused (stereo_max_rel_sigma 1e-9),
    so it is initialised from the mono pair; the point and flight as in ``_stereo_sigma``."""
    rig = stereo_forward_rig(MODEL, 0.3)
    ego = ConstantVelocity(2.0)
    fus = ObstacleFusion(rig, ego, FusionSettings(stereo_max_rel_sigma=1e-9))
    p = np.array([6.0, 1.0, 0.2])
    scales: list[float] = []
    inside = [False]
    bearing_update, init_mono = fus._bearing_update, fus._init_mono

    def spy_update(tr, v, scale=1.0):
        if inside[0]:
            scales.append(scale)
        return bearing_update(tr, v, scale)

    def spy_init(*a):
        inside[0] = True
        try:
            return init_mono(*a)
        finally:
            inside[0] = False

    fus._bearing_update, fus._init_mono = spy_update, spy_init
    for k in range(int(fps) + 1):
        t = k / fps
        T_W_B = ego.pose_at(t)
        views = tuple(CameraView(c.name, _unit((c.T_C_B @ T_W_B.inverse()).apply(p)), [0, 0], 2e-3)
                      for c in rig)
        fus.step([ObstacleObservation(5, k, t, "confirmed", views)], k, t)
        if scales:
            break
    return scales


def test_a_mono_initialisation_weighs_its_last_frames_other_camera_as_the_replay():
    # the sightings replayed between the triangulated pair are weighed by their time since the one
    # before; the initialising frame's other camera was fused at full weight (scale 1) though 0.01 s
    # after the last replayed frame at 100 fps: 3x (tau / dt) as the frame's update in _process
    at100 = _mono_init_scales(100.0)
    assert len(at100) >= 3 and at100 == pytest.approx([TAU / 0.01] * len(at100)), at100
    at30 = _mono_init_scales(30.0)  # (<= 1 / tau fps: every update at full weight, as before)
    assert at30 and all(c == 1.0 for c in at30), at30
