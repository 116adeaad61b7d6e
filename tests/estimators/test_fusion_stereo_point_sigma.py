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


def _run(settings: FusionSettings, frames: int = 16, mono: bool = False,
         tilt: tuple[int, float] | None = None):
    """The stereo rig (baseline 0.3 m; ``mono``: its one forward camera) flies +x at 1.5 m/s; every
    point is seen by every camera with exact rays (``tilt`` (k, a): frame k's rays b tilted to
    b + a z, normalised). Returns the last report and, per frame, its time, the body origin and each
    camera's centre and the points' unit bearings in W."""
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
            if tilt is not None and k == tilt[0]:
                b_W = np.array([_unit(b + tilt[1] * np.array([0.0, 0.0, 1.0])) for b in b_W])
            b_C = b_W @ T_W_C.R  # (rows: R_C_W b = R_W_C^T b)
            views.append(CameraView(c.name, _unit(b_C.mean(axis=0)), [0, 0], 1e-3,
                                    feature_ids=np.arange(len(POINTS_W)), feature_b_C=b_C))
            rays.append((c_W, b_W))
        (r,) = fus.step([ObstacleObservation(4, k, t, "confirmed", tuple(views))], k, t)
        log.append((t, T_W_B.t, rays))
    return r, log


def _own_fit(j: int, log, sigma_f: float, memory_s: float) -> tuple[float, float, float, float, float]:
    """Point j's feature fitted from every ray of the flight (every camera): the weighted
    least-squares point p = A^-1 sum_i w_i (I - b_i b_i^T) c_i (exact rays: the point itself), its
    range from the last body origin, its first-order sigma sigma_f sqrt(D2) sqrt(u^T A^-1 u), the
    rays' forgetting weights summed (n), chi = mean_i miss_i^2 / (2 sigma_f^2 D2) (miss_i the ray's
    perpendicular miss of p, means weighted by w_i) and chi_now = the first camera's current ray's
    angular miss of p squared over 2 sigma_f^2."""
    t_last, o, rays_last = log[-1]
    A = np.zeros((3, 3))
    y = np.zeros(3)
    rays = []
    for t, _o, rays_k in log:
        w = math.exp(-(t_last - t) / memory_s)
        for c_W, b_W in rays_k:
            P = np.eye(3) - np.outer(b_W[j], b_W[j])
            A += w * P
            y += w * P @ c_W
            rays.append((w, c_W, b_W[j]))
    p = np.linalg.solve(A, y)
    wsum = sum(w for w, _c, _b in rays)
    D2 = sum(w * float(b @ (p - c)) ** 2 for w, c, b in rays) / wsum
    miss2 = sum(w * float(np.sum(((np.eye(3) - np.outer(b, b)) @ (p - c)) ** 2)) for w, c, b in rays) / wsum
    u = _unit(p - o)
    sig_r = sigma_f * math.sqrt(D2) * math.sqrt(float(u @ np.linalg.solve(A, u)))
    c_now, b_now = rays_last[0][0], rays_last[0][1][j]
    v = p - c_now
    depth = float(b_now @ v)
    chi_now = (float(v @ v) - depth * depth) / depth**2 / (2.0 * sigma_f**2)
    return float(np.linalg.norm(p - o)), sig_r, wsum, miss2 / (2.0 * sigma_f**2 * D2), chi_now


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
    _, sig_r, n, _, _ = _own_fit(j, log, s.feature_sigma_rad, s.feature_memory_s)
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
    _, sig_r, n, _, _ = _own_fit(j, log, s.feature_sigma_rad, s.feature_memory_s)
    nu0 = s.feature_noise_prior_dof
    post = math.sqrt(nu0 / max(nu0 + 2.0 * n - 3.0, 1.0))  # exact rays: chi 0 (and chi_now 0)
    assert s.mono_point_sigma_k == 1.4
    assert r.range_sigma_m == pytest.approx(1.4 * post * sig_r, rel=1e-6)
    r2, _ = _run(FusionSettings(**base, feature_point_sigma_k=3.0, stereo_point_sigma_k=1.5), mono=True)
    assert r2.range_sigma_m == pytest.approx(1.4 * post * sig_r, rel=1e-6)
    r3, _ = _run(FusionSettings(**base, mono_point_sigma_k=2.8), mono=True)
    assert r3.range_m == pytest.approx(r.range_m, rel=1e-9)
    assert r3.range_sigma_m == pytest.approx(2.8 * post * sig_r, rel=1e-6)


@pytest.mark.parametrize("tilt, larger", [((8, 1e-2), "s2"), ((15, 3e-3), "chi_now")])
def test_a_static_points_sigma_takes_its_own_rays_noise(tilt, larger):
    # one frame's rays tilted (mono rig): the feature's own noise variance factor
    # s2 = (nu0 + 2n chi) / (nu0 + 2n - 3) (an older frame tilted: its rays miss the fitted point)
    # or its current ray's miss chi_now (the last frame tilted), the larger, scales k sigma_r,f:
    # sigma = k sqrt(max(s2, chi_now)) sigma_r,f, all from the hand-fitted point
    base = dict(feature_sigma_focal_px=None, feature_range_floor_frac=0.0, member_spread_weight=0.0,
                occluder_min_members=0)
    s = FusionSettings(**base)
    r, log = _run(s, mono=True, tilt=tilt)
    fits = [_own_fit(j, log, s.feature_sigma_rad, s.feature_memory_s) for j in range(len(POINTS_W))]
    j = int(np.argmin([abs(f[0] - r.range_m) for f in fits]))
    rng, sig_r, n, chi, chi_now = fits[j]
    assert r.range_m == pytest.approx(rng, rel=1e-9)
    nu0 = s.feature_noise_prior_dof
    s2 = (nu0 + 2.0 * n * chi) / max(nu0 + 2.0 * n - 3.0, 1.0)
    assert (s2 > 2.0 * chi_now) if larger == "s2" else (chi_now > 2.0 * s2)
    k = s.mono_point_sigma_k
    assert r.range_sigma_m == pytest.approx(k * math.sqrt(max(s2, chi_now)) * sig_r, rel=1e-6)
