"""A member feature that slides onto a nearer point must not range its track from its stale point.

Closed-form flight (straight, 5 m/s along x, level, 30 frames/s, bearing noise 5e-4 rad, a forward
stereo rig with a 0.3 m baseline whose two cameras track the same corners): a track's three member
corners sit on a far face 8 m away, 30-35 degrees off the flight line. At t_jump a nearer face
passes in front: each tracked corner jumps onto the nearer face's point on the body origin's ray
towards it at that instant, 3 m away (FusionSettings.feature_slide_memory_s, ``_slid_features``).
The expected ranges are those points' own distances, from the geometry written here.
"""

from __future__ import annotations

import math

import numpy as np

from estimators.cameras import Equidistant
from estimators.egomotion import ConstantVelocity
from estimators.fusion import FusionSettings, ObstacleFusion
from estimators.records import CameraView, ObstacleObservation
from estimators.rig import mono_forward_rig, stereo_forward_rig
from tests.estimators.fusion_helpers import noisy_bearing

FPS = 30.0
T_JUMP_S = 1.0
NEAR_RANGE_M = 3.0  # along each corner's ray from the body origin at t_jump
# the far corners (m, W): 30-35 degrees left of the flight line (x), 8 m from the point x = 5 m
# where the drone is at t_jump
FAR_W = np.array([[5.0 + 8.0 * math.cos(math.radians(a)), 8.0 * math.sin(math.radians(a)), z]
                  for a, z in ((30.0, 0.3), (32.5, -0.2), (35.0, 0.1))])


def _near_points(o_W: np.ndarray) -> np.ndarray:
    """The nearer face's points (3, 3) m in W: on each far corner's ray from o_W (the body origin
    at t_jump), NEAR_RANGE_M from it."""
    u = FAR_W - o_W
    return o_W + NEAR_RANGE_M * u / np.linalg.norm(u, axis=1)[:, None]


def _run(settings: FusionSettings, jump: bool = True, frames: int = 45, sigma: float = 5e-4, seed: int = 3,
         stereo: bool = False):
    """[(report, true range of the points the corners are on now (3,))] per frame; stereo: a
    forward stereo rig (0.3 m baseline) whose two cameras track the same corners (same ids)."""
    model = Equidistant.from_deg_per_px(0.15, 1280, 1280)
    rig = stereo_forward_rig(model, 0.3) if stereo else mono_forward_rig(model)
    ego = ConstantVelocity(5.0)
    rng = np.random.default_rng(seed)
    bearing = noisy_bearing(rng, sigma)
    fus = ObstacleFusion(rig, ego, settings)
    near = _near_points(ego.pose_at(T_JUMP_S).t)
    out = []
    for k in range(frames):
        t = k / FPS
        T_W_B = ego.pose_at(t)
        pts = near if (jump and t >= T_JUMP_S - 1e-9) else FAR_W
        views = []
        for cam in rig:
            b = np.array([bearing(cam, T_W_B, p) for p in pts])
            views.append(CameraView(cam.name, b.mean(axis=0) / np.linalg.norm(b.mean(axis=0)), [0, 0], 0.01,
                                    feature_ids=np.arange(3), feature_b_C=b))
        (r,) = fus.step([ObstacleObservation(7, k, t, "confirmed", tuple(views))], k, t)
        out.append((r, np.linalg.norm(pts - T_W_B.t, axis=1)))
    return out


def test_unslid_corners_range_the_far_face():
    # the flight without the jump: the far corners are ranged to within 3 % and 3 sigma in every
    # frame after the first half second (the test's own sanity: the slide test must not refuse
    # static points)
    run = _run(FusionSettings(), jump=False, stereo=True)
    for r, tr in run[15:]:
        assert r.range_m is not None, r.unobservable_reason
        med = float(np.median(tr))
        assert abs(r.range_m - med) / med < 0.03
        assert abs(r.range_m - med) <= 3.0 * r.range_sigma_m


def _stale_reports(run) -> list:
    """Reports from the jump on that range beyond 3 sigma of the points the corners are on now."""
    k_jump = int(round(T_JUMP_S * FPS))
    return [(k, r.range_m, r.range_sigma_m) for k, (r, tr) in enumerate(run[k_jump:], k_jump)
            if r.range_m is not None and max(float(tr.min()) - r.range_m, r.range_m - float(tr.max()))
            > 3.0 * r.range_sigma_m]


def test_corners_that_slid_onto_a_nearer_face_do_not_range_from_their_stale_points():
    # stereo rig: from the jump on every report either has no range or ranges the nearer face
    # within 3 sigma (its points are the only ones the corners are on now), and the track is
    # ranged again within 0.3 s
    run = _run(FusionSettings(), stereo=True)
    assert not _stale_reports(run)
    k_jump = int(round(T_JUMP_S * FPS))
    assert all(r.range_m is not None for r, _ in run[k_jump + 9:])


def test_without_the_slide_test_the_stale_points_range_it():
    # the same flight with the slide test off (feature_slide_memory_s 0): the frame of the jump is
    # ranged from the far face's stale points, far beyond 3 sigma of the nearer face
    stale = _stale_reports(_run(FusionSettings(feature_slide_memory_s=0.0), stereo=True))
    assert stale
    k, r, sig = stale[0]
    assert r > 2.0 * NEAR_RANGE_M


def test_mono_rig_is_left_alone():
    # on a mono rig the test is off (FusionSettings.feature_slide_memory_s): the same reports with
    # and without it
    a = _run(FusionSettings(), frames=40)
    b = _run(FusionSettings(feature_slide_memory_s=0.0), frames=40)
    assert [(r.range_m, r.range_sigma_m) for r, _ in a] == [(r.range_m, r.range_sigma_m) for r, _ in b]
