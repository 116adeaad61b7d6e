"""Degenerate settings are an answer, not an exception: a zero velocity prior and no process noise
leave a stereo track's velocity covariance singular, and the moving test of its filter
(``ObstacleFusion._filter_moving``, abafde5) must still decide (before: numpy LinAlgError)."""

from __future__ import annotations

import numpy as np

from estimators.cameras import Equidistant
from estimators.egomotion import ConstantVelocity
from estimators.fusion import FusionSettings, ObstacleFusion, _Track
from estimators.rig import stereo_forward_rig


def test_filter_moving_with_a_singular_velocity_covariance_decides_without_raising():
    model = Equidistant(fx=200.0, fy=200.0, cx=319.5, cy=179.5, width=640, height=360)
    s = FusionSettings(velocity_prior_sigma_mps=0.0, max_accel_mps2=0.0)
    fus = ObstacleFusion(stereo_forward_rig(model, 0.30), ConstantVelocity(3.0), s)
    tr = _Track(1, "orb")
    tr.kf = fus._new_kf(np.array([0.0, 0.0, 3.0]), np.eye(3) * 0.01, 0.0)  # P_vv = 0
    tr.moving, tr.t_kf = True, 0.0
    assert fus._filter_moving(tr, 0.1) is False  # v = 0 with no spread: zero is not rejected
    # a velocity measured on one axis only (the others still singular): 1 m/s at sigma 0.1 m/s
    # along x rejects zero (chi 100 > chi2_3 gate), at sigma 10 m/s it does not (chi 0.01)
    for sigma, moving in ((0.1, True), (10.0, False)):
        tr.kf.x = np.array([0.0, 0.0, 3.0, 1.0, 0.0, 0.0])
        tr.kf.P = np.zeros((6, 6))
        tr.kf.P[3, 3] = sigma**2
        assert fus._filter_moving(tr, 0.1) is moving
