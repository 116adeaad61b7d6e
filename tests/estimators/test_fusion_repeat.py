"""Information per second, not per frame (``FusionSettings.measurement_correlation_s``): a track's
measurements come from the same tracked features, whose errors are correlated over ~0.1-0.4 s
(renderer truth, docs/ARCHITECTURE.md "Measurements per second at 100 fps"), so a stationary point
seen at 100 Hz over the same seconds as at 30 Hz carries about the same evidence. Expected values
from the closed form: n independent updates of noise R give a sigma ~ sqrt(R / n); with R scaled
by tau / dt, 100 Hz for a second is 100 / 3 updates of R against 30 at 30 Hz (ratio ~0.95), without
it 100 against 30 (~0.55)."""

from __future__ import annotations

import numpy as np

from estimators.cameras import Equidistant
from estimators.egomotion import ConstantVelocity
from estimators.fusion import FusionSettings, ObstacleFusion
from estimators.records import CameraView, ObstacleObservation
from estimators.rig import mono_forward_rig, stereo_forward_rig

MODEL = Equidistant.from_deg_per_px(0.15, 1280, 1280)


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
