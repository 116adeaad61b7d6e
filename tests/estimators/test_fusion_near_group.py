"""A track whose static member points disagree in depth beyond their noise is ranged on its nearest
consistent group (``_near_group_choice``, ``FusionSettings.feature_near_group``). Expected values
from the definitions written here (closed forms worked by hand) and from a flight whose geometry is
set by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from estimators.cameras import Equidistant
from estimators.egomotion import ConstantVelocity
from estimators.fusion import FusionSettings, ObstacleFusion, _near_group_choice
from estimators.records import CameraView, ObstacleObservation
from estimators.rig import mono_forward_rig, stereo_forward_rig
from tests.estimators.fusion_helpers import noisy_bearing

MODEL = Equidistant.from_deg_per_px(0.15, 1280, 1280)
FPS = 30.0


def _unit(v):
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


def test_near_group_choice_closed_form():
    # track 0: a near group 8.0 / 8.1 / 8.2 m (sigma 0.2: agree within 2 sqrt(0.08) = 0.57 m) and a
    # far one 12.0 / 12.5 / 13.0 m; the current choice is 12.5 m, 4.4 m beyond the near group's
    # lower median 8.1 m (> 2 sqrt(0.2^2 + 0.2^2) = 0.57 m and > 0.3 * 8.1 = 2.43 m): it moves
    # to 8.1 m.
    # track 1: 5.0 / 5.3 / 9.0 m: the nearest anchor with 3 agreeing points does not exist
    # (5.0 and 5.3 agree, 9.0 with neither): unchanged.
    # track 2: 3.0 / 3.1 / 3.2 / 3.3 m, choice 3.2 m: within the noise of the group's lower
    # median 3.1 m: unchanged.
    r = np.array([12.5, 5.0, 8.2, 3.3, 13.0, 9.0, 8.0, 3.1, 12.0, 5.3, 8.1, 3.0, 3.2])
    g = np.array([0, 1, 0, 2, 0, 1, 0, 2, 0, 1, 0, 2, 2])
    s = np.full(len(r), 0.2)
    pick = np.array([0, 5, 12])  # 12.5 (track 0), 9.0 (track 1), 3.2 (track 2)
    out = _near_group_choice(g, r, s, pick, 3, 0.3)
    assert r[out].tolist() == [8.1, 9.0, 3.2]
    assert g[out].tolist() == [0, 1, 2]
    # two near points only (n_min 3): no anchor, unchanged
    keep = r != 8.2
    idx = np.flatnonzero(keep)
    pick2 = np.array([np.flatnonzero(idx == 0)[0]])
    out2 = _near_group_choice(g[keep], r[keep], s[keep], pick2, 3, 0.3)
    assert r[keep][out2].tolist() == [12.5]
    # the anchor is the NEAREST point with enough support, not the biggest group: with n_min 2 the
    # pair 5.0 / 5.3 of track 1 is a group; its lower median is 5.0 (9.0 - 5.0 = 4.0 m > 0.3 * 5.0)
    out3 = _near_group_choice(g, r, s, pick, 2, 0.3)
    assert r[out3].tolist() == [8.1, 5.0, 3.2]
    # larger sigmas: 12.5 m +- 2.5 agrees with 8.1 m +- 0.2 within 2 sqrt(2.5^2 + 0.2^2) = 5.0 m
    s4 = s.copy()
    s4[0] = 2.5
    assert r[_near_group_choice(g, r, s4, pick, 3, 0.3)].tolist() == [12.5, 9.0, 3.2]
    # (review of b62e8e2) the group's median's own sigma counts: 8.1 m +- 2.5 (it still agrees with
    # 8.0 and 8.2, so the group and its median are the same) is within 2 sqrt(0.2^2 + 2.5^2) =
    # 5.02 m of 12.5 m: unchanged, although 12.5 m lies 4.5 m beyond the anchor 8.0 m +- 0.2
    s5 = s.copy()
    s5[10] = 2.5
    assert r[_near_group_choice(g, r, s5, pick, 3, 0.3)].tolist() == [12.5, 9.0, 3.2]
    # one surface's depth, not two: 4.4 m is under gap_frac 0.6 of 8.1 m (4.86 m): unchanged
    assert r[_near_group_choice(g, r, s, pick, 3, 0.6)].tolist() == [12.5, 9.0, 3.2]
    # ... and just over 0.5 of it (4.05 m): moved
    assert r[_near_group_choice(g, r, s, pick, 3, 0.5)].tolist() == [8.1, 9.0, 3.2]


def test_near_group_spans_a_surfaces_relief():
    # a near surface of 4 points at 7.52 / 7.53 / 7.81 / 7.83 m, sigma 0.05 m each: relief beyond
    # their noise (7.81 - 7.53 = 0.28 m > 2 sqrt(0.05^2 + 0.05^2) = 0.141 m) but within gap_frac
    # 0.3 of the nearer range (2.26 m): one group, anchor 7.52 m, lower median 7.53 m; the choice
    # 16.6 m lies beyond it by 9.07 m > max(2 sqrt(0.05^2 + 0.05^2), 0.3 * 7.53 = 2.26) m: moved.
    # By the noise alone no point has 3 agreeing (7.52 / 7.53 and 7.81 / 7.83 pairs): unchanged.
    r = np.array([16.6, 7.81, 7.52, 16.7, 7.83, 7.53])
    g = np.zeros(len(r), dtype=np.int64)
    s = np.full(len(r), 0.05)
    pick = np.array([0])
    assert r[_near_group_choice(g, r, s, pick, 3, 0.3)].tolist() == [7.53]
    # the far pair 16.6 / 16.7 m is 8.8 m beyond the near surface (> 0.3 * 7.8 m): not one surface
    # with it; with gap_frac 0 only the noise counts: no anchor
    assert r[_near_group_choice(g, r, s, pick, 3, 0.0)].tolist() == [16.6]


def _junction_run(near_group: bool, seed: int = 2, rig=None, fusion_out: list | None = None):
    """A mono rig flown at 5 m/s for 1.5 s past one track of eight member features: four on a
    near surface (static points around (14, 4, 0.5) m in W, 8 to 15 m away) and four T-junctions
    where its edge crosses a farther surface: their bearings move as points at 1.6 times the
    near surface's distance would, so each fits a static point there (the far surface itself is
    at twice the distance). The track's representative bearing is the junctions' mean, so the
    inner half is the junctions. Returns (the last report, near points (4, 3), junction points
    (4, 3), the body origin). rig: another rig (its first camera sees the features), else mono;
    fusion_out: a list the ObstacleFusion is appended to."""
    rng = np.random.default_rng(seed)
    rig = mono_forward_rig(MODEL) if rig is None else rig
    ego = ConstantVelocity(5.0)
    spread = np.array([[0, 0.3, 0.3], [0, -0.3, 0.3], [0.2, 0, -0.3], [-0.2, 0.1, 0]])
    near = np.array([14.0, 4.0, 0.5]) + spread
    junc = np.array([22.4, 7.4, 0.8]) + spread
    pts = np.vstack([near, junc])
    fus = ObstacleFusion(rig, ego, FusionSettings(feature_near_group=near_group))
    if fusion_out is not None:
        fusion_out.append(fus)
    cam = rig[0]
    sigma = 5e-4
    bearing = noisy_bearing(rng, sigma)
    for k in range(46):
        t = k / FPS
        T_W_B = ego.pose_at(t)
        fb = np.array([bearing(cam, T_W_B, f) for f in pts])
        view = CameraView("cam0", _unit(fb[4:].mean(axis=0)), [0, 0], sigma, feature_ids=np.arange(8),
                          feature_b_C=fb)
        (r,) = fus.step([ObstacleObservation(7, k, t, "confirmed", (view,))], k, t)
    return r, near, junc, ego.pose_at(45 / FPS)


def test_a_track_over_two_depths_is_ranged_on_its_near_surface():
    r, near, junc, T_W_B = _junction_run(True)
    assert r.range_m is not None and r.range_sigma_m is not None
    o = T_W_B.t
    d_near = np.linalg.norm(near - o, axis=1)
    # the reported point is one of the near surface's points: its bearing within 0.5 deg of one
    # of theirs, its range within 3 sigma (and 5 %) of that point's
    b_W = T_W_B.rotate(np.asarray(r.bearing_body))
    ang = np.degrees(np.arccos(np.clip([_unit(p - o) @ b_W for p in near], -1.0, 1.0)))
    j = int(np.argmin(ang))
    assert ang[j] < 0.5
    assert abs(r.range_m - d_near[j]) <= 3.0 * r.range_sigma_m
    assert abs(r.range_m - d_near[j]) / d_near[j] < 0.05


def test_the_moved_choice_names_its_own_feature():
    # (review of b62e8e2) the track's chosen point and the feature id it carries (feature ids 0-3
    # are the near surface's, 4-7 the junctions') move together: the id is a near feature's and
    # the point lies within 5 % of that feature's true point (in range from the body origin)
    fus_l: list = []
    r, near, junc, T_W_B = _junction_run(True, fusion_out=fus_l)
    tr = fus_l[0]._tracks[7]
    assert tr.feature_point_fid in (0, 1, 2, 3)
    o = T_W_B.t
    true = near[tr.feature_point_fid]
    assert np.linalg.norm(np.asarray(tr.feature_point) - true) < 0.05 * np.linalg.norm(true - o)


def test_control_without_the_rule_ranges_the_junctions():
    # the control: the lower median of the inner half (the junctions) is reported, 1.6x the near
    # surface's range, its bearing on the junctions (where the true surface is at twice the near
    # range): the rule above is what changes it
    r, near, junc, T_W_B = _junction_run(False)
    o = T_W_B.t
    assert r.range_m is not None
    assert r.range_m > 1.4 * float(np.max(np.linalg.norm(near - o, axis=1)))
    assert math.isclose(r.range_m, float(np.median(np.linalg.norm(junc - o, axis=1))), rel_tol=0.1)


def test_not_on_a_stereo_rig():
    # (review of b62e8e2) the rule is for mono rigs only (on a stereo rig it put the demo's
    # stereo <= 3 m over its target): the same flight seen by a stereo rig's first camera alone,
    # with the rule on, ranges the junctions as the control does
    r, near, junc, T_W_B = _junction_run(True, rig=stereo_forward_rig(MODEL, 0.30))
    o = T_W_B.t
    assert r.range_m is not None
    assert r.range_m > 1.4 * float(np.max(np.linalg.norm(near - o, axis=1)))
    assert math.isclose(r.range_m, float(np.median(np.linalg.norm(junc - o, axis=1))), rel_tol=0.1)


def test_feature_near_group_setting_is_a_switch():
    with pytest.raises(Exception, match="feature_near_group"):
        FusionSettings(feature_near_group=1)
