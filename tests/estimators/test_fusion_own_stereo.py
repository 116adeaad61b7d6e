"""A report ranged by a member feature's static point gets a range-sigma term that reaches the
same feature's two-ray point of this frame, beyond their joint noise (``ObstacleFusion._own_stereo``).

Numbers worked by hand, after the demo's moving box (track 70 at t 1.567 s): the static point of
feature 1635 at r = 3.64 m, sigma so far 0.187 m; the feature's two-ray point of this frame at
4.73 m with sigma 2 x 0.22 = 0.44 m (k sigma_r,f); the box along the reported bearing at 4.87 m.
    extra^2 = (4.73 - 3.64)^2 - 0.44^2 - 0.187^2 = 1.1881 - 0.1936 - 0.034969 = 0.959531 m^2
so the reported sigma sqrt(0.034969 + 0.959531) = 0.9973 m, and the error 1.23 m is 1.23 sigma
(it was 6.6 sigma).
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
R0, SIG0, FID = 3.64, 0.187, 1635


def _term(settings: FusionSettings | None = None, pairs=None, **track) -> float:
    fus = ObstacleFusion(stereo_forward_rig(MODEL, 0.30), ConstantVelocity(0.0), settings or FusionSettings())
    fus._gidx = {70: 1, 12: 0}
    # two-ray points of this frame: (track index, feature id, range m, sigma m in reports' units)
    rows = pairs if pairs is not None else [(0, FID, 9.0, 0.1), (1, 1634, 2.5, 0.4), (1, FID, 4.73, 0.44)]
    fus._stereo_pairs = (np.array([p[0] for p in rows], dtype=np.int64),
                         np.array([p[1] for p in rows], dtype=np.int64),
                         np.array([p[2] for p in rows]), np.array([p[3] for p in rows]))
    tr = SimpleNamespace(id=70, feature_range=(R0, SIG0, 5), feature_point_fid=FID)
    for k, v in track.items():
        setattr(tr, k, v)
    return float(fus._own_stereo([tr], np.array([R0]), np.array([SIG0**2]))[0])


def test_a_static_point_off_its_own_two_ray_point_gets_a_variance_reaching_it():
    extra2 = 1.09**2 - 0.44**2 - 0.187**2
    assert _term() == pytest.approx(extra2, rel=1e-9)  # 0.959531 m^2
    # the error it stands for (4.87 - 3.64 = 1.23 m) is within 1.3 sigma, not 6.6
    assert 1.23 / math.sqrt(SIG0**2 + _term()) < 1.3
    # either sign: a static point beyond its two-ray point by the same amount
    pairs = [(1, FID, R0 - 1.09, 0.44)]
    assert _term(pairs=pairs) == pytest.approx(extra2, rel=1e-9)


def test_agreement_within_the_joint_noise_adds_nothing():
    # |3.64 - 4.10| = 0.46 < sqrt(0.44^2 + 0.187^2) = 0.478
    assert _term(pairs=[(1, FID, 4.10, 0.44)]) == 0.0
    assert _term(FusionSettings(static_own_stereo=False)) == 0.0  # off


def test_only_the_reported_feature_of_the_same_track():
    assert _term(feature_point_fid=1634) == pytest.approx(1.14**2 - 0.4**2 - SIG0**2, rel=1e-9)
    assert _term(feature_point_fid=999) == 0.0  # no two-ray point of that feature this frame
    assert _term(pairs=[(0, FID, 9.0, 0.1)]) == 0.0  # another track's point of that id
    assert _term(feature_range=None) == 0.0  # not ranged by a static point: its own terms
    assert _term(feature_point_fid=None) == 0.0  # on the representative ray, no feature
