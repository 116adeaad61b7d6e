"""Helpers shared by the fusion and geometry tests (not a test module)."""

from __future__ import annotations

import numpy as np


def noisy_bearing(rng, sigma):
    """bearing(cam, T_W_B, p_W): the unit bearing (3,) of world point p_W (m) in camera cam at body
    pose T_W_B, turned by isotropic tangent noise of sigma rad drawn from rng."""

    def bearing(cam, T_W_B, p_W):
        p_C = (cam.T_C_B @ T_W_B.inverse()).apply(p_W)
        b = p_C / np.linalg.norm(p_C)
        e = rng.normal(scale=sigma, size=3)
        b = b + e - (e @ b) * b
        return b / np.linalg.norm(b)

    return bearing


def noisy_units(rng, b, sigma, n):
    """n unit vectors about unit b (3,) with isotropic tangent-plane noise of std sigma (radians)."""
    e = np.eye(3)[np.argmin(np.abs(b))]
    u1 = np.cross(b, e)
    u1 /= np.linalg.norm(u1)
    u2 = np.cross(b, u1)
    z = rng.standard_normal((n, 2)) * sigma
    v = b + z[:, :1] * u1 + z[:, 1:] * u2
    return v / np.linalg.norm(v, axis=1, keepdims=True)


# The far-wall scene of test_fusion_window and test_fusion_occlusion_window (truth by hand in their
# docstrings): the body flies along +x at 5 m/s for 20 frames at 30 fps, ending at WALL_O_END =
# (19 / 6, 0, 0); track 2 holds three corners of a far wall (17.9-18.0 m from the end, within 0.2 deg
# of each other), track 1 a nearer surface's points; every ray exact, in every camera of the rig.
WALL_FPS = 30.0
WALL_FRAMES = 20
WALL_SPEED = 5.0
WALL_FAR = [np.array([20.0 + 0.05 * i, 6.0, 0.05 * i]) for i in (-1, 0, 1)]
WALL_O_END = np.array([WALL_SPEED * (WALL_FRAMES - 1) / WALL_FPS, 0.0, 0.0])


def exact_bearing(cam, T_W_B, p_W):
    """The unit bearing (3,) of world point p_W (m) in camera cam at body pose T_W_B."""
    p_C = (cam.T_C_B @ T_W_B.inverse()).apply(p_W)
    return p_C / np.linalg.norm(p_C)


def far_wall_report(rig, near, settings=None, window_px=11):
    """The far wall's report (track 2) at the last frame of the far-wall scene flown by rig, with
    the nearer points near (list of (3,) in W, ids 0, 1, ...; the wall's 100-102) as track 1; every
    camera's features tracked by a window_px KLT window (the front end's default; 0: no window)."""
    from estimators.egomotion import ConstantVelocity
    from estimators.fusion import FusionSettings, ObstacleFusion
    from estimators.records import CameraView, ObstacleObservation

    ego = ConstantVelocity(WALL_SPEED)
    fus = ObstacleFusion(rig, ego, settings or FusionSettings(),
                         window_px={c.name: window_px for c in rig} if window_px else None)
    for k in range(WALL_FRAMES):
        t = k / WALL_FPS
        T_W_B = ego.pose_at(t)
        obs = []
        for tid, pts, ids in ((1, near, np.arange(len(near))), (2, WALL_FAR, np.arange(100, 103))):
            views = []
            for cam in rig:
                fb = np.array([exact_bearing(cam, T_W_B, p) for p in pts])
                views.append(CameraView(cam.name, fb[1].copy(), np.zeros(2), 1e-3, feature_ids=ids,
                                        feature_b_C=fb))
            obs.append(ObstacleObservation(tid, k, t, "confirmed", tuple(views)))
        reps = fus.step(obs, k, t)
    assert np.allclose(T_W_B.t, WALL_O_END)
    return next(r for r in reps if r.id == 2)
