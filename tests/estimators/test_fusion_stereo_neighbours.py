"""A report ranged by its feature stereo fix alone gets a range-sigma term that reaches the
farthest in range of its nearest same-surface member points (``ObstacleFusion._stereo_neighbours``).

Numbers worked by hand, after the tuned stereo_hover's track 23 (a two-ray point 5 cm in front of
a 0.3 m sphere, near its limb): the reported point at r = 1.384 m along u = +x (its own member
point, within 1 mrad of u, is not a neighbour), sigma so far 0.017 m; three neighbours at 1.5, 2.3
and 3.6 deg from u with ranges 1.396, 1.385 and 1.322 m and sigmas 0.021, 0.022 and 0.019 m; a
fourth at 5 deg (1.20 m) and a far one at 10 deg (5.64 m, beyond the depth cluster: |5.64 - 1.384|
> 0.3 * 1.384). The two nearest agree within their noise (0.012^2 < 0.021^2 + 0.017^2); the third
does not: extra^2 = 0.062^2 - 0.019^2 - 0.017^2 = 0.003194 m^2.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from estimators.cameras import Equidistant
from estimators.egomotion import ConstantVelocity
from estimators.fusion import FusionSettings, ObstacleFusion
from estimators.rig import stereo_forward_rig

MODEL = Equidistant.from_deg_per_px(0.15, 1280, 1280)
R0, SIG0 = 1.384, 0.017


def _dir(ang_deg: float, polar_deg: float) -> np.ndarray:
    a, p = math.radians(ang_deg), math.radians(polar_deg)
    return np.array([math.cos(a), math.sin(a) * math.cos(p), math.sin(a) * math.sin(p)])


# (angle from u deg, polar angle deg, range m, sigma m)
ST = [(0.0, 0.0, R0, 0.021), (1.5, 68.0, 1.396, 0.021), (2.3, -128.0, 1.385, 0.022),
      (10.0, 108.0, 5.64, 0.345)]
LS = [(3.6, 28.0, 1.322, 0.019), (5.0, 200.0, 1.20, 0.02)]


def _members(rows):
    return (np.zeros(len(rows), dtype=np.int64), np.array([r[2] for r in rows]),
            np.array([_dir(r[0], r[1]) for r in rows]), np.array([r[3] for r in rows]))


def _term(settings: FusionSettings | None = None, **track) -> float:
    fus = ObstacleFusion(stereo_forward_rig(MODEL, 0.30), ConstantVelocity(0.0), settings or FusionSettings())
    fus._gidx = {7: 0}
    fus._members_st, fus._members_ls = _members(ST), _members(LS)
    tr = SimpleNamespace(id=7, feature_range=None, feature_stereo=(R0, 0.02, 4), vel_moving=False)
    for k, v in track.items():
        setattr(tr, k, v)
    out = fus._stereo_neighbours([tr], np.array([R0]), np.array([[1.0, 0.0, 0.0]]), np.array([SIG0**2]))
    return float(out[0])


def test_a_stereo_point_off_its_neighbours_surface_gets_a_sigma_reaching_them():
    assert _term() == pytest.approx(math.sqrt(0.062**2 - 0.019**2 - 0.017**2), rel=1e-9)  # 0.0565 m
    # the error it stands for (1.455 - 1.384 = 0.071 m) is within 1.3 sigma, not 4
    assert 0.071 / math.hypot(SIG0, _term()) < 1.3


def test_neighbours_within_their_noise_add_nothing():
    assert _term(FusionSettings(stereo_neighbour_n=2)) == 0.0  # only the two that agree
    assert _term(FusionSettings(stereo_neighbour_n=0)) == 0.0  # off


def test_only_a_report_ranged_by_its_stereo_fix_alone():
    assert _term(feature_range=(R0, 0.02, 5)) == 0.0  # a static-point fix ranged it: its own terms
    assert _term(feature_stereo=None) == 0.0
    # a track whose velocity evidence rejects zero: its static points (LS) are not neighbours, so
    # the third nearest is the far shared point, beyond the depth cluster: the two that agree
    assert _term(vel_moving=True) == 0.0


def _terms(st, ls, trs, gidx, settings: FusionSettings | None = None) -> list[float]:
    """_stereo_neighbours over several tracks: st / ls rows (group, angle deg, polar deg, range m,
    sigma m); each track ranged at R0 along +x with sigma so far SIG0."""
    fus = ObstacleFusion(stereo_forward_rig(MODEL, 0.30), ConstantVelocity(0.0), settings or FusionSettings())
    fus._gidx = gidx

    def members(rows):
        return (np.array([r[0] for r in rows], dtype=np.int64), np.array([r[3] for r in rows]),
                np.array([_dir(r[1], r[2]) for r in rows]), np.array([r[4] for r in rows]))

    fus._members_st, fus._members_ls = members(st), members(ls)
    K = len(trs)
    out = fus._stereo_neighbours(trs, np.full(K, R0), np.tile([1.0, 0.0, 0.0], (K, 1)), np.full(K, SIG0**2))
    return out.tolist()


def test_each_track_ranks_its_own_neighbours():
    # (review of 4f994d8) two stereo-ranged tracks, reported in the order 7, 9 while their group
    # indices are 9 -> 0, 7 -> 1. Track 7 has the neighbours above: term sqrt(0.062^2 - 0.019^2 -
    # 0.017^2). Track 9's shared point at 2.3 deg lies at 1.50 m (0.116 m off, sigma 0.022) and its
    # static point at 3.6 deg at 1.384 m (agrees): term sqrt(0.116^2 - 0.022^2 - 0.017^2). Each
    # report gets its own track's term (a ranking over all tracks' members at once, or a report
    # index taken for a group index, mixes them: 0 or the other track's term)
    st9 = [ST[0], ST[1], (2.3, -128.0, 1.50, 0.022), ST[3]]
    ls9 = [(3.6, 28.0, R0, 0.019), LS[1]]
    st = [(1, *row) for row in ST] + [(0, *row) for row in st9]
    ls = [(1, *row) for row in LS] + [(0, *row) for row in ls9]
    trs = [SimpleNamespace(id=i, feature_range=None, feature_stereo=(R0, 0.02, 4), vel_moving=False)
           for i in (7, 9)]
    got = _terms(st, ls, trs, {9: 0, 7: 1})
    assert got[0] == pytest.approx(math.sqrt(0.062**2 - 0.019**2 - 0.017**2), rel=1e-9)
    assert got[1] == pytest.approx(math.sqrt(0.116**2 - 0.022**2 - 0.017**2), rel=1e-9)


def test_points_behind_the_body_are_not_neighbours():
    # (review of 4f994d8) with 10 neighbours every member point in the depth cluster counts: the
    # farthest in range of those ahead is the 5 deg one (1.20 m, sigma 0.02): extra^2 = 0.184^2 -
    # 0.02^2 - 0.017^2. A point 90 deg off u (cos 0, not ahead of the reported direction) at 1.0 m,
    # within the depth cluster (|1.0 - 1.384| <= 0.3 * 1.384), is not one of them
    st = [(0, *row) for row in ST]
    ls = [(0, *row) for row in LS] + [(0, 90.0, 0.0, 1.0, 0.02)]
    tr = SimpleNamespace(id=7, feature_range=None, feature_stereo=(R0, 0.02, 4), vel_moving=False)
    (got,) = _terms(st, ls, [tr], {7: 0}, FusionSettings(stereo_neighbour_n=10))
    assert got == pytest.approx(math.sqrt(0.184**2 - 0.02**2 - 0.017**2), rel=1e-9)
