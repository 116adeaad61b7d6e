"""A member-replacement restart keeps the obstacle's measured motion (``restart_keeps_motion``).

The front end hands a track's id to another set of points of the same obstacle (a confirmed track
taking over a younger one): the filter restarts, since its state belongs to the old points, but
the obstacle's velocity belongs to the obstacle. Without it, a moving obstacle's fresh corners,
tracked by one camera of a flying rig, fit static points at a wrong depth: motion along the
epipolar plane of the flight moves a bearing as a static point at another depth would (the demo's
track 121: 0.65 m against 0.97 m, sigma 0.013 m, right after such a restart).

Closed-form scene: a 0.30 m stereo pair flying forward at 2 m/s; a compact cluster of corners
starting 4 m ahead and 0.8 m aside, moving at 1.5 m/s against the flight (it is 1 m away at
t = 1 s and passes the drone at ~0.83 m). Until t = 1 s both cameras list corners 0-5 (stereo: its
velocity is measured); from then on cam1 alone lists new corners 100-105 of the same cluster. The
truth is written here; the ambiguity worked by hand: a point moving along the flight line at
-1.5 m/s seen from a camera moving at +2 m/s has the bearings of a static point whose offset from
the camera is scaled by 2 / 3.5 = 0.57, so a static fit ranges it ~40-50 % short.
"""

from __future__ import annotations

import numpy as np

from estimators.cameras import Equidistant
from estimators.egomotion import ConstantVelocity
from estimators.fusion import FusionSettings, ObstacleFusion, _Track
from estimators.records import CameraView, ObstacleObservation
from estimators.rig import stereo_forward_rig
from tests.estimators.fusion_helpers import noisy_bearing

MODEL = Equidistant.from_deg_per_px(0.15, 1280, 1280)
FPS = 30.0
OFFSETS = 0.1 * np.array([[0, 0.6, 0.5], [0, -0.6, 0.5], [0.3, 0, -0.6], [-0.3, 0.5, 0], [0, 0, 0.8],
                          [0.2, -0.4, -0.3]])
CENTRE0 = np.array([4.0, 0.8, 0.2])
V_OBS = np.array([-1.5, 0.0, 0.0])
V_DRONE = 2.0
T_SWAP = 1.0


def _run(settings: FusionSettings, T_s: float = 1.5, seed: int = 4, few_shared: bool = False):
    """[(t, report, true range from the body origin)] per frame of the scene above; few_shared:
    before the swap cam1 lists corner 0 and one other, 1 in even frames and 2 in odd ones."""
    rng = np.random.default_rng(seed)
    rig = stereo_forward_rig(MODEL, 0.30)
    ego = ConstantVelocity(V_DRONE)
    fus = ObstacleFusion(rig, ego, settings)
    sig = settings.feature_point_sigma_k * settings.feature_sigma_rad
    bearing = noisy_bearing(rng, sig)
    out = []
    for k in range(int(round(T_s * FPS)) + 1):
        t = k / FPS
        T_W_B = ego.pose_at(t)
        pts = CENTRE0 + V_OBS * t + OFFSETS
        centre = pts.mean(axis=0)
        swapped = t >= T_SWAP - 1e-9
        cams = [rig["cam1"]] if swapped else list(rig)
        ids = np.arange(len(pts)) + (100 if swapped else 0)
        listed = [ids] * len(cams)
        if few_shared and not swapped:
            listed[1] = ids[[0, 1 + k % 2]]
        views = tuple(
            CameraView(c.name, bearing(c, T_W_B, centre), [0, 0], sig, feature_ids=f,
                       feature_b_C=np.array([bearing(c, T_W_B, q) for q in pts[f % 100]]))
            for c, f in zip(cams, listed, strict=True))
        (r,) = fus.step([ObstacleObservation(7, "obstacle", t, "confirmed", views)], k, t)
        out.append((t, r, float(np.linalg.norm(centre - T_W_B.t)), fus))
    return out


def test_motion_evidence_closed_form():
    # q = max_accel^2 tau = 0.1, so P grows by q dt = 0.01 per axis from t = 0 to t = 0.1 s;
    # chi = v^T P^-1 v against chi2_3(0.999) = 16.27:
    #   evidence v_e = (1, 0, 0), P_e = 0.04 I: chi = 1 / 0.05 = 20 (rejects zero: kept)
    #   moving filter (0.5, 0, 0), P_vv = 0.01 I: chi = 0.25 / 0.02 = 12.5 (does not: dropped)
    #   the same filter at P_vv = 0.001 I: chi = 0.25 / 0.011 = 22.7 (kept, with the evidence),
    #   assumed (``vel_assumed``: its state was put on a feature stereo point with the velocity
    #   prior) or not: what moved it off the prior's zero since is the fixes' measurement
    #   (``_filter_moving`` tests it too); with neither a carried one (motion_carry) is kept
    fus = ObstacleFusion(stereo_forward_rig(MODEL, 0.30), ConstantVelocity(0.0),
                         FusionSettings(max_accel_mps2=1.0, accel_time_s=0.1))
    tr = _Track(1, "orb")
    assert fus._motion_evidence(tr, 0.1) is None
    ev = (np.array([1.0, 0.0, 0.0]), 0.04 * np.eye(3), 0.0)
    tr.vel_acc = ev
    tr.kf = fus._new_kf(np.zeros(3), np.eye(3), 0.1)
    tr.kf.x[3:] = (0.5, 0.0, 0.0)
    tr.t_kf = 0.0
    tr.moving = True
    (e,) = fus._motion_evidence(tr, 0.1)
    assert e is ev
    tr.kf.P[3:, 3:] = 0.001 * np.eye(3)
    for assumed in (False, True):
        tr.vel_assumed = assumed
        got = fus._motion_evidence(tr, 0.1)
        assert len(got) == 2 and got[0] is ev
        np.testing.assert_allclose(got[1][0], [0.5, 0.0, 0.0])
        np.testing.assert_allclose(got[1][1], 0.001 * np.eye(3))
        assert got[1][2] == 0.0
    tr.vel_acc = None
    tr.kf.x[3:] = 0.0  # the prior's zero: no evidence of motion
    assert fus._motion_evidence(tr, 0.1) is None
    tr.motion_carry = (ev,)
    assert fus._motion_evidence(tr, 0.1) == (ev,)


