"""The static-point fix on a stereo rig: its range sigma is stereo_point_sigma_k sqrt(s2) sigma_r,f
(plus the floor; on a mono rig with mono_point_sigma_k), sigma_r,f the first-order sigma of the
feature's least-squares point, s2 its noise variance factor (``_posterior_sigma``: exact rays miss by
0, so s2 = nu0 / (nu0 + 2n - 3), n the rays' forgetting weights summed). Expected values from the
definitions written here: the normal equations A = sum_i w_i (I - b_i b_i^T) of the feature's
rays from every camera of every frame, their forgetting weights w_i = exp(-(t - t_i) / memory) and
depths d_i = b_i . (p - c_i), summed by hand for a flight whose geometry is set by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from estimators.cameras import Equidistant
from estimators.egomotion import ConstantVelocity
from estimators.fusion import FusionSettings, ObstacleFusion
from estimators.records import CameraView, ObstacleObservation
from estimators.rig import mono_forward_rig, stereo_forward_rig

MODEL = Equidistant.from_deg_per_px(0.15, 1280, 1280)
FPS = 30.0
# six static points of one obstacle, 3 m ahead and 0.5 m to the left of the flight line
POINTS_W = np.array([3.0, 0.5, 0.0]) + np.array(
    [[0, 0, 0], [0, 0.15, 0.1], [0.1, -0.1, 0.15], [-0.05, 0.1, -0.15], [0.1, 0.05, -0.05], [0, -0.15, -0.1]])


def _unit(v):
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


def _run(settings: FusionSettings, frames: int = 16, mono: bool = False):
    """The stereo rig (baseline 0.3 m; ``mono``: its one forward camera) flies +x at 1.5 m/s; every
    point is seen by every camera with exact rays. Returns the last report and, per frame, its time,
    the body origin and each camera's centre and the points' unit bearings in W."""
    rig = mono_forward_rig(MODEL) if mono else stereo_forward_rig(MODEL, 0.30)
    ego = ConstantVelocity(1.5)
    fus = ObstacleFusion(rig, ego, settings)
    log = []
    for k in range(frames):
        t = k / FPS
        T_W_B = ego.pose_at(t)
        views, rays = [], []
        for c in rig:
            T_W_C = T_W_B @ c.T_C_B.inverse()
            c_W = T_W_C.t
            b_W = np.array([_unit(p - c_W) for p in POINTS_W])
            b_C = b_W @ T_W_C.R  # (rows: R_C_W b = R_W_C^T b)
            views.append(CameraView(c.name, _unit(b_C.mean(axis=0)), [0, 0], 1e-3,
                                    feature_ids=np.arange(len(POINTS_W)), feature_b_C=b_C))
            rays.append((c_W, b_W))
        (r,) = fus.step([ObstacleObservation(4, k, t, "confirmed", tuple(views))], k, t)
        log.append((t, T_W_B.t, rays))
    return r, log


def _first_order_sigma(j: int, log, sigma_f: float, memory_s: float) -> tuple[float, float]:
    """sigma_f sqrt(D2) sqrt(u^T A^-1 u) of point j from every ray of the flight (every camera), and
    the rays' forgetting weights summed (n)."""
    t_last, o, _ = log[-1]
    p = POINTS_W[j]
    A = np.zeros((3, 3))
    wd2 = wsum = 0.0
    for t, _o, rays in log:
        w = math.exp(-(t_last - t) / memory_s)
        for c_W, b_W in rays:
            b = b_W[j]
            A += w * (np.eye(3) - np.outer(b, b))
            d = float(b @ (p - c_W))
            wd2 += w * d * d
            wsum += w
    u = _unit(p - o)
    return sigma_f * math.sqrt(wd2 / wsum) * math.sqrt(float(u @ np.linalg.solve(A, u))), wsum


def test_a_stereo_rigs_static_point_is_ranged_with_the_stereo_k():
    base = dict(feature_sigma_focal_px=None, feature_range_floor_frac=0.0, member_spread_weight=0.0,
                occluder_min_members=0)
    s = FusionSettings(**base)
    r, log = _run(s)
    o = log[-1][1]
    assert r.range_m is not None and "mono" in r.source  # the static-point (multi-frame) fix
    dist = np.linalg.norm(POINTS_W - o, axis=1)
    j = int(np.argmin(np.abs(dist - r.range_m)))
    assert r.range_m == pytest.approx(dist[j], rel=1e-6)  # exact rays: the point itself
    sig_r, n = _first_order_sigma(j, log, s.feature_sigma_rad, s.feature_memory_s)
    nu0 = s.feature_noise_prior_dof
    post = math.sqrt(nu0 / max(nu0 + 2.0 * n - 3.0, 1.0))  # exact rays: chi 0 (and chi_now 0)
    assert s.stereo_point_sigma_k == 1.0
    assert r.range_sigma_m == pytest.approx(s.stereo_point_sigma_k * post * sig_r, rel=1e-6)
    # the mono rigs' k (mono_point_sigma_k) and the per-ray k (feature_point_sigma_k) do not scale
    # it; stereo_point_sigma_k does
    r2, _ = _run(FusionSettings(**base, feature_point_sigma_k=3.0, mono_point_sigma_k=3.0,
                                stereo_point_sigma_k=1.5))
    assert r2.range_m == pytest.approx(r.range_m, rel=1e-9)
    assert r2.range_sigma_m == pytest.approx(1.5 * post * sig_r, rel=1e-6)
    # a strong prior (nu0 -> inf) keeps the nominal noise: factor 1, k sigma_r,f
    r3, _ = _run(FusionSettings(**base, feature_noise_prior_dof=1e12))
    assert r3.range_sigma_m == pytest.approx(sig_r, rel=1e-6)


def test_a_mono_rigs_static_point_is_ranged_with_the_mono_k():
    # the same flight with one camera: k = mono_point_sigma_k (1.4), neither the per-ray k
    # (feature_point_sigma_k) nor the stereo rigs' k
    base = dict(feature_sigma_focal_px=None, feature_range_floor_frac=0.0, member_spread_weight=0.0,
                occluder_min_members=0)
    s = FusionSettings(**base)
    r, log = _run(s, mono=True)
    o = log[-1][1]
    assert r.range_m is not None and r.source == "mono"
    dist = np.linalg.norm(POINTS_W - o, axis=1)
    j = int(np.argmin(np.abs(dist - r.range_m)))
    assert r.range_m == pytest.approx(dist[j], rel=1e-6)
    sig_r, n = _first_order_sigma(j, log, s.feature_sigma_rad, s.feature_memory_s)
    nu0 = s.feature_noise_prior_dof
    post = math.sqrt(nu0 / max(nu0 + 2.0 * n - 3.0, 1.0))  # exact rays: chi 0 (and chi_now 0)
    assert s.mono_point_sigma_k == 1.4
    assert r.range_sigma_m == pytest.approx(1.4 * post * sig_r, rel=1e-6)
    r2, _ = _run(FusionSettings(**base, feature_point_sigma_k=3.0, stereo_point_sigma_k=1.5), mono=True)
    assert r2.range_sigma_m == pytest.approx(1.4 * post * sig_r, rel=1e-6)
    r3, _ = _run(FusionSettings(**base, mono_point_sigma_k=2.8), mono=True)
    assert r3.range_m == pytest.approx(r.range_m, rel=1e-9)
    assert r3.range_sigma_m == pytest.approx(2.8 * post * sig_r, rel=1e-6)