def test_carried_motion_decides_until_it_no_longer_rejects_zero():
    # closed form (as test_filter_moving_closed_form): carried v = (0.5, 0, 0) m/s, P = 0.01 I at
    # t = 0, grown by q dt I, q = 0.1: chi = 0.25 / 0.01 = 25 > chi2_3(0.999) = 16.27 at t = 0
    # (moving), 0.25 / 0.11 = 2.27 at t = 1 s (not: the carried evidence is dropped); a second one,
    # v = (2, 0, 0), P = 0.01 I: chi 4 / 0.11 = 36 at 1 s, so the pair still decides then (the first
    # dropped), and 4 / 0.31 = 12.9 at t = 3 s: neither
    fus = ObstacleFusion(stereo_forward_rig(MODEL, 0.30), ConstantVelocity(0.0),
                         FusionSettings(max_accel_mps2=1.0, accel_time_s=0.1))
    tr = _Track(1, "orb")
    assert not fus._carried_moving(tr, 0.0)
    slow = (np.array([0.5, 0.0, 0.0]), 0.01 * np.eye(3), 0.0)
    tr.motion_carry = (slow,)
    assert fus._carried_moving(tr, 0.0)
    assert not fus._carried_moving(tr, 1.0) and tr.motion_carry is None
    fast = (np.array([2.0, 0.0, 0.0]), 0.01 * np.eye(3), 0.0)
    tr.motion_carry = (slow, fast)
    assert fus._carried_moving(tr, 1.0) and tr.motion_carry == (fast,)
    assert not fus._carried_moving(tr, 3.0) and tr.motion_carry is None


def test_restart_keeps_a_moving_obstacles_motion():
    run = _run(FusionSettings())
    # the swap restarts the filter (members replaced) ...
    assert any(r.range_m is None for t, r, _rt, _f in run if abs(t - T_SWAP) < 1e-6)
    # ... and the obstacle's motion survives it: after the swap no report ranges the cluster from
    # static points (one camera cannot range a moving obstacle), or any that does is within 3 sigma
    after = [(t, r, rt) for t, r, rt, _f in run if t >= T_SWAP - 1e-9]
    for t, r, rt in after:
        assert r.range_m is None or abs(r.range_m - rt) <= 3.0 * r.range_sigma_m, (t, r.range_m, rt)


def test_without_the_rule_the_static_fit_ranges_the_mover_short():
    # control: the same scene with restart_keeps_motion off: the static fit of cam1's fresh corners
    # ranges the approaching cluster short by far more than its sigma (the case the rule exists for)
    run = _run(FusionSettings(restart_keeps_motion=False))
    bad = [(t, r.range_m, rt) for t, r, rt, _f in run
           if t >= T_SWAP and r.range_m is not None and abs(r.range_m - rt) > 3.0 * r.range_sigma_m]
    assert bad
    assert all(rng < rt for _t, rng, rt in bad)  # short (the epipolar-plane ambiguity above)


def test_restart_keeps_motion_its_stereo_fixes_measured():
    # the demo's track 119 (2.567 s): a track whose filter velocity only its successive stereo fixes
    # measured (too few shared corners for a feature velocity: ``vel_assumed`` stays set, no
    # velocity reported) is restarted by a member replacement; the filter's velocity, which kept
    # static points from ranging it before the restart (``_filter_moving``), keeps doing so after
    # it. Here cam1 lists corner 0 and one other that alternates (1, 2) before the swap: the fixes
    # follow corner 0, and no two corners are shared a lag apart. Without the rule, cam1's fresh
    # corners ranged it 45-55 % short at sigmas of 1-5 cm (the 2 / 3.5 scale of the docstring).
    run = _run(FusionSettings(), few_shared=True)
    fus = run[0][3]
    before = [r for t, r, _rt, _f in run if t < T_SWAP - 1e-9]
    assert all(r.range_m is not None for r in before[3:]) and all(r.speed_mps is None for r in before)
    assert any(r.range_m is None for t, r, _rt, _f in run if abs(t - T_SWAP) < 1e-6)
    tr = fus._tracks[7]
    assert tr.vel_acc is None  # (no feature velocity was measured)
    after = [(t, r, rt) for t, r, rt, _f in run if t >= T_SWAP - 1e-9]
    for t, r, rt in after:
        assert r.range_m is None or abs(r.range_m - rt) <= 3.0 * r.range_sigma_m, (t, r.range_m, rt)
